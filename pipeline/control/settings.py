"""The ship's autopilot settings: the ``[control]`` table of a dataset.toml (docs/control.md).

Keys (all optional; units in the name):

* ``tw_s``: closed-loop time constant Tw of the CGSA design, s (also sets the PID's natural frequency);
* ``rudder_max_deg``: rudder angle limit, deg;
* ``rudder_rate_deg_s``: steering-gear rate limit, deg/s;
* ``servo_time_constant_s``: first-order lag of the steering gear, s (0: rate limit only);
* ``dead_time_s``: dead time between the autopilot's command and the rudder's response, s;
* ``setpoint_deg``: course step of the simulated course change, deg.

The defaults (:class:`pipeline.config.ControlConfig`) are the KCS's at model scale (the built-in
virtual tank's steering gear: 35 deg, 14.28 deg/s, no lag, no dead time) and the paper's Tw = 3 s and
60 deg course change.  For any other ship a missing key means the KCS's value is assumed, and one
notice line says which keys were.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from pipeline.config import ControlConfig
from pipeline.errors import InputError

#: dataset.toml key -> (ControlConfig field, least allowed value, strict)
KEYS: dict[str, tuple[str, float, bool]] = {
    "tw_s": ("tw", 0.0, True),
    "rudder_max_deg": ("rudder_max", 0.0, True),
    "rudder_rate_deg_s": ("rudder_rate", 0.0, True),
    "servo_time_constant_s": ("servo_time_constant", 0.0, False),
    "dead_time_s": ("dead_time", 0.0, False),
    "setpoint_deg": ("setpoint", -180.0, False),
}

#: ship names whose steering gear the defaults describe (the built-in virtual tank's hull)
DEFAULT_SHIPS = ("KCS",)


def parse_control_table(table: Any, path: Path | str | None = None) -> dict[str, float]:
    """Validated ``[control]`` values (key -> float, units as in the key's name).

    Raises InputError naming the file and key for an unknown key, a value that is not a number, not
    finite, or out of range (tw_s, rudder_max_deg, rudder_rate_deg_s > 0; servo_time_constant_s,
    dead_time_s >= 0; setpoint_deg in (-180, 180], non-zero).
    """
    if table is None:
        return {}
    if not isinstance(table, dict):
        raise InputError("[control] must be a table", file=path)
    out: dict[str, float] = {}
    for key, value in table.items():
        if key not in KEYS:
            raise InputError(f"unknown key {key!r} in [control] (known: {', '.join(KEYS)})", file=path)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"[control] {key} must be a number, got {value!r}", file=path)
        x = float(value)
        _, low, strict = KEYS[key]
        if not math.isfinite(x) or (x <= low if strict else x < low):
            raise InputError(f"[control] {key} = {value!r} must be {'>' if strict else '>='} {low:g}"
                             " and finite", file=path)
        if key == "setpoint_deg" and (x == 0 or x > 180):
            raise InputError(f"[control] setpoint_deg = {value!r} must be a non-zero course step within "
                             "(-180, 180] deg", file=path)
        if key == "rudder_max_deg" and x > 90:
            raise InputError(f"[control] rudder_max_deg = {value!r} is beyond 90 deg", file=path)
        out[key] = x
    return out


def apply(cfg: ControlConfig, values: dict[str, float], ship: str | None) -> tuple[ControlConfig, str | None]:
    """``cfg`` with the dataset's ``[control]`` values, and the one-line notice of what was assumed.

    No notice for the ships the defaults describe (:data:`DEFAULT_SHIPS`) or when every key is given.
    """
    cfg = replace(cfg, **{KEYS[k][0]: v for k, v in values.items()})
    missing = [k for k in KEYS if k not in values]
    if not missing or (ship or "").upper() in DEFAULT_SHIPS:
        return cfg, None
    shown = ", ".join(f"{k} = {getattr(cfg, KEYS[k][0]):g}" for k in missing)
    return cfg, (f"control: ship {ship or 'unnamed'}: [control] in dataset.toml does not give {shown}; "
                 "the KCS model-scale steering gear and the paper's Tw and course step are assumed")


def read_dataset_control(toml_path: str | Path | None) -> dict[str, float]:
    """The validated ``[control]`` table of a dataset.toml ({} when there is no file or no table)."""
    import tomllib

    if not toml_path:
        return {}
    p = Path(toml_path)
    if not p.is_file():
        return {}
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"not valid TOML ({exc})", file=p) from None
    return parse_control_table(doc.get("control"), p)
