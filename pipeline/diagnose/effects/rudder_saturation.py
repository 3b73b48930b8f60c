"""rudder_saturation: the rudder force stops growing linearly with the angle (a cubic term in delta)."""

from __future__ import annotations

from pipeline.diagnose.effects.base import Effect, Form, Injection, Param, Terms

#: floor: the force at the largest rudder angle differs from the linear one by >= 5 % (the precision
#: a rudder force is measured to in captive tests)
MIN_FORCE_CHANGE = 0.05


class RudderSaturation(Effect):
    name = "rudder_saturation"
    label = "rudder saturation (stall)"
    signature_axis = ("delta", "logged rudder delta (deg)")
    estimate_key = "force_change_at_max_rudder"
    magnitude_unit = "rudder force lost at 20 deg (stall tanh(delta/stall) law)"
    injection = Injection(plants=("truth", "tank"))
    forms = (Form("cubic", (Param("rudder_cubic_per_deg2", 0.0, -5e-3, 5e-3, 0.0, "1/deg^2"),)),)
    words = "a saturating rudder force"
    term = "rudder force ~ delta_eff + c delta_eff^3 (c < 0: saturation/stall)"
    signature = "yaw-acceleration error odd in delta, growing with |delta|^3"
    floor_reason = f"force at the largest rudder angle changed by >= {MIN_FORCE_CHANGE:.0%}"

    def apply(self, form, values, terms: Terms) -> None:
        terms.rudder_cubic_per_deg2 = float(values["rudder_cubic_per_deg2"])

    def material(self, form, values, ctx, response_change):
        ch = abs(values["rudder_cubic_per_deg2"]) * ctx.d_max**2
        return bool(ch >= MIN_FORCE_CHANGE), (
            f"rudder force at {ctx.d_max:.0f} deg changed by {ch:.1%} (floor {MIN_FORCE_CHANGE:.0%})"
        )

    def physical(self, form, values, ctx):
        ch = values["rudder_cubic_per_deg2"] * ctx.d_max**2
        if ch < 0:
            return (
                f"at {ctx.d_max:.0f} deg the rudder gives {abs(ch):.0%} less force than a linear rudder "
                f"(stall or saturation of the lift at large angles)"
            )
        # c > 0 is not stall: the force grows faster than the angle over the range the runs cover
        return (
            f"at {ctx.d_max:.0f} deg the rudder gives {ch:.0%} more force than a linear rudder: its "
            f"force grows faster than the angle over the runs' range (not stall, which gives less)"
        )

    def extra_estimate(self, form, values, ctx):
        return {
            "force_change_at_max_rudder": values["rudder_cubic_per_deg2"] * ctx.d_max**2,
            "max_rudder_deg": ctx.d_max,
        }

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return delta**3

    def inject(self, plant, magnitude, cfg, rudder_deg=20.0):
        """The magnitude is the rudder force lost at 20 deg (the rudder of the 20/20 design that defines
        every truth magnitude), set as a tanh stall (``rudder_stall_deg``); the true value is the
        estimate's force change at the largest logged rudder ``rudder_deg`` (deg): on the truth -magnitude
        (the same quantity when the study's rudder is 20 deg), on the tank the loss at ``rudder_deg``,
        the largest its zigzags reach."""
        import dataclasses

        from pipeline.diagnose.truth import stall_for_loss, stall_loss

        if plant not in self.injection.plants:
            return super().inject(plant, magnitude, cfg, rudder_deg)
        stall = stall_for_loss(magnitude, 20.0)
        true_value = -magnitude if plant == "truth" else -stall_loss(stall, rudder_deg)
        return dataclasses.replace(cfg, rudder_stall_deg=stall), true_value


EFFECT = RudderSaturation()
