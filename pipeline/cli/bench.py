"""``python -m pipeline bench``: run every benchmark in :mod:`pipeline.bench` and print a table.

Each module in ``pipeline/bench/`` defines ``run(quick: bool) -> list[dict]``: rows with at least
``name``, ``value``, ``unit`` and optionally ``target`` and ``note``.  Ratios are always computed
within one run (baseline and candidate measured back to back).
"""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

from pipeline.io import write_json


def register(sub) -> None:
    p = sub.add_parser("bench", help="run the benchmarks (ingest throughput, filter speed)")
    p.add_argument("--only", nargs="*", help="benchmark modules to run (default: all)")
    p.add_argument("--quick", action="store_true", help="fewer repetitions")
    p.add_argument("--study", action="store_true",
                   help="study benchmarks: engine scaling (pipeline/bench/study.py), filter kernel")
    p.add_argument("--out", type=Path, default=Path("data/processed/bench.json"))
    p.set_defaults(func=_run, out_is_file=True)


def _run(args) -> int:
    import pipeline.bench as pkg

    rows: list[dict] = []
    if args.study:
        args.only = [*(args.only or []), "identify", "study"]
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_") or (args.only and info.name not in args.only):
            continue
        mod = importlib.import_module(f"pipeline.bench.{info.name}")
        for row in mod.run(quick=args.quick):
            rows.append({"benchmark": info.name, **row})
            print(_fmt(rows[-1]), flush=True)
    write_json(args.out, {"rows": rows})
    print(f"written {args.out}")
    return 0


def _fmt(row: dict) -> str:
    val = row["value"]
    text = f"{val:.4g}" if isinstance(val, float) else str(val)
    extra = f"  (target {row['target']})" if "target" in row else ""
    note = f"  {row['note']}" if row.get("note") else ""
    return f"{row['benchmark']:>10} | {row['name']:<48} {text:>12} {row.get('unit', '')}{extra}{note}"

