"""Study engine scaling, all measured in one run:

* throughput (cases/s) of an autopilot Monte Carlo on 1 and 2 local worker processes, the scaling
  efficiency (2-worker throughput / twice the 1-worker one), and the engine's per-case overhead
  against calling the same case function in a plain loop in this process (cluster start-up excluded
  and reported on its own);
* the same study through a scheduler and two workers started as separate processes
  (``dask scheduler``, ``dask worker tcp://127.0.0.1:PORT``): the cluster path;
* the power study's diagnosis cases per second (linear truth model, the power-ci settings), in a plain
  loop (one core) and on 2 workers.

The SR-UKF per-step ratio against filterpy and the 1,000-run batch are in :mod:`.identify`.
"""

from __future__ import annotations

import dataclasses as dc
import tempfile
import time
from pathlib import Path

from pipeline.study.cluster import local_client, loopback_cluster
from pipeline.study.engine import plan, run_case_task
from pipeline.study.spec import spec_from_dict

ROOT = Path(__file__).resolve().parents[2]


def _autopilot(n_seeds: int, short: bool = False):
    """Autopilot cases on the Nomoto plant; ``short``: 12 s runs (about 1/15 of the work), to make the
    engine's fixed per-case cost visible against the case itself."""
    extra = {"control": {"duration": 12.0, "steady_start": 10.0}} if short else {}
    return spec_from_dict({"study": {"kind": "autopilot_monte_carlo", "name": "bench", "seed": 3},
                           "autopilot_monte_carlo": {"plants": ["nomoto"], "tw": [2.0, 3.0],
                                                     "wind_rudder": [0.0, 2.0], "seeds": n_seeds, **extra}})


def _power(seeds: int, one: bool = False):
    """The power-ci settings with ``seeds`` replicates (clean ones too); ``one``: a single case
    (rudder offset 1 deg, one seed), to warm a worker."""
    from pipeline.study import load_spec

    base = load_spec(ROOT / "studies" / "power-ci.toml")
    s = dc.replace(base.settings, seeds=seeds, clean_seeds=seeds)
    if one:
        s = dc.replace(s, seeds=1, clean_seeds=1, effects=("rudder_offset",),
                       magnitudes={"rudder_offset": (1.0,)})
    return dc.replace(base, settings=s)


def _loop(spec) -> tuple[float, int]:
    cases = plan(spec)
    t0 = time.perf_counter()
    for c in cases:
        run_case_task(spec.study.kind, c["params"], c["seed"], spec.settings)
    return time.perf_counter() - t0, len(cases)


def _engine(spec, client) -> float:
    """Seconds to run the whole study through ``client`` (a throw-away output folder)."""
    from pipeline.study import run_study

    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        run_study(spec, d, client=client, progress=False)
        return time.perf_counter() - t0


def _timed_on(client, warm_spec, *specs) -> list[float]:
    """One throw-away run of ``warm_spec`` (every worker imports and compiles what the cases use),
    then the seconds of each of ``specs``."""
    _engine(warm_spec, client)
    return [_engine(s, client) for s in specs]


def run(quick: bool = False) -> list[dict]:
    rows: list[dict] = []
    ap = _autopilot(5 if quick else 15)
    small = _autopilot(1)
    # the case function itself (and its compilation) warmed in this process too
    _loop(small)
    loop_s, n = _loop(ap)
    short = _autopilot(5 if quick else 25, short=True)
    loop_short, n_short = _loop(short)
    per = {}
    start = {}
    eng_short = None
    for w in (1, 2):
        t0 = time.perf_counter()
        with local_client(w) as client:
            start[w] = time.perf_counter() - t0
            if w == 1:
                per[w], eng_short = _timed_on(client, small, ap, short)
            else:
                (per[w],) = _timed_on(client, small, ap)
    rows += [
        {"name": f"autopilot cases, plain loop ({n} cases)", "value": n / loop_s, "unit": "cases/s",
         "note": "run_case in this process"},
        {"name": "autopilot cases, engine 1 worker", "value": n / per[1], "unit": "cases/s"},
        {"name": "autopilot cases, engine 2 workers", "value": n / per[2], "unit": "cases/s"},
        {"name": "scaling efficiency 2 workers", "value": per[1] / (2 * per[2]), "unit": "",
         "note": "throughput(2) / (2 x throughput(1)); the machine has 2 cores"},
        {"name": f"engine overhead per case (1 worker vs loop, {n_short} short cases)",
         "value": (eng_short - loop_short) / n_short * 1e3, "unit": "ms",
         "note": f"case alone {loop_short / n_short * 1e3:.0f} ms; submit, transfer, result file, gather, "
                 "table, summary"},
        {"name": "local cluster start-up, 2 workers", "value": start[2], "unit": "s"},
    ]
    # separate scheduler and worker processes on the loopback
    from distributed import Client

    with loopback_cluster(2) as addr, Client(addr, timeout="60s") as client:
        (secs,) = _timed_on(client, small, ap)
    rows.append({"name": "autopilot cases, separate scheduler + 2 workers", "value": n / secs,
                 "unit": "cases/s", "note": f"dask scheduler / dask worker processes on {addr}"})
    # diagnosis cases of the power study
    pw = _power(1 if quick else 2)
    _loop(_power(1, one=True))
    loop_p, npw = _loop(pw)
    with local_client(2) as client:
        (eng_p,) = _timed_on(client, _power(1, one=True), pw)
    rows += [
        {"name": f"power-study diagnosis cases, plain loop ({npw})", "value": npw / loop_p, "unit": "cases/s",
         "note": "linear truth model, power-ci settings, one core"},
        {"name": "power-study diagnosis cases, 2 workers", "value": npw / eng_p, "unit": "cases/s",
         "note": f"scaling {loop_p / eng_p:.2f}x of the loop"},
    ]
    return rows
