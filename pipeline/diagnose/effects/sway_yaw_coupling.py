"""sway_yaw_coupling: nonlinear sway-yaw cross terms v^2 r and v r^2 in both equations (Abkowitz).

In the speed scaling of the non-dimensional form (v' = v/u, r' = r L/u, forces on u^2): the cubic
terms give accelerations divided by u (v'^2 r' u^2 = v^2 r L / u), read through the kernel's speed
factor s (feature codes 8, 9: 1 without speed_loss); the modulus form's second-order terms
(|v'| r' u^2 = |v| r L) are independent of u (docs/diagnosis.md, "The catalogue")."""

from __future__ import annotations

from pipeline.diagnose.effects.base import R_EQ, RESPONSE_FLOOR, V_EQ, Effect, Form, Injection, Param

#: damping=True (signed in the anchored form, fit.Layout.bounds): the terms that are a damping growing
#: with the other motion, v r^2 / v |r| in dv/dt (sway damping growing with the turn) and v^2 r / |v| r
#: in dr/dt (yaw damping growing with the drift), negative in the MMG and Abkowitz derivatives of
#: merchant hulls (e.g. KVLCC2: Y'_vrr, N'_vvr < 0); the other two are couplings of either sign


class SwayYawCoupling(Effect):
    name = "sway_yaw_coupling"
    label = "sway-yaw cross terms"
    signature_axis = ("vr", "v r (m/s x deg/s)")
    estimate_key = "n_vvr_s_per_m2"
    magnitude_unit = "cut of the 20/20 yaw-rate amplitude (v^2 r in the yaw equation)"
    injection = Injection(plants=("truth",), solver="cross_term_for_change", field="n_vvr")
    forms = (
        Form(
            "abkowitz",
            (
                Param("y_vvr_s_per_m_deg", 0.0, -1e3, 1e3, 0.0, "s/(m deg)", feature=(8, V_EQ)),
                Param("y_vrr_s2_per_deg2", 0.0, -10.0, 10.0, 0.0, "s^2/deg^2", feature=(9, V_EQ),
                      damping=True),
                Param("n_vvr_s_per_m2", 0.0, -1e5, 1e5, 0.0, "s/m^2", feature=(8, R_EQ), damping=True),
                Param("n_vrr_s_per_m_deg", 0.0, -1e3, 1e3, 0.0, "s/(m deg)", feature=(9, R_EQ)),
            ),
        ),
        # the modulus form of Norrbin-type models (e.g. Van Berlekom & Goddard's N_|v|r |v| r): the same
        # odd symmetry (the term changes sign with v and r together), growing linearly in each
        Form(
            "modulus",
            (
                Param("y_avr_per_deg", 0.0, -10.0, 10.0, 0.0, "1/deg", feature=(6, V_EQ)),
                Param("y_var_per_deg", 0.0, -10.0, 10.0, 0.0, "1/deg", feature=(5, V_EQ), damping=True),
                Param("n_avr_per_m", 0.0, -1e3, 1e3, 0.0, "1/m", feature=(6, R_EQ), damping=True),
                Param("n_var_per_m", 0.0, -1e3, 1e3, 0.0, "1/m", feature=(5, R_EQ)),
            ),
        ),
    )
    needs_v = True
    words = "nonlinear sway-yaw coupling"
    term = ("dv/dt and dr/dt each gain (c_vvr v^2 r + c_vrr v r^2) / s (Abkowitz cross terms, s the speed "
            "factor) or c_avr |v| r + "
            "c_var v |r| (modulus form)")
    signature = "errors that grow with the product of drift and turn: large manoeuvres mis-shaped in v and r"
    floor_reason = RESPONSE_FLOOR

    def physical(self, form, values, ctx):
        v, r = ctx.v_max, ctx.r_max
        if form.name == "modulus":
            yaw = values["n_avr_per_m"] * abs(v) * r + values["n_var_per_m"] * v * abs(r)
        else:
            yaw = values["n_vvr_s_per_m2"] * v * v * r + values["n_vrr_s_per_m_deg"] * v * r * r
        return (
            f"the hull's yaw moment depends on drift and turn together: at v = {v:.3f} m/s, "
            f"r = {r:.2f} deg/s the cross terms add {yaw:+.3g} deg/s^2 to the yaw acceleration, "
            f"which a linear (or r-only) model cannot carry"
        )

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return v * v * r


EFFECT = SwayYawCoupling()
