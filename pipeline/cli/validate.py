"""``python -m pipeline validate --dataset D``: one-step and free-run validation
(docs/identification.md#validation).

Reads runs/index.json, the runs and identify/<alg>/estimates.json (every algorithm that has been
identified); writes validate/metrics.json and validate/predictions.parquet (pipeline/catalog.py).
"""

from __future__ import annotations

from pipeline.cli._common import add_dataset_args, catalog
from pipeline.config import FilterConfig
from pipeline.errors import InputError
from pipeline.indices.trust import identify_side_flags
from pipeline.io import atomic_dir, read_json, read_run, write_frame, write_json


def register(sub) -> None:
    p = sub.add_parser("validate", help="validate identified models on held-out data (one-step, free-run)")
    p.add_argument("--algorithms", nargs="*", default=["srukf-ffm", "ffm-ukf"])
    add_dataset_args(p)
    p.set_defaults(func=_run)


def _run(args) -> int:
    from pipeline.runinfo import choose_runs
    from pipeline.validate import metrics_document, validate

    cat = catalog(args)
    index = read_json(cat.runs_index)
    entries = index.get("runs") or []
    estimates = {}
    for alg in args.algorithms:
        path = cat.identify_dir(alg) / "estimates.json"
        if path.exists():
            estimates[alg] = read_json(path)
    if not estimates:
        raise InputError("no estimates.json for any algorithm (run `python -m pipeline identify` first)",
                         file=cat.identify_dir(args.algorithms[0]) / "estimates.json")
    ident_ids = {e.get("run_id") for e in estimates.values()}
    if len(ident_ids) != 1:
        raise InputError(f"the algorithms were identified on different runs {sorted(map(str, ident_ids))}")
    ident_id = ident_ids.pop()
    try:
        _, val_ids = choose_runs(entries, ident_id)
    except ValueError as exc:
        raise InputError(str(exc), file=cat.runs_index) from None
    files = {e["run_id"]: e.get("file", f"{e['run_id']}.parquet") for e in entries}

    def load(rid):
        run = read_run(cat.runs_dir / files[rid])
        run.meta["run_id"] = rid
        return run

    rows, preds = validate(estimates, load(ident_id), [load(r) for r in val_ids], FilterConfig())
    # the identify-side trust flags of each estimate travel with the errors computed from it
    doc = metrics_document(args.dataset, index, ident_run=ident_id, validation_runs=val_ids, rows=rows,
                           flags={alg: identify_side_flags(est) for alg, est in estimates.items()}).to_json()
    with atomic_dir(cat.validate_dir) as tmp:
        write_frame(tmp / "predictions.parquet", preds, {"dataset": args.dataset, "ident_run": ident_id})
        write_json(tmp / "metrics.json", doc)
    for r in rows:
        v = "   n/a  " if r["mse_v"] is None else f"{r['mse_v']:.2e}"
        print(f"{r['algorithm']:>9} {r['segment']:>19} {r['run_id']:<28} {r['mode']:>8}  MSE v {v}  "
              f"MSE r {r['mse_r']:.4g}  MAE psi {r['mae_psi']:.4g}  (n={r['samples']})")
    print(f"-> {cat.validate_dir}")
    return 0
