"""The study engine: cases fanned out with dask.distributed, gathered into one table and a summary.

* Cluster: by default a ``LocalCluster`` of worker *processes*, one thread each (the numba kernels are
  serial; one case per core).  With a scheduler address (``--scheduler`` or DASK_SCHEDULER_ADDRESS) the
  same study runs on an existing cluster; the workers there need this package importable (and, for
  ``batch_identify``, the input files at the same paths).
* Warm-up: a :class:`WarmKernels` worker plugin compiles the kind's numba kernels once per worker
  (on every worker that joins, also later ones), so no case pays for compilation.
* Seeds: every case's seed is ``SeedSequence(study seed, spawn_key = hash of the case's parameters)``:
  the same case gets the same draws whatever worker runs it and whatever else is in the study.
* Resume: each finished case is written (on the client, atomically) to ``DIR/cases/<case_id>.json``;
  the case id hashes the kind, its case-relevant settings, the study seed and the case's parameters,
  so a rerun skips exactly the cases already done with the same settings.
* Failures: an exception inside a case is recorded with its type and message (status ``error``) and
  the other cases go on.  A case whose worker died is retried by dask (``StudyConfig.retries``); if
  it still fails it is listed but not stored, so the next run tries it again.
* Outputs: ``DIR/results.parquet`` (one row per case, sorted by case id: case_id, seed, the case's
  parameters, status, error, then the results) and ``DIR/summary.json`` hold no timing, so the same
  spec gives the same bytes with any number of workers; per-case run times go to ``DIR/timings.json``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pipeline.errors import InputError
from pipeline.io import write_frame, write_json
from pipeline.progress import bar as progress_bar
from pipeline.study.spec import Spec

log = logging.getLogger(__name__)

ENV_SCHEDULER = "DASK_SCHEDULER_ADDRESS"
BASE_COLUMNS = ("case_id", "seed")
STATUS_COLUMNS = ("status", "error")


# ---------------------------------------------------------------- identities and seeds


def _canon(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def params_hash(params: dict[str, Any]) -> str:
    return hashlib.sha256(_canon(params).encode()).hexdigest()


def case_seed(study_seed: int, params: dict[str, Any]) -> int:
    """The case's seed: SeedSequence(study seed, spawn_key = first 64 bits of the parameters' hash)."""
    key = int(params_hash(params)[:16], 16)
    ss = np.random.SeedSequence(int(study_seed), spawn_key=(key,))
    return int(ss.generate_state(1, dtype=np.uint64)[0] >> np.uint64(1))   # fits an int64 column


def settings_fingerprint(kind, settings) -> dict[str, Any]:
    d = asdict(settings)
    for k in (*kind.summary_only, *kind.grid):
        d.pop(k, None)
    return d


def case_id(kind, settings, study_seed: int, params: dict[str, Any]) -> str:
    """16 hex digits naming the case's result: kind, case-relevant settings, study seed, parameters."""
    doc = {"kind": kind.name, "settings": settings_fingerprint(kind, settings), "seed": int(study_seed),
           "params": params}
    return hashlib.sha256(_canon(doc).encode()).hexdigest()[:16]


# ---------------------------------------------------------------- the task run on a worker


def run_case_task(kind_name: str, params: dict[str, Any], seed: int, settings) -> dict[str, Any]:
    """Run one case on a worker.  Never raises for an error of the case itself: returns it."""
    from pipeline.study import get_kind

    kind = get_kind(kind_name)
    t0 = time.perf_counter()
    try:
        out = kind.run_case(dict(params), int(seed), settings)
        res = {"status": "ok", "error": None, "results": _scalars(out)}
    except Exception as exc:  # noqa: BLE001 - any failure of one case is recorded, the study goes on
        msg = " ".join(str(exc).split()) or repr(exc)
        res = {"status": "error", "error": f"{type(exc).__name__}: {msg}"[:500], "results": {}}
    res["seconds"] = time.perf_counter() - t0
    return res


def _scalars(out: dict[str, Any]) -> dict[str, Any]:
    clean = {}
    for k, v in out.items():
        if isinstance(v, np.generic):
            v = v.item()
        if v is not None and not isinstance(v, bool | int | float | str):
            raise TypeError(f"result {k!r} is not a scalar ({type(v).__name__})")
        clean[str(k)] = v
    return clean


try:  # the plugin base class is only needed when dask is there (it is a declared dependency)
    from distributed.diagnostics.plugin import WorkerPlugin
except ImportError:  # pragma: no cover
    WorkerPlugin = object


class WarmKernels(WorkerPlugin):
    """Worker plugin: compile a study kind's numba kernels once on every worker (also ones that join
    later).  A failed warm-up is logged, not fatal: the first case then compiles instead."""

    def __init__(self, kind_name: str, settings):
        self.kind_name = kind_name
        self.settings = settings
        self.name = f"pipeline-warm-{kind_name}"

    def setup(self, worker=None):
        os.environ.setdefault("NUMBA_NUM_THREADS", "1")
        from pipeline.study import get_kind

        kind = get_kind(self.kind_name)
        if kind.warm is not None:
            try:
                kind.warm(self.settings)
            except Exception as exc:  # noqa: BLE001
                log.warning("warm-up of %s failed: %s", self.kind_name, exc)


