"""Which model the autopilot is designed from: the identified one unless it loses on held-out runs.

The one place this is decided: the indices stage (``control_model.design_model`` of indices.json),
which the control stage and both reports read (docs/control.md, "Which model the autopilot is
designed from").

The filter's consistency (NIS, whiteness, parameter covariance) says whether its *uncertainty* is
right; whether its *model* is fit to design from is a question of prediction.  Both candidates are
scored the same way on the same held-out runs (the zigzags the validate stage holds out):

* identified: the SR-UKF-FFM sway-yaw model (its six parameters, pipeline.model.simulate);
* graphical: the first-order Nomoto model K/(s (T s + 1)) of the standard (graphical) method, written
  as the same state-space model (a12 = a21 = b11 = 0, a22 = -1/T, b21 = K/T) and run by the same
  simulator,

each a free run from the run's measured initial state driven by the measured rudder alone
(pipeline.validate.free_run), scored by the mean absolute heading error (deg) pooled over every
held-out sample.  Rule: design from the identified model unless its error exceeds the graphical
model's by both ``ControlConfig.design_rule_rel`` (relative) and ``design_rule_abs_deg`` (deg); the
reasons for both thresholds are beside them in pipeline/config.py.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pipeline.config import ControlConfig
from pipeline.io import Run
from pipeline.model import PARAM_NAMES
from pipeline.validate import free_run


def graphical_parameters(K: float, T: float) -> dict[str, float]:
    """The first-order Nomoto model K (1/s), T (s) as the six sway-yaw parameters (v decays at 1/s)."""
    return {"a11": -1.0, "a12": 0.0, "a21": 0.0, "a22": -1.0 / float(T), "b11": 0.0,
            "b21": float(K) / float(T)}


def heldout_error(parameters: dict[str, float], runs: list[Run]) -> dict[str, Any]:
    """Pooled free-run MAE of psi (deg) over ``runs`` and per run."""
    est = {"parameters": {n: float(parameters[n]) for n in PARAM_NAMES}}
    per, tot, n = {}, 0.0, 0
    for run in runs:
        pred = free_run(est, run, start=0)
        psi = run.frame["psi"].to_numpy(dtype=float)[1:]
        err = np.abs(pred[:, 2] - psi)
        err = err[np.isfinite(err)]
        per[run.name] = float(np.mean(err)) if err.size else float("nan")
        tot += float(np.sum(err))
        n += err.size
    return {"mae_psi_deg": tot / n if n else float("nan"), "samples": n, "per_run": per}


def choose_design_model(identified: dict[str, Any] | None, graphical: dict[str, float], runs: list[Run],
                        cfg: ControlConfig) -> dict[str, Any]:
    """The ``design_model`` block of control/metrics.json (docs/control.md).

    ``identified``: {"parameters": six parameters, "indices": K, T1, T2, T3, T} or None when the
    identification gave no usable model (then the graphical model, saying why).  ``graphical``:
    K (1/s), T (s).  ``runs``: the held-out runs.
    """
    rule = (f"identified unless its pooled held-out free-run MAE psi exceeds the graphical model's by more "
            f"than {cfg.design_rule_rel:.0%} and by more than {cfg.design_rule_abs_deg:g} deg")
    g_err = heldout_error(graphical_parameters(graphical["K"], graphical["T"]), runs) if runs else None
    out: dict[str, Any] = {"rule": rule, "heldout_runs": [r.name for r in runs],
                           "graphical": {"K": graphical["K"], "T": graphical["T"], "heldout": g_err}}
    if identified is None:
        out.update({"chosen": "graphical", "reason": "no identified model with positive K and T"})
        return out
    ind = identified["indices"]
    if not runs:
        out.update({"chosen": "identified", "identified": {**ind, "heldout": None},
                    "reason": "no held-out run to judge by: the identified model (the paper's chain)"})
        return out
    i_err = heldout_error(identified["parameters"], runs)
    out["identified"] = {**ind, "heldout": i_err}
    a, b = i_err["mae_psi_deg"], g_err["mae_psi_deg"]
    loses = bool(np.isfinite(a) and np.isfinite(b) and a > b * (1 + cfg.design_rule_rel)
                 and a - b > cfg.design_rule_abs_deg) or not np.isfinite(a)
    out["chosen"] = "graphical" if loses else "identified"
    out["reason"] = (f"held-out MAE psi: identified {a:.3g} deg, graphical {b:.3g} deg: "
                     + ("the identified model loses" if loses else "the identified model does not lose"))
    return out


def decision_table(block: dict[str, Any]) -> tuple[list[dict[str, Any]], str]:
    """Rows (model, K 1/s, T s, held-out MAE psi deg, samples, chosen) and the caption of a
    ``design_model`` block, as the indices and control reports show it (the same table on both)."""
    rows = []
    for name in ("identified", "graphical"):
        blk = block.get(name) or {}
        ho = blk.get("heldout") or {}
        rows.append({"model": name, "K (1/s)": blk.get("K"), "T (s)": blk.get("T"),
                     "held-out MAE psi (deg)": ho.get("mae_psi_deg"), "samples": ho.get("samples"),
                     "chosen": "yes" if block.get("chosen") == name else ""})
    caption = (f"The one design-model decision, made by the indices stage: {block.get('rule')}. "
               f"{block.get('reason', '')}. Held-out runs: {', '.join(block.get('heldout_runs') or [])}.")
    return rows, caption
