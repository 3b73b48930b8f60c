"""``python -m pipeline diagnose``: docs/diagnosis.md.

Explicit mode:  ``--train RUN [RUN ...] --validate RUN [RUN ...] --out DIR [--scale S]``, RUN a raw
file of any docs/contract.md#raw-formats format or a processed Parquet run.
           ``[--test RUN ...]``: the gain is reported on the test runs (else nested cross-validation).
Catalog mode:   ``--dataset D`` uses every zigzag and turning circle of data/processed/D/runs/index.json
by the rule of the diagnose package (pipeline.diagnose.design: selection runs in twins spanning the
rudder and heading amplitudes, crossed by side; turning circles in twins crossed the same way; every
other run a test run; runs at another approach speed than the largest set that agrees within 15 % left
out, with the reason, in ``runs_not_used`` of diagnosis.json), or, when the dataset's description
gives ``[roles]`` train and validate (docs/dataset.md), by those roles (pick_catalog_runs, one_speed,
roles_design);
writes data/processed/D/diagnose/.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from pipeline.cli._common import add_dataset_args, catalog
from pipeline.config import DiagnoseConfig
from pipeline.diagnose.design import (  # noqa: F401 - re-exported for one release: import from there
    extrapolated,
    one_speed,
    pick_catalog_runs,
    pick_zigzags,
    roles_design,
)
from pipeline.errors import InputError
from pipeline.io import Run, read_json, read_run

#: deprecated alias of :attr:`pipeline.config.DiagnoseConfig.twin_tolerance`, kept for one release
TWIN_TOL = DiagnoseConfig().twin_tolerance


def load_run(path: str | Path, scale: float | None = None) -> Run:
    """A processed Parquet run, or a raw file read by the ingest stage."""
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", file=os.path.abspath(path))
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


def _other_speed(e: dict, used: list[dict], tol: float) -> str:
    speeds = sorted(float(x["approach_speed"]) for x in used if x.get("approach_speed"))
    return (f"approach speed {float(e['approach_speed']):.3f} m/s, the design's "
            f"{speeds[0]:.3f}-{speeds[-1]:.3f} m/s: more than {tol:.0%} apart, and one linear model holds at "
            "one speed; diagnose it with --train/--validate")




def run(args: argparse.Namespace) -> int:
    cfg = DiagnoseConfig()
    not_used: dict[str, str] = {}       # catalog mode: runs of the index left out, with the reason
    if args.train or args.validate:
        if not (args.train and args.validate and args.out):
            raise InputError("explicit mode needs --train, --validate and --out")
        train = [load_run(p, args.scale) for p in args.train]
        val = [load_run(p, args.scale) for p in args.validate]
        test = [load_run(p, args.scale) for p in (args.test or [])]
        out = Path(args.out)
    else:
        cat = catalog(args)
        index = read_json(cat.runs_index)
        roles = roles_design(index)
        if roles is not None:
            # the user's own design (docs/dataset.md [roles]): taken as given; the diagnosis itself
            # refuses runs of different approach speeds
            entries = index.get("runs", [])
            train_ids, val_ids, test_ids = roles
            placed = set(train_ids + val_ids + test_ids)
            not_used = {e["run_id"]: "in no [roles] of the dataset's description" for e in entries
                        if e["run_id"] not in placed}
        else:
            entries, other = one_speed(index.get("runs", []), cfg.speed_tolerance)
            not_used = {e["run_id"]: _other_speed(e, entries, cfg.speed_tolerance) for e in other}
            train_ids, val_ids, test_ids = pick_catalog_runs(entries)
            placed = set(train_ids + val_ids + test_ids)
            not_used.update({e["run_id"]: f"a test of kind '{e.get('kind')}': the design takes zigzags "
                                          "and turning circles"
                             for e in entries if e["run_id"] not in placed})
        if not_used:
            print("not used: " + "; ".join(f"{k} ({why})" for k, why in not_used.items()))
        outside = extrapolated(entries, train_ids + val_ids, test_ids)
        print(
            ("design (the dataset's [roles])" if roles is not None else "design")
            + f": train {', '.join(train_ids)}; validate {', '.join(val_ids)}; test "
            f"{', '.join(test_ids) or 'none (the honest gain by nested leave-one-run-out)'}"
            + (f"; outside the selection's amplitudes: {', '.join(outside)}" if outside else "")
        )
        files = {e["run_id"]: e.get("file", f"{e['run_id']}.parquet") for e in entries}

        def load(rid):
            f = Path(files[rid])
            return read_run(f if f.is_absolute() or f.exists() else cat.runs_dir / f.name)

        train = [load(r) for r in train_ids]
        val = [load(r) for r in val_ids]
        test = [load(r) for r in test_ids]
        out = Path(args.out) if args.out else cat.diagnose_dir

    from pipeline.diagnose import diagnose
    from pipeline.diagnose.output import write_outputs

    diag = diagnose(train, val, cfg=cfg, progress=True, test=test)
    diag.report["runs_not_used"] = not_used
    path = write_outputs(diag, out, plots=not args.no_plots)
    rep = diag.report
    from pipeline.report.diagnosis_text import headline

    print(f"{headline(rep)}; wrote {path}")
    for check in rep["data_checks"].values():
        if check["warning"]:
            print(f"warning: {check['warning']}", file=sys.stderr)
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "diagnose",
        help="what the linear model gets wrong, the cause, the extended model (docs/diagnosis.md)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--train", nargs="+", metavar="RUN", help="training runs (raw file or processed Parquet)")
    p.add_argument("--validate", nargs="+", metavar="RUN", help="validation runs")
    p.add_argument(
        "--test",
        nargs="+",
        metavar="RUN",
        help="test runs: the gain is reported on them (no choice "
        "sees them); without them, nested cross-validation",
    )
    p.add_argument("--out", type=Path, help="output directory (catalog mode: data/processed/D/diagnose)")
    p.add_argument("--scale", type=float, default=None, help="scale factor of full-scale raw files")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_dataset_args(p)
    p.set_defaults(func=run)
