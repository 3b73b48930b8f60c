"""speed_loss: the ship slows in the manoeuvre and the coefficients change with u."""

from __future__ import annotations

import numpy as np

from pipeline.diagnose.effects.base import Context, Effect, Form, Injection, Param, Terms

#: floor: the coefficients at the lowest speed differ by >= 5 % from the approach-speed ones
MIN_COEFF_CHANGE = 0.05
#: the effect is tried only when the speed falls by at least this fraction (else nothing to explain)
MIN_SPEED_LOSS = 0.03


class SpeedLoss(Effect):
    name = "speed_loss"
    label = "speed loss in turns"
    signature_axis = ("u", "surge speed u (m/s)")
    estimate_key = "coefficient_loss"
    magnitude_unit = "fraction of approach speed lost"
    injection = Injection(
        plants=("truth",), solver="speed_loss_for", field="speed_loss_k", estimate_is_coefficient=False,
        why_not=(("tank", "the tank's speed loss is its own (speed free or held), not a set magnitude"),))
    forms = (Form("power", (Param("speed_exponent", 0.0, -2.0, 5.0, 0.0, "1"),)),)
    words = "speed-dependent coefficients"
    term = "hull terms a_ij scale with s = (u/U)^n, rudder terms with s^2 (n = 1: dimensional physics)"
    signature = "yaw-acceleration error growing with ln(u/U) times the model's forces"
    floor_reason = f"coefficients at the lowest speed changed by >= {MIN_COEFF_CHANGE:.0%}"
    needs_u = True

    def applicable(self, ctx: Context):
        if ctx.u_ref is None or ctx.u_min_ratio is None:
            return "the runs have no surge speed u"
        loss = 1.0 - ctx.u_min_ratio
        if loss < MIN_SPEED_LOSS:
            return (
                f"the speed falls by only {loss:.1%} (below {MIN_SPEED_LOSS:.0%}): no speed loss to explain"
            )
        return None

    def apply(self, form, values, terms: Terms) -> None:
        terms.speed_exponent = float(values["speed_exponent"])

    def _change(self, values, ctx):
        return abs(1.0 - ctx.u_min_ratio ** values["speed_exponent"])

    def material(self, form, values, ctx, response_change):
        ch = self._change(values, ctx)
        return bool(
            ch >= MIN_COEFF_CHANGE
        ), f"coefficients at the lowest speed changed by {ch:.1%} (floor 5 %)"

    def physical(self, form, values, ctx):
        return (
            f"the coefficients scale as (u/U)^{values['speed_exponent']:.2f}: the ship lost "
            f"{1 - ctx.u_min_ratio:.0%} of its {ctx.u_ref:.3f} m/s approach speed, which changed its hull "
            f"coefficients by {self._change(values, ctx):.0%}"
        )

    def extra_estimate(self, form, values, ctx):
        lo = ctx.u_min_ratio
        return {
            "u_ref_m_s": ctx.u_ref,
            "max_speed_loss": 1.0 - lo,
            "coefficient_loss": 1.0 - lo ** values["speed_exponent"],
        }

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        if u_ratio is None:
            return None
        return np.log(np.clip(u_ratio, 0.05, None)) * r


EFFECT = SpeedLoss()
