"""Diagnosis speed (docs/performance.md): a 4-run case (train 20/20 S + 10/10 P, validate 20/20 P +
10/10 S of the linear truth model with a 2 deg rudder offset and cubic damping, 80 s each) with the
full effect catalogue, both folds, the nested cross-validation of the gain and the per-fold stability
selections.  Wall time of :func:`pipeline.diagnose.diagnose` after a warm-up that compiles the numba
kernels (so the figure is the method, not the compiler); the target is < 15 s on a 2-core machine.

Beside it (not in quick mode): the same case with plain fits (``DiagnoseConfig.plain_fits``:
residuals from Python, SciPy's finite-difference Jacobian, no memo) as the same-run baseline, its
ratio, whether the two verdicts agree and the largest relative difference of the reports' figures
(another Jacobian reaches the same optimum within the optimiser's tolerance, not the same bits); the
same case with the nested leave-one-run-out in this process (``nested_workers = 1``) against its
worker processes; the same case with a memo of fits per worker round (``shared_memo = False``) against
the memo the processes share; and the virtual KCS's diagnosis (its nine default runs, turning circles
included, designed by the catalog rule: six selection runs and three test runs; target < 60 s) beside
the same diagnosis without the helper process that makes fits ahead (``DiagnoseConfig.fit_ahead``,
its same-run ratio and whether the report is the same bytes), and its main selection alone (nested gain
off) against plain fits as its same-run ratio.
"""

from __future__ import annotations

import dataclasses as dc
import json
import resource
import time

from pipeline.config import DiagnoseConfig
from pipeline.diagnose import CATALOGUE, TruthConfig, diagnose, zigzag_truth
from pipeline.diagnose.core import _nested_workers
from pipeline.diagnose.design import pick_catalog_runs
from pipeline.diagnose.truth import damping_for_cut

#: relative: a figure of two reports counts as moved when it differs by more than this (the
#: least-squares stopping tolerance, fit._TOL: a refit lands anywhere within it)
MOVED = 1e-6


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
            "target": "< 15",
            "note": f"CPU {cpu:.1f} s (this process and its workers), nested leave-one-run-out in "
            f"{_nested_workers(DiagnoseConfig(), 4)} worker process(es); cause {rep['cause']}, "
            f"extended {'+'.join(rep['extended']['effects'])}, honest gain "
            + ("none" if honest is None else f"{honest:.3f}"),
        }
    ]
    if quick:
        return out
    # same-run baseline: plain fits (residuals from Python, finite differences, no memo)
    out += _same_run("diagnosis, same case, plain fits (baseline)",
                     "speed-up of the diagnosis over plain fits (CPU)", runs, DiagnoseConfig(plain_fits=True),
                     sec, cpu, lambda r: _agreement(r, rep))
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
    # the same-run baseline of the shared memo: each worker's round with a memo of its own
    out += _same_run("diagnosis, same case, a memo of fits per worker round (not shared)",
                     "speed-up of the shared memo of fits (CPU)", runs, DiagnoseConfig(shared_memo=False),
                     sec, cpu, lambda r: "report " + ("identical" if _dump(r) == _dump(rep) else "DIFFERENT"))
    return out + virtual_rows()


def _same_run(name: str, ratio_name: str, runs, cfg: DiagnoseConfig, sec: float, cpu: float,
              note) -> list[dict]:
    """Rows of the bench case diagnosed (training runs[:2], validation runs[2:]) with ``cfg``: its wall
    time (s) with its CPU time and ``note(report)``, and its CPU time over ``cpu`` (s, the default
    settings' run of the same bench; ``sec`` its wall time) as the speed-up of the default."""
    t0, c0 = time.perf_counter(), _cpu()
    rep = diagnose(runs[:2], runs[2:], cfg=cfg).report
    sec0, cpu0 = time.perf_counter() - t0, _cpu() - c0
    return [
        {"name": name, "value": sec0, "unit": "s", "note": f"CPU {cpu0:.1f} s; " + note(rep)},
        {"name": ratio_name, "value": cpu0 / max(cpu, 1e-9), "unit": "x",
         "note": f"wall {sec0 / max(sec, 1e-9):.2f} x; same run"},
    ]


def virtual_runs():
    """(training, validation, test) runs of the virtual KCS's default set (pipeline.tank), simulated
    here and designed by the catalog rule (:func:`~pipeline.diagnose.design.pick_catalog_runs`) as
    ``python -m pipeline diagnose`` designs the virtual dataset."""
    from pipeline.tank.manoeuvres import default_set
    from pipeline.tank.simulate import simulate

    made = {}
    entries = []
    for m in default_set():
        run = simulate(m)
        made[run.name] = run
        entries.append({"run_id": run.name, "kind": m.kind, "rudder_deg": m.rudder_deg,
                        "heading_deg": m.heading_deg, "first_side": m.side})
    tr, va, te = pick_catalog_runs(entries)
    return [made[r] for r in tr], [made[r] for r in va], [made[r] for r in te]


