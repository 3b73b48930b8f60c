"""``python -m pipeline diagnose``: SPEC section 7.

Explicit mode:  ``--train RUN [RUN ...] --validate RUN [RUN ...] --out DIR [--scale S]``, RUN a raw
file of any SPEC section 3 format or a processed Parquet run.
Catalog mode:   ``--dataset D`` trains on the identification run that pipeline.runinfo.choose_runs
picks from data/processed/D/runs/index.json plus (DiagnoseConfig.other_side) a zigzag of the
other side with another amplitude, and validates on their mirror images (both sides, two
amplitudes), or on every other zigzag when the mirrors are not there
(pipeline.runinfo.choose_diagnosis_runs); writes data/processed/D/diagnose/.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.cli._common import add_dataset_args, catalog
from pipeline.config import DiagnoseConfig
from pipeline.errors import InputError
from pipeline.io import Run, read_json, read_run


def load_run(path: str | Path, scale: float | None = None) -> Run:
    """A processed Parquet run, or a raw file read by the ingest stage."""
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", file=path)
    if path.suffix.lower() == ".parquet":
        return read_run(path)
    try:
        from pipeline.ingest import ingest_file
    except ImportError as exc:  # pragma: no cover - the ingest stage is part of the project
        raise InputError(f"cannot read raw files: ingest stage unavailable ({exc})", file=path) from None
    kw = {"fmt": None}
    if scale is not None:
        kw["scale"] = scale
    run = ingest_file(path, **kw)
    run.meta.setdefault("run_id", path.stem)
    return run


def pick_catalog_runs(entries: list[dict], other_side: bool = True) -> tuple[list[str], list[str]]:
    """Training and validation run ids from a runs index (pipeline.runinfo.choose_diagnosis_runs)."""
    from pipeline.runinfo import choose_diagnosis_runs

    try:
        return choose_diagnosis_runs(entries, other_side)
    except ValueError as exc:
        raise InputError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    cfg = DiagnoseConfig()
    if args.train or args.validate:
        if not (args.train and args.validate and args.out):
            raise InputError("explicit mode needs --train, --validate and --out")
        train = [load_run(p, args.scale) for p in args.train]
        val = [load_run(p, args.scale) for p in args.validate]
        out = Path(args.out)
    else:
        cat = catalog(args)
        index = read_json(cat.runs_index)
        entries = index.get("runs", [])
        train_ids, val_ids = pick_catalog_runs(entries, cfg.other_side)
        files = {e["run_id"]: e.get("file", f"{e['run_id']}.parquet") for e in entries}

        def load(rid):
            f = Path(files[rid])
            return read_run(f if f.is_absolute() or f.exists() else cat.runs_dir / f.name)

        train = [load(r) for r in train_ids]
        val = [load(r) for r in val_ids]
        out = Path(args.out) if args.out else cat.diagnose_dir

    from pipeline.diagnose import diagnose
    from pipeline.diagnose.output import write_outputs

    diag = diagnose(train, val, cfg, progress=True)
    path = write_outputs(diag, out, plots=not args.no_plots)
    rep = diag.report
    print(
        f"diagnosis: cause {rep['cause']}; held-out MAE psi "
        f"{rep['baseline']['validation']['mae_psi_deg']:.3f} -> "
        f"{rep['extended']['validation']['mae_psi_deg']:.3f} deg "
        f"(gain {rep['gain']['mae_psi_relative_reduction']:.0%}); wrote {path}"
    )
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "diagnose",
        help="what the linear model gets wrong, the cause, the extended model (SPEC 7)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--train", nargs="+", metavar="RUN", help="training runs (raw file or processed Parquet)")
    p.add_argument("--validate", nargs="+", metavar="RUN", help="validation runs")
    p.add_argument("--out", type=Path, help="output directory (catalog mode: data/processed/D/diagnose)")
    p.add_argument("--scale", type=float, default=None, help="scale factor of full-scale raw files")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_dataset_args(p)
    p.set_defaults(func=run)
