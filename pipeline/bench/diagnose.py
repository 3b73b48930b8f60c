"""Diagnosis speed: a 4-run case (train 20/20 S + 10/10 P, validate 20/20 P + 10/10 S of the linear
truth model with a 2 deg rudder offset and cubic damping, 80 s each) with the full effect catalogue,
both folds, the nested cross-validation of the gain and the per-fold stability selections.
Wall time of :func:`pipeline.diagnose.diagnose` after a warm-up that compiles the numba kernels (so
the figure is the method, not the compiler); the target is < 30 s on a
2-core machine (docs/results.md#speed).
Beside it (not in quick mode) the same case with plain fits (:func:`~pipeline.diagnose.fit.plain_fits`:
no batched finite differences, no memo) as the same-run baseline, its ratio, and whether the two
reports are the same bytes; and the same case with the nested leave-one-run-out in this process
(``nested_workers = 1``) against its worker processes (the default where a fork is safe, as here).
"""

from __future__ import annotations

import dataclasses as dc
import json
import resource
import time

from pipeline.config import DiagnoseConfig
from pipeline.diagnose import CATALOGUE, TruthConfig, diagnose, zigzag_truth
from pipeline.diagnose.core import _nested_workers
from pipeline.diagnose.fit import plain_fits
from pipeline.diagnose.truth import damping_for_cut


def run(quick: bool = False) -> list[dict]:
    cfg = TruthConfig(seed=5, rudder_offset=2.0, n_rrr=damping_for_cut(0.3))
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
    runs = [zigzag_truth(a, a, s, 80.0, dc.replace(cfg, seed=cfg.seed + j)) for j, (a, s) in enumerate(legs)]
    short = [zigzag_truth(a, a, s, 20.0, dc.replace(cfg, seed=cfg.seed + j)) for j, (a, s) in enumerate(legs)]
    diagnose(short[:1], short[1:2])  # compile / warm up
    t0, c0 = time.perf_counter(), _cpu()
    rep = diagnose(runs[:2], runs[2:]).report
    sec, cpu = time.perf_counter() - t0, _cpu() - c0
    honest = rep["gain"]["mae_psi_relative_reduction"]
    out = [
        {
            "name": f"diagnosis, 4 runs x 80 s, {len(CATALOGUE)} effects",
            "value": sec,
            "unit": "s",
            "target": "< 30",
            "note": f"CPU {cpu:.1f} s (this process and its workers), nested leave-one-run-out in "
            f"{_nested_workers(DiagnoseConfig(), 4)} worker process(es); cause {rep['cause']}, "
            f"extended {'+'.join(rep['extended']['effects'])}, honest gain "
            + ("none" if honest is None else f"{honest:.3f}"),
        }
    ]
    if quick:
        return out
    # same-run baseline: the fits as before the speed devices (one residual evaluation per Python
    # call, finite-difference columns one by one, no memo); the report must be the same bytes
    t0, c0 = time.perf_counter(), _cpu()
    with plain_fits():
        plain = diagnose(runs[:2], runs[2:]).report
    sec0, cpu0 = time.perf_counter() - t0, _cpu() - c0
    same = _dump(plain) == _dump(rep)
    out += [
        {
            "name": "diagnosis, same case, plain fits (baseline)",
            "value": sec0,
            "unit": "s",
            "note": f"CPU {cpu0:.1f} s; report "
            + ("identical" if same else "DIFFERENT (a speed device changed a number)"),
        },
        {
            "name": "speed-up of the diagnosis over plain fits (CPU)",
            "value": cpu0 / max(cpu, 1e-9),
            "unit": "x",
            "note": f"wall {sec0 / max(sec, 1e-9):.2f} x; same run",
        },
    ]
    t0 = time.perf_counter()
    alone = diagnose(runs[:2], runs[2:], cfg=DiagnoseConfig(nested_workers=1)).report
    sec1 = time.perf_counter() - t0
    out += [
        {
            "name": "diagnosis, same case, nested leave-one-run-out in this process",
            "value": sec1,
            "unit": "s",
            "note": "report " + ("identical" if _dump(alone) == _dump(rep) else "DIFFERENT"),
        },
        {
            "name": "speed-up of the nested worker processes (wall)",
            "value": sec1 / max(sec, 1e-9),
            "unit": "x",
            "note": "same run; 2 cores",
        },
    ]
    return out


def _cpu() -> float:
    """CPU seconds of this process and of its children reaped so far (the nested workers are reaped
    when the diagnosis closes its pool, so a difference around one diagnosis counts them)."""
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + ch.ru_utime + ch.ru_stime


def _dump(report: dict) -> str:
    def enc(o):
        return o.tolist() if hasattr(o, "tolist") else repr(o)

    return json.dumps(report, sort_keys=True, default=enc)
