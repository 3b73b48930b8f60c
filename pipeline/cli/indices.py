"""``python -m pipeline indices --dataset D``: Nomoto indices with uncertainty, zigzag/turning metrics,
graphical and integral K-T, Table 7 (pipeline.indices; files per pipeline/catalog.py)."""

from __future__ import annotations

import dataclasses

from pipeline.cli._common import add_dataset_args, catalog
from pipeline.config import IndicesConfig
from pipeline.errors import InputError
from pipeline.indices.stage import build, resolve_run_path
from pipeline.io import atomic_dir, read_json, read_run, write_json


def register(sub) -> None:
    p = sub.add_parser("indices", help="Nomoto indices with uncertainty, zigzag/turning metrics, IMO check")
    add_dataset_args(p)
    p.add_argument("--identification", default=None,
                   help="run_id of the identification run (default: pipeline.runinfo.choose_runs)")
    p.add_argument("--uncertainty", choices=("unscented", "linear"), default=IndicesConfig.uncertainty,
                   help="propagation of the parameter covariance (default: unscented)")
    p.set_defaults(func=_run)


def _run(args) -> int:
    cat = catalog(args)
    cfg = dataclasses.replace(IndicesConfig(), uncertainty=args.uncertainty)
    index = read_json(cat.runs_index)
    entries = index.get("runs")
    if not isinstance(entries, list) or not entries:
        raise InputError("no runs listed", file=cat.runs_index)
    runs = {}
    for e in entries:
        if "run_id" not in e:
            raise InputError("an entry has no run_id", file=cat.runs_index)
        runs[e["run_id"]] = read_run(resolve_run_path(cat.runs_dir, e))
    estimates = {}
    for alg in cfg.algorithms:
        path = cat.identify_dir(alg) / "estimates.json"
        if path.is_file():
            estimates[alg] = read_json(path)
        elif alg == "srukf-ffm":
            raise InputError("file not found (run `python -m pipeline identify --dataset "
                             f"{args.dataset} --algorithm {alg}` first)", file=path)
    ind, zz, table = build(index, runs, estimates, cfg, identification=args.identification)
    with atomic_dir(cat.indices_dir) as tmp:
        write_json(tmp / "indices.json", ind)
        write_json(tmp / "zigzag.json", zz)
        table.to_csv(tmp / "table7.csv", index=False, float_format="%.6g")
    print(f"written {cat.indices_dir}/indices.json, zigzag.json, table7.csv "
          f"({len(runs)} runs; control model: {ind['control_model']['source']})")
    return 0
