"""Control stage: the share of its time that the in-loop identification takes (docs/control.md).

Back to back in one run: the whole control stage (:func:`pipeline.control.stage.run_control` on the
paper's indices with the KCS plant, the robustness block and the adaptive run), then the adaptive
block alone on the same seeds, which reports the seconds spent in the streaming identifier's updates.
The ratio of the two is the identification's share of the stage (target: below 10 %).
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from pipeline.config import ControlConfig


def run(quick: bool = False) -> list[dict]:
    from pipeline.cli.control import paper_indices
    from pipeline.control.adaptive import adaptive_block
    from pipeline.control.simulate import kcs_available
    from pipeline.control.stage import run_control, wave_seeds
    from pipeline.model import PAPER_TABLE4, PAPER_TABLE7, PARAM_NAMES

    if not kcs_available():
        return [{"name": "control stage", "value": "skipped", "unit": "", "note": "no pipeline.tank"}]
    cfg = replace(ControlConfig(), seeds=2 if quick else ControlConfig().seeds)
    theta = [PAPER_TABLE4[n] for n in PARAM_NAMES]
    cov = np.diag(np.abs(theta) * 0.05 + 1e-6) ** 2          # 5 % one-sigma: a bench input, not a result
    doc = {**paper_indices(), "builtin_tank": True}
    extra = {"parameters": theta, "covariance": cov.tolist(), "kcs": True}
    run_control(doc, replace(cfg, seeds=1, adaptive=False), progress=False)      # warm up (compilation)
    t0 = time.perf_counter()
    run_control(doc, cfg, progress=False, robustness=extra)
    stage = time.perf_counter() - t0
    seeds = wave_seeds(cfg)[:cfg.adaptive_seeds]
    _, ident = adaptive_block(theta, cov, PAPER_TABLE7["K"], PAPER_TABLE7["T"], seeds, cfg)
    return [
        {"name": f"control stage, {cfg.seeds} seeds, KCS, adaptive", "value": stage, "unit": "s"},
        {"name": "in-loop identification (streaming updates)", "value": ident, "unit": "s",
         "note": f"the {len(seeds)} adaptive runs (the fixed-gain runs carry no identifier)"},
        {"name": "in-loop identification / control stage", "value": 100.0 * ident / stage, "unit": "%",
         "target": "< 10", "note": "same run, back to back"},
    ]
