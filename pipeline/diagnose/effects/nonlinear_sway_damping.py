"""nonlinear_sway_damping: sway damping growing faster than linearly with v (v|v| in both equations)."""

from __future__ import annotations

from pipeline.diagnose.effects.base import R_EQ, RESPONSE_FLOOR, V_EQ, Effect, Form, Injection, Param


class NonlinearSwayDamping(Effect):
    name = "nonlinear_sway_damping"
    label = "nonlinear sway damping"
    signature_axis = ("v", "measured sway speed v (m/s)")
    estimate_key = "y_vv_per_m"
    magnitude_unit = "cut of the 20/20 sway-velocity amplitude (v|v| drag, sway only)"
    injection = Injection(plants=("truth",), solver="sway_drag_for_cut", field="y_vv")
    forms = (
        Form(
            "abs",
            (
                Param("y_vv_per_m", 0.0, -50.0, 50.0, 0.0, "1/m", feature=(2, V_EQ), damping=True),
                Param("n_vv_deg_per_m2", 0.0, -5000.0, 5000.0, 0.0, "deg/m^2", feature=(2, R_EQ)),
            ),
        ),
    )
    needs_v = True
    words = "nonlinear sway damping"
    term = "dv/dt gains y_vv v|v|, dr/dt gains n_vv v|v| (Abkowitz/MMG cross-flow drag)"
    signature = "sway and yaw acceleration errors even-odd in v (v|v|): drift angle over-predicted at large v"
    floor_reason = RESPONSE_FLOOR

    def physical(self, form, values, ctx):
        """One sentence, read by the sign of y_vv: cross-flow drag opposes the drift (y_vv < 0 in contract
        signs (docs/contract.md#run-data), dv/dt = ... + y_vv v|v|); a fitted y_vv > 0 pushes the drift
        further, which no hull's drag does, and is said to stand in for something else.  n_vv's sign depends
        on where along the hull the cross-flow acts, so it is given, not judged."""
        y, n = values["y_vv_per_m"], values["n_vv_deg_per_m2"]
        dv, dr = y * ctx.v_max**2, n * ctx.v_max**2
        yaw = f"its yaw part adds {dr:+.3g} deg/s^2 to the yaw acceleration"
        if y < 0.0:
            return (
                f"cross-flow drag: at the largest sway velocity {ctx.v_max:.3f} m/s it opposes the drift "
                f"with {abs(dv):.3g} m/s^2 of sway acceleration beyond the linear damping and {yaw}, so "
                f"the drift angle of large manoeuvres is limited more than a linear hull predicts"
            )
        return (
            f"at the largest sway velocity {ctx.v_max:.3f} m/s the fitted sway term pushes the drift "
            f"further, by {abs(dv):.3g} m/s^2 of sway acceleration, and {yaw}: the sign opposite to "
            f"cross-flow drag, which opposes the drift on every hull, so the term stands in for another "
            f"nonlinearity of the sway-yaw motion, not for damping"
        )

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return v * abs(v)


EFFECT = NonlinearSwayDamping()
