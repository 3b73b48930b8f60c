"""Ship, scale and particulars of a dataset, from ``runs/index.json``, for every report and the index.

Where the facts come from (first found wins):

* the dataset description that ingest copies into ``runs/index.json`` from ``dataset.toml``
  (SPEC section 9): top-level ``"ship"`` (``{"name", "lpp_m", "beam_m", "draught_m",
  "design_speed_kn"}``, full scale) and ``"data"`` (``{"scale", "tank", "source"}``), or the same keys
  under ``"particulars"``;
* the runs' own metadata: ``ship``, ``lpp`` (m, model scale, as the files' headers give it),
  ``model_scale`` (full/model geometric scale of the ship model), ``scale_factor`` (what ingest
  applied to the values; 1 = the files were at model scale) and ``approach_speed`` (m/s, model scale).

Units: lengths in m, speeds in m/s (model scale) or kn (full scale design speed), as labelled.
Nothing here guesses: a fact that is not in the index is reported as "not given".
"""

from __future__ import annotations

import math
from typing import Any

NOT_GIVEN = "not given"


def _num(x: Any) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _first(*values: Any) -> Any:
    return next((v for v in values if v not in (None, "", [], {})), None)


def _unique(runs: list[dict], key: str) -> list[Any]:
    return list(dict.fromkeys(r.get(key) for r in runs if r.get(key) not in (None, "")))


def particulars(index: dict) -> dict[str, Any]:
    """The dataset's ship and scale as plain values (None when not given).

    Keys: ship, scale (full/model), files_scale_factor (applied at ingest), lpp_model_m,
    lpp_full_m, beam_full_m, draught_full_m, design_speed_kn, approach_speed_m_s (min, max over the
    runs, model scale), froude (approach, model), tank, source.
    """
    index = index if isinstance(index, dict) else {}
    runs = [r for r in index.get("runs") or [] if isinstance(r, dict)]
    part = index.get("particulars") if isinstance(index.get("particulars"), dict) else {}
    ship_block = index.get("ship") if isinstance(index.get("ship"), dict) else part.get("ship") or {}
    data_block = index.get("data") if isinstance(index.get("data"), dict) else part.get("data") or {}
    ship_block = ship_block if isinstance(ship_block, dict) else {}
    data_block = data_block if isinstance(data_block, dict) else {}

    names = _unique(runs, "ship")
    ship = _first(ship_block.get("name"), part.get("name"),
                  index.get("ship") if isinstance(index.get("ship"), str) else None,
                  " / ".join(map(str, names)) if names else None)
    scales = [s for s in (_num(x) for x in _unique(runs, "model_scale")) if s]
    scale = _num(_first(data_block.get("scale"), part.get("scale"), scales[0] if len(scales) == 1 else None))
    applied = [s for s in (_num(x) for x in _unique(runs, "scale_factor")) if s]
    lpp_full = _num(_first(ship_block.get("lpp_m"), part.get("lpp_m")))
    lpps = [v for v in (_num(x) for x in _unique(runs, "lpp")) if v]
    lpp_model = _num(_first(part.get("lpp_model_m"), lpps[0] if len(lpps) == 1 else None))
    if lpp_model is None and lpp_full and scale:
        lpp_model = lpp_full / scale
    if lpp_full is None and lpp_model and scale:
        lpp_full = lpp_model * scale
    speeds = [v for v in (_num(r.get("approach_speed")) for r in runs) if v is not None]
    u_range = (min(speeds), max(speeds)) if speeds else None
    froude = None
    if u_range and lpp_model:
        froude = tuple(u / math.sqrt(9.81 * lpp_model) for u in u_range)
    return {
        "ship": ship,
        "scale": scale,
        "files_scale_factor": applied[0] if len(applied) == 1 else (tuple(applied) if applied else None),
        "lpp_model_m": lpp_model,
        "lpp_full_m": lpp_full,
        "beam_full_m": _num(_first(ship_block.get("beam_m"), part.get("beam_m"))),
        "draught_full_m": _num(_first(ship_block.get("draught_m"), part.get("draught_m"))),
        "design_speed_kn": _num(_first(ship_block.get("design_speed_kn"), part.get("design_speed_kn"))),
        "approach_speed_m_s": u_range,
        "froude": froude,
        "tank": _first(data_block.get("tank"), part.get("tank")),
        "source": _first(data_block.get("source"), part.get("source")),
    }


def _range(rng: tuple[float, float] | None, fmt: str) -> str:
    if rng is None:
        return NOT_GIVEN
    a, b = format(rng[0], fmt), format(rng[1], fmt)
    return a if a == b else f"{a} to {b}"


def rows(index: dict) -> list[tuple[str, str]]:
    """(label, text) pairs for a particulars table, units in the labels; plain text (not escaped)."""
    p = particulars(index)

    def f(v, fmt=".4g"):
        return NOT_GIVEN if v is None else format(v, fmt)

    applied = p["files_scale_factor"]
    if applied is None:
        files = NOT_GIVEN
    elif isinstance(applied, tuple):
        files = "mixed: " + ", ".join(f"{a:g}" for a in applied)
    elif applied == 1:
        files = "model scale (taken as they are)"
    else:
        files = f"full scale, Froude-scaled by 1:{applied:g} at ingest"
    return [
        ("ship", p["ship"] or NOT_GIVEN),
        ("scale (full/model)", NOT_GIVEN if p["scale"] is None else f"1:{p['scale']:g}"),
        ("raw files", files),
        ("Lpp, model (m)", f(p["lpp_model_m"])),
        ("Lpp, full scale (m)", f(p["lpp_full_m"])),
        ("beam, full scale (m)", f(p["beam_full_m"])),
        ("draught, full scale (m)", f(p["draught_full_m"])),
        ("design speed, full scale (kn)", f(p["design_speed_kn"])),
        ("approach speed, model (m/s)", _range(p["approach_speed_m_s"], ".3g")),
        ("Froude number at approach", _range(p["froude"], ".3f")),
        ("tank", p["tank"] or NOT_GIVEN),
        ("source", p["source"] or NOT_GIVEN),
    ]


def summary(index: dict) -> str:
    """One line: 'KCS, model 1:37.89, Lpp 6.07 m (model), approach 2.0 m/s (Fn 0.260)'; plain text."""
    p = particulars(index)
    parts = [str(p["ship"] or "ship not given")]
    parts.append(f"model 1:{p['scale']:g}" if p["scale"] else "scale not given")
    if p["lpp_model_m"]:
        full = f", {p['lpp_full_m']:.4g} m full scale" if p["lpp_full_m"] else ""
        parts.append(f"Lpp {p['lpp_model_m']:.4g} m model{full}")
    else:
        parts.append("Lpp not given")
    if p["approach_speed_m_s"]:
        fn = f" (Fn {_range(p['froude'], '.3f')})" if p["froude"] else ""
        parts.append(f"approach {_range(p['approach_speed_m_s'], '.3g')} m/s{fn}")
    if p["tank"]:
        parts.append(f"tank: {p['tank']}")
    return ", ".join(parts)
