"""Ship, scale and particulars of a dataset, from ``runs/index.json``, for every report and the index.

Where the facts come from (first found wins):

* the dataset description that ingest copies into ``runs/index.json`` from ``dataset.toml``
  (docs/dataset.md): top-level ``"ship"``, a table of ``{"ship" (the name), "lpp_m", "beam_m",
  "draught_m", "design_speed_kn"`` (full scale), ``"scale"`` (full/model of the values in the files),
  ``"model_scale"`` (full/model of the tank model), ``"tank"``, ``"source"``, ``"dataset_toml"``
  (the file it was read from)``}``; the older layouts (``"ship": {"name", ...}`` with
  ``"data": {"scale", "tank", "source"}``, or the same keys under ``"particulars"``) are read too;
* the runs' own metadata: ``ship``, ``lpp`` (m, model scale, as the files' headers give it),
  ``model_scale`` (full/model geometric scale of the ship model), ``scale_factor`` (what ingest
  applied to the values; 1 = the files were at model scale) and ``approach_speed`` (m/s, model scale).

Scale conventions of the pages (docs/reports.md): every stage works at model scale.  When the user's
files are at full scale (``scale`` > 1: ingest Froude-scaled them by 1:scale), the pages give times and
speeds at full scale as well, labelled, by Froude similarity with the same factor
(:func:`full_scale_factor`, :func:`to_full`): t_full = t_model sqrt(scale), U_full = U_model sqrt(scale)
(in kn), rates / sqrt(scale).

Units: lengths in m, speeds in m/s (model scale) or kn (full scale), as labelled.
Nothing here guesses: a fact that is not in the index is reported as "not given".
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from pipeline.units import FROUDE_EXPONENT, KNOT, G

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
    # ingest's layout: the dataset.toml's [ship] and [data] in one table under "ship"
    described = {**ship_block, **data_block}

    names = _unique(runs, "ship")
    ship = _first(ship_block.get("name"),
                  ship_block.get("ship") if isinstance(ship_block.get("ship"), str) else None,
                  part.get("name"), index.get("ship") if isinstance(index.get("ship"), str) else None,
                  " / ".join(map(str, names)) if names else None)
    scales = [s for s in (_num(x) for x in _unique(runs, "model_scale")) if s]
    # geometric scale of the tank model: ingest's model_scale, else an older layout's data.scale
    scale = _num(_first(described.get("model_scale"), part.get("model_scale"), data_block.get("scale"),
                        part.get("scale"), scales[0] if len(scales) == 1 else None))
    applied = [s for s in (_num(x) for x in _unique(runs, "scale_factor")) if s]
    if not applied and _num(ship_block.get("scale")):      # ingest's layout: the files' own scale
        applied = [_num(ship_block.get("scale"))]
    lpp_full = _num(_first(ship_block.get("lpp_m"), part.get("lpp_m")))
    lpps = [v for v in (_num(x) for x in _unique(runs, "lpp")) if v]
    lpp_model = _num(_first(part.get("lpp_model_m"), ship_block.get("lpp_model_m"),
                            lpps[0] if len(lpps) == 1 else None))
    if lpp_model is None and lpp_full and scale:
        lpp_model = lpp_full / scale
    if lpp_full is None and lpp_model and scale:
        lpp_full = lpp_model * scale
    speeds = [v for v in (_num(r.get("approach_speed")) for r in runs) if v is not None]
    u_range = (min(speeds), max(speeds)) if speeds else None
    froude = None
    if u_range and lpp_model:
        froude = tuple(u / math.sqrt(G * lpp_model) for u in u_range)
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
        "tank": _first(described.get("tank"), part.get("tank")),
        "source": _first(described.get("source"), part.get("source")),
        "provenance": _first(index.get("provenance")),
        "dataset_toml": _first(described.get("dataset_toml"), part.get("dataset_toml")),
    }


def full_scale_factor(index: dict) -> float | None:
    """The Froude scale (full/model, -) to show times and speeds at full scale, or None.

    Given only when the user's files are at full scale (ingest applied a scale factor > 1 to every
    run): the user thinks in full-scale seconds and knots.  Model-scale files (factor 1), mixed or
    unknown factors give None (the pages then give model scale only, as the stages compute).
    """
    applied = particulars(index)["files_scale_factor"]
    if isinstance(applied, float) and applied > 1:
        return applied
    return None


def to_full(value: Any, kind: str, scale: float) -> Any:
    """A model-scale quantity at full scale by Froude similarity (pipeline.units.FROUDE_EXPONENT).

    Parameters
    ----------
    value : float or array, the model-scale value(s) in SI or degree units (s, m/s, deg/s, 1/s, ...).
    kind : 'time', 'velocity', 'rate', 'frequency', 'length' or 'angle'.
    scale : geometric scale full/model (> 0).

    Returns
    -------
    The full-scale value(s) in the same unit (a velocity stays in m/s: divide by pipeline.units.KNOT for kn).
    """
    if kind not in FROUDE_EXPONENT:
        raise ValueError(f"unknown Froude quantity kind {kind!r}")
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive finite number, got {scale!r}")
    out = np.asarray(value, dtype=float) * float(scale) ** -FROUDE_EXPONENT[kind]
    return float(out) if np.ndim(out) == 0 else out


# unit in a label's last parentheses -> (Froude kind, the full-scale unit, factor to that unit)
_UNIT_KINDS = {"s": ("time", "s", 1.0), "deg^2 s": ("time", "deg^2 s", 1.0),
               "1/s": ("rate", "1/s", 1.0), "deg/s": ("rate", "deg/s", 1.0), "rad/s": ("rate", "rad/s", 1.0),
               "m/s": ("velocity", "kn", 1.0 / KNOT)}
_LABEL_UNIT = re.compile(r"^(.*?)\s*\(([^()]*)\)\s*$")


def full_scale_label(label: str, scale: float, value: Any = None) -> tuple[str, Any] | None:
    """(full-scale label, full-scale value) for a label 'name (unit)' whose unit scales with Froude
    (s, deg^2 s, 1/s, deg/s, rad/s; m/s given in kn), else None.  Example: ('T (s)', 10.0) at
    scale 49 gives ('T, full scale (s)', 70.0)."""
    m = _LABEL_UNIT.match(str(label))
    if not m or m[2].strip() not in _UNIT_KINDS:
        return None
    kind, unit, factor = _UNIT_KINDS[m[2].strip()]
    full = None if value is None else to_full(value, kind, scale) * factor
    return f"{m[1]}, full scale ({unit})", full


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
        ("approach speed, full scale (kn)",
         _range(tuple(to_full(u, "velocity", p["scale"]) / KNOT for u in p["approach_speed_m_s"]), ".3g")
         if p["approach_speed_m_s"] and p["scale"] else NOT_GIVEN),
        ("Froude number at approach", _range(p["froude"], ".3f")),
        ("tank", p["tank"] or NOT_GIVEN),
        ("source", p["source"] or NOT_GIVEN),
        ("provenance", p["provenance"] or NOT_GIVEN),
        ("described in", p["dataset_toml"] or NOT_GIVEN),
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


def identity(index: dict) -> dict[str, str]:
    """What tells this dataset from another of the same ship, as plain text ("not given" when absent):
    ship, scale (with the files' own scale), tank, source, provenance, dataset description file."""
    p = particulars(index)
    applied = p["files_scale_factor"]
    files = ("full-scale files" if isinstance(applied, float) and applied > 1
             else "model-scale files" if applied == 1 else None)
    scale = NOT_GIVEN if p["scale"] is None else f"1:{p['scale']:g}"
    return {"ship": str(p["ship"] or NOT_GIVEN), "scale": scale + (f" ({files})" if files else ""),
            "tank": str(p["tank"] or NOT_GIVEN), "source": str(p["source"] or NOT_GIVEN),
            "provenance": str(p["provenance"] or NOT_GIVEN),
            "described in": str(p["dataset_toml"] or NOT_GIVEN)}


def scale_sentence(index: dict) -> str:
    """One sentence for a page: at which scale its times and speeds are, and how to reach full scale."""
    p = particulars(index)
    lam = full_scale_factor(index)
    if lam is not None:
        return (f"The files are at full scale; ingest brought them to model scale 1:{lam:g} (Froude), where "
                f"every stage computes. Times and speeds are given at model scale and, labelled 'full "
                f"scale', at the files' scale: t_full = t_model x sqrt({lam:g}) = t_model x "
                f"{math.sqrt(lam):.3g}; U_full = U_model x {math.sqrt(lam):.3g} (in kn); rates / "
                f"{math.sqrt(lam):.3g}.")
    if p["scale"]:
        return (f"Times and speeds are at model scale 1:{p['scale']:g}, as the files give them; at full "
                f"scale times and speeds are {math.sqrt(p['scale']):.3g} times larger (Froude).")
    return "Times and speeds are at the scale of the files (the scale is not given)."

