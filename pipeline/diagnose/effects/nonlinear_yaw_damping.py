"""nonlinear_yaw_damping: yaw damping growing faster than linearly with r (Norrbin r^3, or r|r|).

Both forms in the speed scaling of the non-dimensional form (r' = r L/u, moments on u^2): r'|r'| u^2 =
r|r| L^2 gives a yaw acceleration independent of u, r'^3 u^2 = r^3 L^3 / u one divided by u, read
through the kernel's speed factor s (feature code 10, r^3 / s: 1 without speed_loss, so the cubic form
is r^3 there; docs/diagnosis.md, "The catalogue")."""

from __future__ import annotations

from pipeline.diagnose.effects.base import R_EQ, RESPONSE_FLOOR, Context, Effect, Form, Injection, Param


class NonlinearYawDamping(Effect):
    name = "nonlinear_yaw_damping"
    label = "nonlinear yaw damping"
    signature_axis = ("r", "measured yaw rate r (deg/s)")
    estimate_key = "n_rrr_s_per_deg2"
    magnitude_unit = "cut of the 20/20 yaw-rate amplitude"
    injection = Injection(plants=("truth",), solver="damping_for_cut", field="n_rrr")
    forms = (
        Form("cubic", (Param("n_rrr_s_per_deg2", 0.0, -1.0, 1.0, 0.0, "s/deg^2", feature=(10, R_EQ),
                             damping=True),)),
        Form("abs", (Param("n_rr_per_deg", 0.0, -2.0, 2.0, 0.0, "1/deg", feature=(1, R_EQ),
                           damping=True),)),
    )
    words = "nonlinear yaw damping"
    term = ("dr/dt gains n_rrr r^3 / s (cubic form, s the speed factor) or n_rr r|r| (modulus form); "
            "negative = more damping")
    signature = "yaw-acceleration error odd in r, growing with |r|: large manoeuvres over-predicted"
    floor_reason = f"{RESPONSE_FLOOR} (the precision model tests are trusted to)"

    def physical(self, form, values, ctx: Context) -> str:
        ((k, val),) = values.items()
        term = val * ctx.r_max**3 if form.name == "cubic" else val * ctx.r_max**2
        more = "more" if val < 0 else "less"
        return (
            f"yaw damping grows with the rate of turn ({form.name} form, {k} = {val:.3g}): at "
            f"r = {ctx.r_max:.2f} deg/s it adds {abs(term):.3g} deg/s^2 of {more} damping, so indices from "
            f"small manoeuvres mis-predict large ones"
        )

    def extra_estimate(self, form, values, ctx):
        return {"r_max_deg_s": ctx.r_max, "form": form.name}

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return r**3


EFFECT = NonlinearYawDamping()
