"""Where the autopilot is designed: at the course-keeping operating point (docs/control.md, "Operating
point").

Course keeping holds the rudder within a few degrees of its offset, where a ship answers as it does in
the smallest zigzag, not in the 20/20 one the identification and the paper's CGSA use (the built-in
KCS: K' 0.92 at 20/20, 1.7 at 10/10, 7.3 linearised straight ahead).  Two bases are compared:

* ``design_model``: the model the held-out rule chose (pipeline/indices/design_model.py), at the
  identification run's amplitude;
* ``small_amplitude``: the first-order K (1/s), T (s) of the standard (graphical) method, averaged
  over the zigzags of the smallest rudder angle in the dataset,

and, where the ship is known (the built-in tank), the linearisation straight ahead as a third plant.
For each basis the CGSA and the PID are designed and their sampled loops are scored on every plant.

Rule (``ControlConfig.operating_point``): the project's autopilot (PID) is designed from the
small-amplitude model when there is one whose K, T carry no blocking flag (sign, ill-conditioned) and
whose PID keeps a stable sampled loop with a phase margin of at least ``min_phase_margin`` on the
design model too (the zigzag amplitude it may meet in a course change); otherwise from the design
model, saying why.  The CGSA rows stay on the design model: they are the paper's chain.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from pipeline.config import ControlConfig
from pipeline.control.autopilot import design_pid
from pipeline.control.design import design_first_order
from pipeline.control.robust import sampled_margins


def _amplitude(label: str) -> float | None:
    m = re.match(r"\s*(\d+(?:\.\d+)?)\s*/", str(label))
    return float(m.group(1)) if m else None


def small_amplitude_model(indices: dict) -> tuple[dict | None, str]:
    """First-order K (1/s), T (s) of the smallest-amplitude zigzags (standard method, their mean), or
    None and why.  Rows whose K or T carry a blocking flag (pipeline.indices.trust.blocking) are left
    out; an amplitude none of whose rows is usable gives None."""
    from pipeline.indices.trust import blocking

    rows = [r for r in indices.get("graphical") or [] if r.get("method") == "standard"
            and _amplitude(r.get("test", "")) is not None]
    if not rows:
        return None, "no zigzag with a standard-method K, T and a known amplitude"
    amp = min(_amplitude(r["test"]) for r in rows)
    here = [r for r in rows if _amplitude(r["test"]) == amp]
    good = [r for r in here if not blocking(list(r.get("flags") or []), ("K", "T"))
            and r.get("K", 0) > 0 and r.get("T", 0) > 0]
    if not good:
        why = "; ".join(f.get("reason", "") for r in here for f in blocking(list(r.get("flags") or []),
                                                                             ("K", "T")))
        return None, (f"the {amp:g} deg zigzags' standard-method K, T are not usable"
                      + (f" ({why})" if why else " (K or T not positive)"))
    k = float(np.mean([r["K"] for r in good]))
    t = float(np.mean([r["T"] for r in good]))
    tests = sorted({r["test"] for r in good})
    return ({"K": k, "T1": t, "T2": 0.0, "T3": 0.0, "T": t, "rudder_deg": amp,
             "runs": [r["run_id"] for r in good],
             "source": f"standard (graphical) method, mean over the {', '.join(tests)} zigzags "
                       f"({len(good)} runs)"}, "")


def _pid(K: float, T: float, cfg: ControlConfig):
    return design_pid(K, T, cfg.tw, rudder_max=cfg.rudder_max, zeta=cfg.pid_zeta, ki_ratio=cfg.pid_ki_ratio,
                      ref_wn_ratio=cfg.ref_wn_ratio, ref_zeta=cfg.ref_zeta, ref_rate_share=cfg.ref_rate_share)


def _margins(design, m: dict, cfg: ControlConfig) -> dict:
    try:
        out = sampled_margins(design, m["K"], m["T1"], m["T2"], m["T3"], cfg.dt,
                              servo_time_constant=cfg.servo_time_constant, dead_time=cfg.dead_time)
    except Exception as exc:  # noqa: BLE001 - a plant the margins cannot be taken on is reported
        return {"error": str(exc)}
    return {k: out[k] for k in ("gain_margin_db", "phase_margin_deg", "delay_margin_s", "sensitivity_peak",
                                "stable")}


def operating_point(design_model: dict, indices: dict, cfg: ControlConfig, *,
                    straight_ahead: dict | None = None) -> dict[str, Any]:
    """The ``operating_point`` block of control/metrics.json (module docstring).

    ``design_model``: K (1/s), T1, T2, T3, T (s) the CGSA is designed from.  ``straight_ahead``: the
    ship linearised straight ahead (K, T1, T2, T3), where known.  Returns the models, the margins of
    the CGSA and PID designed from each basis on each plant, ``used`` and ``why``.
    """
    small, why_none = small_amplitude_model(indices)
    models: dict[str, Any] = {"design_model": {n: float(design_model[n])
                                               for n in ("K", "T1", "T2", "T3", "T")}}
    models["design_model"]["source"] = design_model.get("source")
    if small is not None:
        models["small_amplitude"] = small
    if straight_ahead is not None:
        models["straight_ahead"] = {n: float(straight_ahead[n]) for n in ("K", "T1", "T2", "T3")}
        models["straight_ahead"]["T"] = (models["straight_ahead"]["T1"] + models["straight_ahead"]["T2"]
                                         - models["straight_ahead"]["T3"])
        models["straight_ahead"]["source"] = "the built-in KCS linearised straight ahead"
    bases = [b for b in ("design_model", "small_amplitude") if b in models]
    margins: dict[str, Any] = {}
    for b in bases:
        K, T = models[b]["K"], models[b]["T"]
        designs = {"cgsa": design_first_order(K, T, cfg.tw, name=f"cgsa-{b}"), "pid": _pid(K, T, cfg)}
        margins[b] = {name: {"gains": {"Kp": float(d.Kp), "Kd": float(d.Kd),
                                       **({"Ki": float(d.Ki)} if hasattr(d, "Ki") else {})},
                             "plants": {p: _margins(d, models[p], cfg) for p in models}}
                      for name, d in designs.items()}
    used, why = "design_model", ""
    if cfg.operating_point != "small_amplitude":
        why = f"ControlConfig.operating_point = {cfg.operating_point!r}"
    elif small is None:
        why = f"no small-amplitude model: {why_none}"
    else:
        on_design = margins["small_amplitude"]["pid"]["plants"]["design_model"]
        pm = on_design.get("phase_margin_deg")
        if not on_design.get("stable") or pm is None or not pm >= cfg.min_phase_margin:
            why = (f"the PID from the small-amplitude model has phase margin {pm} deg on the design model "
                   f"(needs a stable loop with at least {cfg.min_phase_margin:g} deg)")
        else:
            used = "small_amplitude"
            why = (f"course keeping works near the smallest rudder angles: the {small['rudder_deg']:g} deg "
                   f"zigzags' K {small['K']:.3g} 1/s, T {small['T']:.3g} s, and the PID from them keeps a "
                   f"phase margin of {pm:.3g} deg on the design model")
    return {"rule": ("the PID from the smallest-amplitude zigzags' K, T (standard method) when they are "
                     "usable and that PID keeps a stable sampled loop with a phase margin of at least "
                     f"{cfg.min_phase_margin:g} deg on the design model; else the design model. The CGSA "
                     "stays on the design model (the paper's chain)"),
            "used": used, "why": why, "models": models, "margins": margins}
