"""IMO MSC.137(76) Standards for ship manoeuvrability, checked on one run's metrics.

Criteria (L = Lpp, V = approach speed; L/V is a FULL-SCALE time, so model values are Froude-scaled
with the model scale factor lambda: (L/V)_full = (L/V)_model * sqrt(lambda)):

* turning ability (35 deg turning circle): advance <= 4.5 L, tactical diameter <= 5 L;
* initial turning ability (10/10 zigzag): track reach <= 2.5 L when the heading has changed by 10 deg;
* yaw checking, 10/10: first overshoot <= 10 deg if L/V < 10 s, <= 20 deg if L/V >= 30 s, else
  5 + 0.5 L/V deg; second overshoot <= 25 deg if L/V < 10 s, <= 40 deg if L/V >= 30 s, else
  17.5 + 0.75 L/V deg;
* yaw checking, 20/20: first overshoot <= 25 deg.

The scale factor comes from the run's metadata (``model_scale``, else ``scale_factor`` if > 1),
else from ``IndicesConfig.ship_scales`` by ship name; when unknown the model-scale L/V is used and
the result says so.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pipeline.config import IndicesConfig


def overshoot_limits(l_over_v: float) -> tuple[float, float]:
    """The IMO (MSC.137(76)) first and second overshoot limits of a 10/10 zigzag.

    Parameters
    ----------
    l_over_v : float
        Full-scale L/V, s.

    Returns
    -------
    tuple of float
        (first, second) overshoot limits, deg.
    """
    if l_over_v < 10:
        return 10.0, 25.0
    if l_over_v >= 30:
        return 20.0, 40.0
    return 5.0 + 0.5 * l_over_v, 17.5 + 0.75 * l_over_v


def model_scale(meta: dict[str, Any], cfg: IndicesConfig) -> float | None:
    """The geometric scale factor (full / model) of a run: its metadata's, else its ship's.

    Parameters
    ----------
    meta : dict
        Run metadata ("model_scale", "scale_factor" or "ship").
    cfg : IndicesConfig
        ``ship_scales``: the scale by ship name when the metadata gives none.

    Returns
    -------
    float or None
        The scale factor (dimensionless, > 1), None when unknown.
    """
    for key in ("model_scale",):
        if meta.get(key):
            return float(meta[key])
    sf = meta.get("scale_factor")
    if sf and float(sf) > 1:
        return float(sf)
    ship = str(meta.get("ship") or "").upper()
    return cfg.ship_scales.get(ship)


def _nominal(value, measured) -> float | None:
    v = value if value is not None else measured
    return None if v is None else float(round(float(v)))


def imo_check(kind: str, metrics: dict[str, Any], meta: dict[str, Any], *,
              config: IndicesConfig | None = None) -> dict[str, Any]:
    """IMO manoeuvring-standard check of one run (module docstring for the criteria).

    Parameters
    ----------
    kind : str
        'zigzag' or 'turning'.
    metrics : dict
        From :func:`pipeline.indices.zigzag.zigzag_metrics` or
        :func:`pipeline.indices.turning.turning_metrics` (a zigzag's ``reach_at_trigger_m`` gives the
        10/10 reach).
    meta : dict
        The run's metadata: lpp (m), approach_speed (m/s, model scale), model_scale, ship, rudder_deg,
        heading_deg (deg).
    config : IndicesConfig, optional
        ``ship_scales`` for the scale when the metadata gives none.

    Returns
    -------
    dict
        {"applicable": bool, "test", "l_over_v_s" (full-scale L/V, s), "scale", "criteria": [{"name",
        "value", "limit", "unit", "pass"}], "pass": bool or None, "note"}.
    """
    cfg = config or IndicesConfig()
    lpp = meta.get("lpp")
    lpp = float(lpp) if lpp else None
    u0 = metrics.get("approach_speed_m_s") or meta.get("approach_speed")
    scale = model_scale(meta, cfg)
    lv = None
    note = []
    if lpp and u0:
        lv = lpp / float(u0) * (np.sqrt(scale) if scale else 1.0)
        if not scale:
            note.append("model scale unknown: L/V taken at model scale")
    crit = []
    test = None
    if kind == "turning":
        rud = _nominal(meta.get("rudder_deg"), abs(metrics.get("rudder_deg") or 0))
        test = f"turning {rud:g}" if rud is not None else "turning"
        if rud is not None and rud >= 30:
            for name, key, lim in (("advance", "advance_L", 4.5),
                                   ("tactical diameter", "tactical_diameter_L", 5.0)):
                v = metrics.get(key)
                crit.append({"name": name, "value": v, "limit": lim, "unit": "L",
                             "pass": None if v is None else bool(v <= lim)})
    elif kind == "zigzag":
        rud = _nominal(meta.get("rudder_deg"), metrics.get("rudder_deg"))
        head = _nominal(meta.get("heading_deg"), metrics.get("heading_deg"))
        test = f"zigzag {rud:g}/{head:g}" if rud is not None and head is not None else "zigzag"
        if rud == 10 and head == 10:
            if lv is not None:
                l1, l2 = overshoot_limits(lv)
                for name, key, lim in (("first overshoot", "first_overshoot_deg", l1),
                                       ("second overshoot", "second_overshoot_deg", l2)):
                    v = metrics.get(key)
                    crit.append({"name": name, "value": v, "limit": lim, "unit": "deg",
                                 "pass": None if v is None else bool(v <= lim)})
            else:
                note.append("lpp or approach speed unknown: 10/10 limits cannot be set")
            reach = metrics.get("reach_at_trigger_m")
            if reach is not None and lpp:
                crit.append({"name": "initial turning (reach at 10 deg)", "value": reach / lpp,
                             "limit": 2.5, "unit": "L", "pass": bool(reach / lpp <= 2.5)})
        elif rud == 20 and head == 20:
            v = metrics.get("first_overshoot_deg")
            crit.append({"name": "first overshoot", "value": v, "limit": 25.0, "unit": "deg",
                         "pass": None if v is None else bool(v <= 25.0)})
    passes = [c["pass"] for c in crit if c["pass"] is not None]
    return {"applicable": bool(crit), "test": test, "l_over_v_s": lv, "scale": scale,
            "criteria": crit, "pass": (all(passes) if passes else None), "note": "; ".join(note)}
