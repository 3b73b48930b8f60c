"""hull_nonlinearity: the Abkowitz-type set of the hull's nonlinear forces in one effect.

v|v|, r|r|, v^2 r and v r^2 in both equations, in the speed scaling of the non-dimensional form
(v' = v/u, r' = r L/u, forces on u^2): with Y = rho/2 L^2 u^2 Y'(v', r'), the second-order modulus
terms give accelerations independent of u (v'|v'| u^2 = v|v|, r'|r'| u^2 = r|r| L^2) and the cubic
terms accelerations divided by u (v'^2 r' u^2 = v^2 r L / u), read through the kernel's speed factor
s (feature codes 8, 9: 1 without speed_loss, u/U with its exponent at 1, the dimensional physics).
The length L and the fluid's constants are in the dimensional coefficients, so nothing here needs
the ship's particulars.

Two forms: ``abkowitz``, the eight terms above; ``mixed``, the same with the second-order cross
terms |v| r and v |r| in both equations beside the third-order ones (twelve terms; |v'| r' u^2 = |v| r
L, independent of u).  Hull models are written either way (Abkowitz's third-order Taylor terms, the
MMG's v^2 r and v r^2; Norrbin-type and Van Berlekom & Goddard's |v| r): where the data cannot say
which order a hull's cross-flow forces are of, the mixed form carries both (the reference structure,
:data:`~pipeline.diagnose.effects.REFERENCE`).  One step can then carry what a hull's nonlinearity
is, where sway damping, yaw damping and the cross terms judged one at a time each carry a part
(docs/diagnosis.md, "The catalogue").
"""

from __future__ import annotations

from pipeline.diagnose.effects import sway_yaw_coupling
from pipeline.diagnose.effects.base import R_EQ, RESPONSE_FLOOR, V_EQ, Effect, Form, Injection, Param

#: v|v|, r|r|, v^2 r / s, v r^2 / s in both equations (bounds as the single effects' of the same terms:
#: nonlinear_sway_damping, nonlinear_yaw_damping's abs form, sway_yaw_coupling's abkowitz form)
_ABKOWITZ = (
    Param("y_vv_per_m", 0.0, -50.0, 50.0, 0.0, "1/m", feature=(2, V_EQ), damping=True),
    Param("y_rr_m_per_deg2", 0.0, -1.0, 1.0, 0.0, "m/deg^2", feature=(1, V_EQ)),
    Param("y_vvr_s_per_m_deg", 0.0, -1e3, 1e3, 0.0, "s/(m deg)", feature=(8, V_EQ)),
    Param("y_vrr_s2_per_deg2", 0.0, -10.0, 10.0, 0.0, "s^2/deg^2", feature=(9, V_EQ), damping=True),
    Param("n_vv_deg_per_m2", 0.0, -5000.0, 5000.0, 0.0, "deg/m^2", feature=(2, R_EQ)),
    Param("n_rr_per_deg", 0.0, -2.0, 2.0, 0.0, "1/deg", feature=(1, R_EQ), damping=True),
    Param("n_vvr_s_per_m2", 0.0, -1e5, 1e5, 0.0, "s/m^2", feature=(8, R_EQ), damping=True),
    Param("n_vrr_s_per_m_deg", 0.0, -1e3, 1e3, 0.0, "s/(m deg)", feature=(9, R_EQ)),
)
#: |v| r and v |r| in both equations: sway_yaw_coupling's modulus form, its bounds and signs
_MODULUS_CROSS = sway_yaw_coupling.EFFECT.form("modulus").params

class HullNonlinearity(Effect):
    name = "hull_nonlinearity"
    label = "hull nonlinearity (nonlinear hull terms in v and r)"
    signature_axis = ("r", "measured yaw rate r (deg/s)")
    estimate_key = "n_rr_per_deg"
    magnitude_unit = "yaw damping n_rr (1/deg) of the set"
    injection = Injection(why_not=(
        ("truth", "a set of eight or twelve terms has no one magnitude: its parts are injected one by one "
                  "(nonlinear_sway_damping, nonlinear_yaw_damping, sway_yaw_coupling)"),
        ("tank", "the tank's hull is already nonlinear: nothing to inject"),
    ))
    forms = (
        Form("abkowitz", _ABKOWITZ),
        # the same with the second-order (modulus) cross terms |v| r and v |r| of Norrbin-type models
        # beside the third-order ones (e.g. Van Berlekom & Goddard's tanker: N_|v|r |v| r): the odd
        # function of (v, r) to second and third order both, for hulls whose cross-flow forces are
        # not of one order; bounds and signs as sway_yaw_coupling's modulus form
        Form("mixed", _ABKOWITZ + _MODULUS_CROSS),
    )
    needs_v = True
    words = "hull nonlinearity"
    term = ("dv/dt and dr/dt each gain c_vv v|v| + c_rr r|r| + (c_vvr v^2 r + c_vrr v r^2) / s "
            "(Abkowitz-type terms in the non-dimensional speed scaling), and in the mixed form "
            "c_avr |v| r + c_var v |r| too")
    signature = ("errors that grow with the size of the manoeuvre in v and r alike: large manoeuvres "
                 "over-predicted")
    floor_reason = RESPONSE_FLOOR

    def physical(self, form, values, ctx):
        """The yaw acceleration the terms add at the largest sway velocity and yaw rate together, and
        at each alone (deg/s^2)."""
        v, r = ctx.v_max, ctx.r_max
        nv = values["n_vv_deg_per_m2"] * v * abs(v)
        nr = values["n_rr_per_deg"] * r * abs(r)
        nx = values["n_vvr_s_per_m2"] * v * v * r + values["n_vrr_s_per_m_deg"] * v * r * r
        nx += values.get("n_avr_per_m", 0.0) * abs(v) * r + values.get("n_var_per_m", 0.0) * v * abs(r)
        return (
            f"the hull's forces grow faster than linearly with drift and turn: at v = {v:.3f} m/s and "
            f"r = {r:.2f} deg/s the terms add {nv + nr + nx:+.3g} deg/s^2 to the yaw acceleration "
            f"({nv:+.3g} from the drift, {nr:+.3g} from the turn, {nx:+.3g} from both together), "
            f"which a linear hull cannot carry"
        )

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return r * abs(r)


EFFECT = HullNonlinearity()
