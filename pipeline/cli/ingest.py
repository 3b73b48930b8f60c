"""``python -m pipeline ingest FILE... --out DIR``: raw tank files to processed runs (SPEC sections 2-4, 8).

All files are read and validated first; only if every one is good are ``DIR/<run_id>.parquet``
(run_id = file stem) and ``DIR/index.json`` written, each atomically.  A bad file: one line naming
the file and the problem, exit status 2, nothing written, earlier outputs in DIR untouched.
Files that are not tank data (README.md, .stamp, .gitkeep, hidden files) are skipped with a note.

``index.json`` (pipeline/catalog.py): ``{"dataset", "provenance", "runs": [{"run_id", "file", ...meta}]}``
listing the runs of this invocation.
"""

from __future__ import annotations

import sys
from pathlib import Path

from pipeline.config import IngestConfig
from pipeline.errors import InputError
from pipeline.ingest import FORMATS, ingest_file, with_dt
from pipeline.io import atomic_dir, write_json, write_run

SKIP_SUFFIXES = {".md", ".stamp", ".gitkeep", ".txt", ".json", ".pdf", ".png"}


def register(sub) -> None:
    p = sub.add_parser("ingest", help="read, validate and resample raw tank files into processed runs")
    p.add_argument("files", nargs="+", type=Path, metavar="FILE", help="raw files (CSV, MARIN/HSVA .dat)")
    p.add_argument("--out", type=Path, required=True, help="output directory (e.g. data/processed/hsva/runs)")
    p.add_argument("--format", dest="fmt", choices=FORMATS, help="override format recognition")
    p.add_argument("--scale", type=float, help="scale (full/model) of the values")
    p.add_argument("--dt", type=float, help="output step in s (default 0.08)")
    p.add_argument("--rudder-sign", type=int, choices=(1, -1), default=1,
                   help="-1 for files whose rudder is positive to port (canonical: positive delta gives "
                        "positive r)")
    p.add_argument("--dataset", help="dataset name for index.json (default: the parent folder of --out)")
    p.set_defaults(func=_run)


def is_tank_file(path: Path) -> bool:
    """False for files in a data folder that are not tank data (README.md, .stamp, .gitkeep, dotfiles)."""
    return not (path.name.startswith(".") or path.suffix.lower() in SKIP_SUFFIXES)


def _run(args) -> int:
    config = with_dt(IngestConfig(), args.dt)
    files = []
    for f in args.files:
        if is_tank_file(f):
            files.append(f)
        else:
            print(f"ingest: skipped {f} (not tank data)", file=sys.stderr)
    if not files:
        raise InputError("no tank files given")
    ids: dict[str, Path] = {}
    for f in files:
        if f.stem in ids:
            raise InputError(f"two files give the same run id {f.stem!r} (also {ids[f.stem]})", file=f.name)
        ids[f.stem] = f
    runs = [ingest_file(f, fmt=args.fmt, scale=args.scale, config=config, rudder_sign=args.rudder_sign)
            for f in files]
    dataset = args.dataset or args.out.resolve().parent.name
    provs = {r.meta.get("provenance") for r in runs}
    index = {
        "dataset": dataset,
        "provenance": provs.pop() if len(provs) == 1 else "mixed",
        "runs": [],
    }
    with atomic_dir(args.out) as tmp:
        for f, run in zip(files, runs, strict=True):
            run_id = f.stem
            run.meta["run_id"] = run_id
            run.meta["dataset"] = dataset
            write_run(tmp / f"{run_id}.parquet", run)
            index["runs"].append({"run_id": run_id, "file": f"{run_id}.parquet", **run.meta})
        write_json(tmp / "index.json", index)
    for run in runs:
        m = run.meta
        print(f"ingest: {m['run_id']}: {m['source_format']} {m['test_name']!r}, {m['samples']} samples at "
              f"{m['dt']:g} s, {m['duration']:.1f} s")
    print(f"written {len(runs)} runs and index.json to {args.out}")
    return 0