# ---------------------------------------------------------------- client side


def _client(scheduler: str | None, workers: int, memory_limit: str, dashboard: bool = False):
    from distributed import Client

    from pipeline.study.cluster import local_cluster

    address = scheduler or os.environ.get(ENV_SCHEDULER)
    if address:
        try:
            return Client(address, timeout="30s"), None
        except (OSError, TimeoutError) as exc:
            raise InputError(f"cannot reach the dask scheduler at {address} ({type(exc).__name__}: "
                             f"{' '.join(str(exc).split())[:200]})") from None
    client, cluster = local_cluster(workers, memory_limit, dashboard=dashboard)
    if dashboard:
        log.warning("dask dashboard (loopback only): %s", cluster.dashboard_link)
    return client, cluster


def _read_case(path: Path) -> dict[str, Any] | None:
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None                      # a torn or foreign file: the case is simply run again
    return doc if isinstance(doc, dict) and "status" in doc else None


def plan(spec: Spec) -> list[dict[str, Any]]:
    """Every case of the study: case_id, seed, params (sorted by case id)."""
    from pipeline.study import get_kind

    kind = get_kind(spec.study.kind)
    cases = kind.cases(spec.settings)
    out, seen = [], {}
    for p in cases:
        cid = case_id(kind, spec.settings, spec.study.seed, p)
        if cid in seen:
            raise InputError(f"two cases of the study have the same parameters {p}", file=spec.path)
        seen[cid] = p
        out.append({"case_id": cid, "seed": case_seed(spec.study.seed, p), "params": p})
    if not out:
        raise InputError("the study has no cases (check the spec's ranges)", file=spec.path)
    return sorted(out, key=lambda c: c["case_id"])


def run_study(spec: Spec, out: str | Path, *, scheduler: str | None = None, workers: int | None = None,
              progress: bool = True, client=None, dashboard: bool = False) -> dict[str, Any]:
    """Run (or resume) a study; write DIR/results.parquet, DIR/summary.json, DIR/timings.json.

    Parameters
    ----------
    spec : Spec
        The study (:func:`~pipeline.study.spec.load_spec`).
    out : str or Path
        Its folder; cases already in DIR/results.parquet are not run again.
    scheduler : str, optional
        A dask scheduler's address (else DASK_SCHEDULER_ADDRESS, else a local cluster).
    workers : int, optional
        Worker processes of the local cluster (listening on 127.0.0.1 only).
    progress : bool
        Show a progress bar over the cases.
    client : dask.distributed.Client, optional
        An existing client to use instead of making one.
    dashboard : bool
        Start the local cluster's web dashboard (on 127.0.0.1).

    Returns
    -------
    dict
        The summary (summary.json's content: the kind's statistics per group, docs/studies.md).
    """
    from pipeline.study import get_kind

    kind = get_kind(spec.study.kind)
    out = Path(out)
    cases_dir = out / "cases"
    todo = plan(spec)
    done: dict[str, dict] = {}
    for c in todo:
        doc = _read_case(cases_dir / f"{c['case_id']}.json")
        if doc is not None:
            done[c["case_id"]] = doc
    pending = [c for c in todo if c["case_id"] not in done]
    lost: dict[str, str] = {}
    n_workers = int(workers or spec.study.workers)
    t_start = time.perf_counter()
    if pending:
        own = client is None
        cluster = None
        if own:
            client, cluster = _client(scheduler, n_workers, spec.study.memory_limit, dashboard)
        try:
            cases_dir.mkdir(parents=True, exist_ok=True)      # only once there is a cluster to run on
            _register_warm(client, kind, spec.settings)
            got, lost = _fan_out(client, kind, spec, pending, cases_dir=cases_dir, progress=progress)
            done.update(got)
            n_workers = len(client.scheduler_info().get("workers", {})) or n_workers
        finally:
            if own:
                client.close()
                if cluster is not None:
                    cluster.close()
    wall = time.perf_counter() - t_start
    frame = results_frame(todo, done, lost)
    summary = kind.summarise(frame, spec.settings, spec.study.seed)
    summary = {"study": {"name": spec.study.name, "kind": kind.name, "seed": spec.study.seed,
                         "cases": len(todo), "ok": int((frame["status"] == "ok").sum()),
                         "failed": int((frame["status"] != "ok").sum())},
               "failures": [{"case_id": r.case_id, "error": r.error,
                             "params": {k: _py(getattr(r, k)) for k in todo[0]["params"]}}
                            for r in frame[frame["status"] != "ok"].itertuples()],
               **summary}
    write_frame(out / "results.parquet", frame)
    write_json(out / "summary.json", summary)
    if kind.render is not None:
        kind.render(frame, summary, out)
    secs = {cid: d.get("seconds") for cid, d in sorted(done.items())}
    write_json(out / "timings.json", {"workers": n_workers, "cases_run_now": len(pending),
                                      "cases_resumed": len(todo) - len(pending),
                                      "wall_seconds": wall, "case_seconds": secs})
    return summary


