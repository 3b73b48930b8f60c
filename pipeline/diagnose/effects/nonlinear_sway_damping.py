"""nonlinear_sway_damping: sway damping growing faster than linearly with v (v|v| in both equations)."""

from __future__ import annotations

from pipeline.diagnose.effects.base import R_EQ, V_EQ, Effect, Form, Param, response_floor_text

MIN_RESPONSE = 0.05  # as nonlinear_yaw_damping: 5 % of the largest manoeuvre's peak yaw rate


class NonlinearSwayDamping(Effect):
    name = "nonlinear_sway_damping"
    forms = (
        Form(
            "abs",
            (
                Param("y_vv_per_m", 0.0, -50.0, 50.0, 0.0, "1/m", feature=(2, V_EQ)),
                Param("n_vv_deg_per_m2", 0.0, -5000.0, 5000.0, 0.0, "deg/m^2", feature=(2, R_EQ)),
            ),
        ),
    )
    needs_v = True
    words = "nonlinear sway damping"
    term = "dv/dt gains y_vv v|v|, dr/dt gains n_vv v|v| (Abkowitz/MMG cross-flow drag)"
    signature = "sway and yaw acceleration errors even-odd in v (v|v|): drift angle over-predicted at large v"
    floor_reason = f"changes the peak yaw rate of the largest manoeuvre by >= {MIN_RESPONSE:.0%}"

    def material(self, form, values, ctx, response_change):
        return bool(response_change >= MIN_RESPONSE), response_floor_text(response_change, MIN_RESPONSE)

    def physical(self, form, values, ctx):
        y, n = values["y_vv_per_m"], values["n_vv_deg_per_m2"]
        return (
            f"cross-flow drag: at the largest sway velocity {ctx.v_max:.3f} m/s the sway force adds "
            f"{y * ctx.v_max**2:+.3g} m/s^2 and the yaw moment {n * ctx.v_max**2:+.3g} deg/s^2, so the "
            f"drift angle of large manoeuvres is limited more than a linear hull predicts"
        )

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return v * abs(v)


EFFECT = NonlinearSwayDamping()
