"""rudder_asymmetry: the rudder is more effective to one side than to the other."""

from __future__ import annotations

import numpy as np

from pipeline.diagnose.effects.base import Effect, Form, Injection, Param, Terms

#: floor: the two sides' effectiveness differs by >= 6 % (asymmetry >= 3 %), twice the 3 % a well-
#: trimmed single-screw model shows between port and starboard zigzag overshoots in repeat tests
MIN_ASYMMETRY = 0.03


class RudderAsymmetry(Effect):
    name = "rudder_asymmetry"
    label = "rudder asymmetry (port/starboard)"
    signature_axis = ("delta", "logged rudder delta (deg)")
    estimate_key = "asymmetry"
    magnitude_unit = "a: rudder force x (1 + a sign(delta))"
    injection = Injection(plants=("truth", "tank"), direct=True)
    forms = (Form("two_sided", (Param("asymmetry", 0.0, -0.5, 0.5, 0.0, "1"),)),)
    words = "a rudder more effective to one side"
    term = "rudder force ~ delta_eff (1 + a sign(delta_eff)); a > 0: more effective to starboard"
    signature = "yaw-acceleration error proportional to |delta|: port and starboard responses differ"
    floor_reason = f"|a| >= {MIN_ASYMMETRY:.0%} (sides differ by {2 * MIN_ASYMMETRY:.0%})"

    def apply(self, form, values, terms: Terms) -> None:
        terms.asymmetry = float(values["asymmetry"])

    def material(self, form, values, ctx, response_change):
        a = abs(values["asymmetry"])
        return bool(a >= MIN_ASYMMETRY), f"|asymmetry| {a:.1%} (floor {MIN_ASYMMETRY:.0%})"

    def physical(self, form, values, ctx):
        a = values["asymmetry"]
        strong, weak = ("starboard", "port") if a > 0 else ("port", "starboard")
        ratio = (1 + abs(a)) / max(1 - abs(a), 1e-9)
        return (
            f"the rudder is {ratio - 1:.0%} more effective to {strong} than to {weak}: the propeller "
            f"slipstream's rotation, typical of a single screw"
        )

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return np.abs(delta)


EFFECT = RudderAsymmetry()
