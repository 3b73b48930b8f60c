"""Control stage: the share of its time that the in-loop identification takes (docs/control.md).

Back to back in one run: the whole control stage (:func:`pipeline.control.stage.run_control` on the
paper's indices with the KCS plant, the robustness block and the adaptive run), then the adaptive
block alone on the same seeds, which reports the seconds spent in the streaming identifier's updates.
The ratio of the two is the identification's share of the stage (target: below 10 %).

Then the robustness draws (``robust_draws`` parameter draws x the stage's three designs) two ways in the
same run: the baseline as the stage used to run them (each draw's plant through its transfer function,
python-control's ``c2d``, BLAS on its default threads, the plant rebuilt for every design) and the
stage's way (:func:`pipeline.control.robust.parameters_plant` once per draw, one BLAS thread); the
ratio is the speed-up (docs/control.md, "Speed").
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
    base, cand = _draws_two_ways(doc, cfg, np.asarray(theta, float), cov)
    return [
        {"name": f"control stage, {cfg.seeds} seeds, KCS, adaptive", "value": stage, "unit": "s"},
        {"name": f"robustness draws, {cfg.robust_draws} x 3 designs, baseline (transfer-function route, "
                 "default BLAS threads)", "value": base, "unit": "s"},
        {"name": "robustness draws, the stage's way (state-space route, one BLAS thread)", "value": cand,
         "unit": "s"},
        {"name": "robustness draws: baseline / stage's way", "value": base / cand, "unit": "x",
         "note": "same run, back to back"},
        {"name": "in-loop identification (streaming updates)", "value": ident, "unit": "s",
         "note": f"the {len(seeds)} adaptive runs (the fixed-gain runs carry no identifier)"},
        {"name": "in-loop identification / control stage", "value": 100.0 * ident / stage, "unit": "%",
         "target": "< 10", "note": "same run, back to back"},
    ]


def _draws_two_ways(doc: dict, cfg: ControlConfig, theta: np.ndarray, cov: np.ndarray) -> tuple[float, float]:
    """Seconds of the robustness draws the old way and the stage's way (module docstring)."""
    from threadpoolctl import threadpool_limits

    from pipeline.control.autopilot import design_pid
    from pipeline.control.design import design_first_order
    from pipeline.control.robust import (
        discrete_margins,
        loop_tf,
        parameters_rate_tf,
        sampled_plant_tf,
    )
    from pipeline.control.robustness import _draws

    cm, gm = doc["control_model"], doc["graphical_model"]
    designs = {"identified": design_first_order(cm["K"], cm["T"], cfg.tw, name="identified"),
               "graphical": design_first_order(gm["K"], gm["T"], cfg.tw, name="graphical"),
               "autopilot": design_pid(cm["K"], cm["T"], cfg.tw, rudder_max=cfg.rudder_max)}
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, 41]))
    draws = rng.multivariate_normal(theta, 0.5 * (cov + cov.T), size=cfg.robust_draws, method="eigh")
    t0 = time.perf_counter()
    for d in designs.values():
        for th in draws:
            plant = sampled_plant_tf(parameters_rate_tf(th), cfg.dt,
                                     servo_time_constant=cfg.servo_time_constant, dead_time=cfg.dead_time)
            discrete_margins(loop_tf(d, plant, cfg.dt), n_grid=600)
    base = time.perf_counter() - t0
    t0 = time.perf_counter()
    with threadpool_limits(limits=1, user_api="blas"):
        _draws(designs, theta, cov, cfg)
    return base, time.perf_counter() - t0
