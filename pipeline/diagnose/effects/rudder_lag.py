"""rudder_lag: the effective rudder follows the logged one through a first-order lag (servo)."""

from __future__ import annotations

from pipeline.diagnose.effects.base import Effect, Form, Injection, Param, Terms
from pipeline.diagnose.effects.rudder_delay import MIN_SHARE_OF_T, MIN_STEPS, time_floor


class RudderLag(Effect):
    name = "rudder_lag"
    label = "steering-gear lag"
    signature_axis = ("ddelta", "rudder rate d(delta)/dt (deg/s)")
    estimate_key = "lag_s"
    magnitude_unit = "s (servo time constant)"
    injection = Injection(plants=("truth", "tank"), direct=True)
    forms = (Form("first_order", (Param("lag_s", 0.0, 0.0, 0.4, 0.0, "s", time_scaled=True),)),)
    words = "a first-order rudder servo lag"
    term = "lag_s d(delta_eff)/dt = delta - delta_eff (steering-gear time constant)"
    signature = "like a dead time, but the yaw error after a reversal decays exponentially, not as a shift"
    floor_reason = (
        f"time constant >= max({MIN_STEPS} sample steps, {MIN_SHARE_OF_T:.0%} of the ship's time scale)"
    )

    def apply(self, form, values, terms: Terms) -> None:
        terms.lag_s = max(float(values["lag_s"]), 0.0)

    def material(self, form, values, ctx, response_change):
        f = time_floor(ctx)
        return bool(values["lag_s"] >= f), f"time constant {values['lag_s']:.3f} s (floor {f:.3f} s)"

    def physical(self, form, values, ctx):
        return (
            f"the rudder follows its logged command through a first-order lag of {values['lag_s']:.2f} s "
            f"(steering-gear time constant; the logged angle is the order, not the blade)"
        )

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return -ddelta


EFFECT = RudderLag()
