"""rudder_asymmetry: the rudder is more effective to one side than to the other."""

from __future__ import annotations

import numpy as np

from pipeline.diagnose.effects.base import Effect, Form, Injection, Param, Terms
from pipeline.diagnose.effects.rudder_offset import MIN_OFFSET_DEG

#: deg: floor of a named asymmetry, as the effective rudder angle it adds at the runs' largest rudder
#: angle (|a| d_max): an asymmetry a moves the effective rudder by a |delta| on each side, the offset
#: of that side, so it is held to the offset's floor (three rudder-encoder resolutions, the least
#: neutral-rudder error worth correcting; rudder_offset.MIN_OFFSET_DEG).  At 35 deg of rudder that is
#: |a| >= 0.9 %, at 10 deg |a| >= 3 %
MIN_ASYMMETRY_DEG = MIN_OFFSET_DEG


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
    floor_reason = (
        f"|a| d_max >= {MIN_ASYMMETRY_DEG} deg: the effective rudder it adds at the runs' largest rudder "
        "angle held to the rudder offset's floor"
    )

    def apply(self, form, values, terms: Terms) -> None:
        terms.asymmetry = float(values["asymmetry"])

    def material(self, form, values, ctx, response_change):
        a = abs(values["asymmetry"])
        deg = a * ctx.d_max
        return bool(deg >= MIN_ASYMMETRY_DEG), (
            f"|asymmetry| {a:.1%}, {deg:.2f} deg of rudder at {ctx.d_max:.0f} deg "
            f"(floor {MIN_ASYMMETRY_DEG} deg)")

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