def virtual_rows() -> list[dict]:
    """The virtual KCS's diagnosis (target < 60 s), and its main selection alone with and without
    plain fits (the same-run ratio; the whole diagnosis with plain fits takes twenty minutes)."""
    train, val, test = virtual_runs()
    t0, c0 = time.perf_counter(), _cpu()
    rep = diagnose(train, val, test=test).report
    sec, cpu = time.perf_counter() - t0, _cpu() - c0
    honest = rep["gain"]["mae_psi_relative_reduction"]
    out = [{
        "name": f"virtual KCS diagnosis, {len(train) + len(val)} runs, {len(test)} test runs",
        "value": sec,
        "unit": "s",
        "target": "< 60",
        "note": f"CPU {cpu:.1f} s; cause {rep['cause']}, extended "
        f"{'+'.join(rep['extended']['effects']) or 'none'}, honest gain "
        + ("none" if honest is None else f"{honest:.3f}"),
    }]
    # the same-run baseline of the helper that makes fits ahead (pipeline.diagnose.ahead)
    t0, c0 = time.perf_counter(), _cpu()
    alone = diagnose(train, val, test=test, cfg=DiagnoseConfig(fit_ahead=False)).report
    sec_a, cpu_a = time.perf_counter() - t0, _cpu() - c0
    out += [
        {"name": "virtual KCS diagnosis, no helper making fits ahead (fit_ahead off)", "value": sec_a,
         "unit": "s",
         "note": f"CPU {cpu_a:.1f} s; report "
         + ("identical" if _dump(alone) == _dump(rep) else "DIFFERENT")},
        {"name": "speed-up of the virtual diagnosis by the helper (wall)", "value": sec_a / max(sec, 1e-9),
         "unit": "x", "note": f"same run; CPU {cpu / max(cpu_a, 1e-9):.2f} x of the run without it"},
    ]
    main = DiagnoseConfig(nested_gain=False)
    t0, c0 = time.perf_counter(), _cpu()
    fast = diagnose(train, val, cfg=main).report
    sec1, cpu1 = time.perf_counter() - t0, _cpu() - c0
    t0, c0 = time.perf_counter(), _cpu()
    plain = diagnose(train, val, cfg=dc.replace(main, plain_fits=True)).report
    sec0, cpu0 = time.perf_counter() - t0, _cpu() - c0
    return out + [
        {"name": "virtual KCS main selection (nested gain off)", "value": sec1, "unit": "s",
         "note": f"CPU {cpu1:.1f} s"},
        {"name": "virtual KCS main selection, plain fits", "value": sec0, "unit": "s",
         "note": f"CPU {cpu0:.1f} s; " + _agreement(plain, fast)},
        {"name": "speed-up of the virtual main selection (CPU)", "value": cpu0 / max(cpu1, 1e-9), "unit": "x",
         "note": "same run"},
    ]


def _agreement(a: dict, b: dict) -> str:
    """Whether two reports give the same verdict (cause, extended effects, every nested fold's effects)
    and how many of their figures moved by more than :data:`MOVED` (relative), the largest move."""
    def verdict(r):
        return (r["cause"], tuple(r["extended"]["effects"]),
                tuple(tuple(f.get("effects", ())) for f in r["gain"].get("nested", [])))

    moves = [abs(x - y) / max(abs(x), abs(y)) for x, y in _pairs(a, b) if max(abs(x), abs(y)) > 1e-12]
    moved = [m for m in moves if m > MOVED]
    return (("verdict the same" if verdict(a) == verdict(b) else "verdict DIFFERENT")
            + f"; {len(moved)} of {len(moves)} figures moved by more than {MOVED:g}"
            + (f" (largest {max(moves):.2g})" if moves else ""))


def _pairs(a, b):
    """The numbers at the same places of two JSON-like trees."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in a.keys() & b.keys():
            yield from _pairs(a[k], b[k])
    elif isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)) and len(a) == len(b):
        for x, y in zip(a, b, strict=True):
            yield from _pairs(x, y)
    elif (isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool)
          and not isinstance(b, bool)):
        yield float(a), float(b)


def _cpu() -> float:
    """CPU seconds of this process and of its children reaped so far (the nested workers are reaped
    when the diagnosis closes its pool, so a difference around one diagnosis counts them)."""
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + ch.ru_utime + ch.ru_stime


def _dump(report: dict) -> str:
    def enc(o):
        return o.tolist() if hasattr(o, "tolist") else repr(o)

    return json.dumps(report, sort_keys=True, default=enc)