def _py(v):
    return v.item() if isinstance(v, np.generic) else v


def _register_warm(client, kind, settings) -> None:
    if kind.warm is None:
        return
    plugin = WarmKernels(kind.name, settings)
    if hasattr(client, "register_plugin"):
        client.register_plugin(plugin)
    else:  # pragma: no cover - older distributed
        client.register_worker_plugin(plugin)


def _fan_out(client, kind, spec: Spec, pending, *, cases_dir: Path,
             progress: bool) -> tuple[dict[str, dict], dict[str, str]]:
    """Run the ``pending`` cases on the cluster, writing each finished case's JSON to ``cases_dir``.
    Returns (case id -> its document, case id -> why a case was lost: a worker gone after its
    retries, a cancelled task)."""
    from distributed import as_completed
    lost: dict[str, str] = {}
    futures = {}
    for c in pending:
        fut = client.submit(run_case_task, kind.name, c["params"], c["seed"], spec.settings,
                            key=f"{kind.name}-{c['case_id']}", retries=spec.study.retries, pure=False)
        futures[fut.key] = (fut, c)
    got = {}
    bar = progress_bar(total=len(pending), desc=f"study {spec.study.name}", unit="case", progress=progress,
                       dynamic_ncols=True)
    errors = 0
    ac = as_completed([f for f, _ in futures.values()])
    try:
        for fut in _finished(client, ac, spec, len(pending), got):
            _, c = futures[fut.key]
            try:
                res = fut.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker after its retries, a cancelled task
                lost[c["case_id"]] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:500]
                errors += 1
                bar.update(1)
                bar.set_postfix(failed=errors)
                continue
            doc = {"case_id": c["case_id"], "kind": kind.name, "seed": c["seed"], "params": c["params"],
                   **res}
            write_json(cases_dir / f"{c['case_id']}.json", doc)
            got[c["case_id"]] = doc
            errors += res["status"] != "ok"
            bar.update(1)
            if errors:
                bar.set_postfix(failed=errors)
    except BaseException:            # Ctrl-C, no worker left: nothing keeps running on the cluster
        for f, _ in futures.values():
            f.cancel()
        raise
    finally:
        bar.close()
    return got, lost


#: s between two looks at the scheduler while no case finishes (a cheap call; a tenth of the default
#: no-worker timeout, so the timeout is kept to within 10 %)
POLL_S = 0.5


def _finished(client, ac, spec: Spec, n: int, got: dict):
    """The futures of ``ac`` as they finish; a PipelineError once the cluster has had no worker for
    ``spec.study.no_worker_timeout_s`` seconds (every worker died, or none reached the scheduler),
    instead of waiting for ever."""
    from pipeline.errors import PipelineError

    limit = spec.study.no_worker_timeout_s
    last_worker = time.monotonic()
    while not ac.is_empty():
        batch = ac.next_batch(block=False)
        if batch:
            yield from batch
            continue
        if client.nthreads():
            last_worker = time.monotonic()
        elif time.monotonic() - last_worker > limit:
            raise PipelineError(
                f"study {spec.study.name}: no dask worker for {limit:g} s (every worker died, or none "
                f"reached the scheduler; see the workers' logs; key 'study.no_worker_timeout_s'); {len(got)} "
                f"of {n} cases finished and kept, a rerun resumes", file=spec.path)
        time.sleep(POLL_S)


def results_frame(todo: list[dict], done: dict[str, dict], lost: dict[str, str]) -> pd.DataFrame:
    """One row per case, sorted by case id; parameter columns in the kind's order, results sorted."""
    rows = []
    result_keys: set[str] = set()
    for c in todo:
        doc = done.get(c["case_id"])
        if doc is None:
            status, err, res = "error", lost.get(c["case_id"], "not run"), {}
        else:
            status, err, res = doc["status"], doc.get("error"), doc.get("results", {})
        result_keys.update(res)
        rows.append({"case_id": c["case_id"], "seed": c["seed"], **c["params"], "status": status,
                     "error": err, **res})
    pcols = list(todo[0]["params"])
    clash = set(pcols) & (set(BASE_COLUMNS) | set(STATUS_COLUMNS))
    if clash:
        raise InputError(f"case parameter names clash with engine columns: {sorted(clash)}")
    cols = [*BASE_COLUMNS, *pcols, *STATUS_COLUMNS, *sorted(result_keys - set(pcols))]
    frame = pd.DataFrame(rows, columns=cols)
    frame["error"] = frame["error"].astype("string")
    frame["seed"] = frame["seed"].astype("int64")
    return frame.sort_values("case_id", kind="stable").reset_index(drop=True)
