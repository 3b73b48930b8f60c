"""rudder_offset: the effective rudder is the logged one plus a constant (docs/diagnosis.md)."""

from __future__ import annotations

import numpy as np

from pipeline.diagnose.effects.base import Context, Effect, Form, Injection, Param, Terms

#: deg: floor of a named offset.  A tank's rudder encoder resolves ~0.1 deg and the neutral rudder is
#: set to ~0.1-0.2 deg; an offset below 0.3 deg (3 resolutions) is not distinguishable from the zero
#: setting and is not worth a helmsman's correction.
MIN_OFFSET_DEG = 0.3


class RudderOffset(Effect):
    name = "rudder_offset"
    label = "rudder offset"
    signature_axis = ("delta", "logged rudder delta (deg)")
    estimate_key = "offset_deg"
    magnitude_unit = "deg"
    injection = Injection(plants=("truth", "tank"), direct=True)
    forms = (Form("constant", (Param("offset_deg", 0.0, -10.0, 10.0, 0.0, "deg"),)),)
    words = "a constant rudder offset"
    term = "delta_eff = delta + offset_deg (in every rudder term)"
    signature = "a constant yaw acceleration: steady heading drift on a straight rudder"
    floor_reason = (
        f"|offset| >= {MIN_OFFSET_DEG} deg: three times a tank rudder encoder's 0.1 deg resolution, "
        "the least neutral-rudder error worth correcting"
    )

    def apply(self, form: Form, values: dict, terms: Terms) -> None:
        terms.offset_deg = float(values["offset_deg"])

    def material(self, form, values, ctx, response_change):
        off = abs(values["offset_deg"])
        return bool(off >= MIN_OFFSET_DEG), f"|offset| {off:.2f} deg (floor {MIN_OFFSET_DEG} deg)"

    def physical(self, form: Form, values: dict, ctx: Context) -> str:
        off = values["offset_deg"]
        side = "starboard" if off > 0 else "port"
        return (
            f"the rudder acts as if {abs(off):.2f} deg to {side} of its logged angle: a steady yaw moment "
            f"equal to that much rudder, typical of a single propeller's asymmetric flow or a "
            f"neutral-rudder setting error"
        )

    def extra_estimate(self, form, values, ctx):
        return {"offset_share_of_max_rudder": abs(values["offset_deg"]) / max(ctx.d_max, 1e-9)}

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return np.ones_like(r)


EFFECT = RudderOffset()
