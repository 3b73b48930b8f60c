"""``python -m pipeline study SPEC.toml --out DIR [--scheduler ADDRESS] [--workers N]``.

Runs (or resumes) the study described by SPEC.toml on dask.distributed and writes DIR/results.parquet,
DIR/summary.json (and DIR/timings.json; figures and a page for kinds that render).  Without
``--scheduler`` (or DASK_SCHEDULER_ADDRESS) a LocalCluster of N worker processes is started.
"""

from __future__ import annotations

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("study", help="run a study (detection power, autopilot Monte Carlo, batch "
                                     "identification) on dask.distributed")
    p.add_argument("spec", type=Path, help="study spec, TOML (see studies/*.toml)")
    p.add_argument("--out", type=Path, required=True, help="output folder (rerun to resume)")
    p.add_argument("--scheduler", default=None,
                   help="address of an existing dask scheduler, e.g. tcp://host:8786 "
                        "(default: DASK_SCHEDULER_ADDRESS, else a local cluster)")
    p.add_argument("--workers", type=int, default=None,
                   help="local worker processes, one thread each (default: the spec's study.workers)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--dashboard", action="store_true",
                   help="start the local cluster's web dashboard (on 127.0.0.1 only; off by default)")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from pipeline.errors import InputError
    from pipeline.study import load_spec, run_study

    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be at least 1, got {args.workers}")
    spec = load_spec(args.spec)
    summary = run_study(spec, args.out, scheduler=args.scheduler, workers=args.workers,
                        progress=not args.no_progress, dashboard=args.dashboard)
    st = summary["study"]
    print(f"study {st['name']} ({st['kind']}): {st['cases']} cases, {st['ok']} ok, {st['failed']} failed; "
          f"written {args.out / 'results.parquet'} and {args.out / 'summary.json'}")
    for f in summary["failures"][:10]:
        print(f"  failed {f['case_id']} {f['params']}: {f['error']}")
    if len(summary["failures"]) > 10:
        print(f"  ... {len(summary['failures']) - 10} more failures in summary.json")
    return 0
