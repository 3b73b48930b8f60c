"""rudder_delay: the effective rudder lags the logged one by a dead time."""

from __future__ import annotations

from pipeline.diagnose.effects.base import Effect, Form, Injection, Param, Terms

#: floor, as a share of the ship's time scale: a dead time below 3 % of T shifts the yaw response by
#: less than 3 % of its own time scale, the timing precision of a zigzag's time to check yaw
MIN_SHARE_OF_T = 0.03
#: and at least 1.5 sample steps: a shorter one is not resolved by the log
MIN_STEPS = 1.5


def time_floor(ctx) -> float:
    return max(MIN_STEPS * ctx.h, MIN_SHARE_OF_T * ctx.t_ship)


class RudderDelay(Effect):
    name = "rudder_delay"
    label = "rudder dead time"
    signature_axis = ("ddelta", "rudder rate d(delta)/dt (deg/s)")
    estimate_key = "delay_s"
    magnitude_unit = "s"
    injection = Injection(plants=("truth", "tank"), direct=True)
    forms = (Form("dead_time", (Param("delay_s", 0.0, -0.02, 0.4, 0.0, "s", time_scaled=True),)),)
    words = "a rudder dead time"
    term = "delta_eff(t) = delta(t - delay_s) (logged rudder interpolated)"
    signature = "yaw-acceleration error proportional to -d(delta)/dt at every rudder reversal"
    floor_reason = (
        f"delay >= max({MIN_STEPS} sample steps, {MIN_SHARE_OF_T:.0%} of the ship's time scale): "
        "shorter is not resolved by the log nor visible in a zigzag's timing"
    )

    def apply(self, form, values, terms: Terms) -> None:
        terms.delay_s = float(values["delay_s"])

    def material(self, form, values, ctx, response_change):
        f = time_floor(ctx)
        return bool(values["delay_s"] >= f), f"dead time {values['delay_s']:.3f} s (floor {f:.3f} s)"

    def physical(self, form, values, ctx):
        return (
            f"the rudder acts {values['delay_s']:.2f} s after it is logged "
            f"({values['delay_s'] / ctx.t_ship:.0%} "
            f"of the ship's {ctx.t_ship:.1f} s time scale): an actuator or logging dead time"
        )

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return -ddelta


EFFECT = RudderDelay()
