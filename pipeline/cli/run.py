"""``python -m pipeline run --all | --dataset NAME [...]``: every stage of the datasets, only what is stale.

What ``make pipeline`` calls.  Dataset names are found here, in Python (pipeline.build.discover), and
never pass through a shell.  ``--list`` prints the dataset names, one per line.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from pipeline.errors import InputError, PipelineError


def register(sub) -> None:
    from pipeline.build import STAGES

    p = sub.add_parser("run", help="run every stage of the datasets that is out of date (make pipeline)")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--all", action="store_true", help="every dataset (virtual, hsva, data/raw/*)")
    which.add_argument("--dataset", nargs="+", metavar="NAME", help="these datasets only")
    which.add_argument("--list", action="store_true", help="print the dataset names, one per line")
    p.add_argument("--raw", type=Path, default=Path("data/raw"), help="raw-data root (default: data/raw)")
    p.add_argument("--root", type=Path, default=Path("data/processed"),
                   help="processed-data root (default: data/processed)")
    p.add_argument("--shared", type=Path, default=Path("../shared"),
                   help="shared data folder with data/kvlcc2_hsva (default: ../shared)")
    p.add_argument("--until", choices=[s.name for s in STAGES], help="stop after this stage")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from pipeline.build import build_dataset, discover

    found = discover(args.raw, args.shared)
    if args.list:
        for d in found:
            print(d.name)
        return 0
    if args.all:
        chosen = found
    else:
        by_name = {d.name: d for d in found}
        missing = [n for n in args.dataset if n not in by_name]
        if missing:
            raise InputError(f"unknown dataset {missing[0]!r} (known: {', '.join(by_name)})")
        chosen = [by_name[n] for n in args.dataset]
    t0 = time.perf_counter()
    failed = []
    rows: list[tuple[str, str, str, float]] = []
    for ds in chosen:
        # one dataset's failure does not stop the others (a user's folder with a bad file must not
        # keep the rest from being built); each is said on its line, and the exit status is 2
        try:
            done = build_dataset(ds, args.root, until=args.until,
                                 say=lambda line: print(line, flush=True),
                                 on_stage=lambda *row: rows.append(row))
        except PipelineError as exc:
            print(f"error: {exc}", file=sys.stderr, flush=True)
            failed.append(ds.name)
            continue
        except Exception as exc:  # noqa: BLE001 - whatever one dataset raises, the others are built
            msg = " ".join(str(exc).split())[:300]
            print(f"error: dataset {ds.name!r} ({ds.raw}): {type(exc).__name__}: {msg}", file=sys.stderr,
                  flush=True)
            failed.append(ds.name)
            continue
        print(f"[{ds.name}] " + (f"ran {', '.join(done)}" if done else "up to date"), flush=True)
    print(stage_table(rows, time.perf_counter() - t0), flush=True)
    if failed:
        raise PipelineError(f"{len(failed)} of {len(chosen)} dataset(s) not fully built: {', '.join(failed)} "
                            "(see above)")
    return 0


def stage_table(rows: list[tuple[str, str, str, float]], total_s: float) -> str:
    """The closing table of a build: one line per stage run (dataset, stage, status, wall time in s),
    then the total wall time (s) of the build."""
    if not rows:
        return f"stages: nothing to run (everything up to date); {total_s:.0f} s"
    w_ds = max(len("dataset"), *(len(r[0]) for r in rows))
    w_st = max(len("stage"), *(len(r[1]) for r in rows))
    w_ok = max(len("status"), *(len(r[2]) for r in rows))
    lines = [f"{'dataset':<{w_ds}}  {'stage':<{w_st}}  {'status':<{w_ok}}  {'seconds':>9}"]
    lines += [f"{d:<{w_ds}}  {st:<{w_st}}  {ok:<{w_ok}}  {sec:>9.1f}" for d, st, ok, sec in rows]
    lines.append(f"stages finished in {total_s:.0f} s")
    return "\n".join(lines)
