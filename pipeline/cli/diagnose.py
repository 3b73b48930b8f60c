"""``python -m pipeline diagnose``: SPEC section 7.

Explicit mode:  ``--train RUN [RUN ...] --validate RUN [RUN ...] --out DIR [--scale S]``, RUN a raw
file of any SPEC section 3 format or a processed Parquet run.
           ``[--test RUN ...]``: the gain is reported on the test runs (else nested cross-validation).
Catalog mode:   ``--dataset D`` uses every zigzag of data/processed/D/runs/index.json by the rule of
:func:`pick_catalog_runs` (crossed side/amplitude selection runs, every other run a test run);
writes data/processed/D/diagnose/.
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


def pick_catalog_runs(entries: list[dict]) -> tuple[list[str], list[str], list[str]]:
    """Training, validation and test run ids from a runs index, by a stated rule (all runs used).

    Zigzags are grouped by test (rudder/heading amplitude) and first side.  Tests run to both sides
    ("pairs") make the selection runs: with two or more pairs, the pair of the largest and the pair of
    the smallest rudder amplitude form a crossed design: train on (large, starboard) + (small, port),
    validate on (large, port) + (small, starboard) (both sides and both amplitudes on each side; the
    diagnosis adds the reverse fold); with one pair, train on its starboard run and validate on its port
    run.  Every other zigzag is a TEST run: no choice sees it, the gain is reported on it.  Without any
    pair, the zigzags sorted by amplitude are dealt train, validate, test in turn.
    """
    zz = [e for e in entries if str(e.get("kind", "zigzag")).startswith("zig")] or list(entries)
    if len(zz) < 2:
        raise InputError("catalog mode needs at least two zigzag runs (one to train, one to validate)")

    def test(e):
        return (e.get("rudder_deg"), e.get("heading_deg"))

    groups: dict = {}
    for e in zz:
        groups.setdefault(test(e), {})[e.get("first_side")] = e["run_id"]
    pairs = sorted(
        (k for k, g in groups.items() if "starboard" in g and "port" in g),
        key=lambda k: (k[0] or 0, k[1] or 0),
    )
    if len(pairs) >= 2:
        big, small = groups[pairs[-1]], groups[pairs[0]]
        train = [big["starboard"], small["port"]]
        val = [big["port"], small["starboard"]]
    elif len(pairs) == 1:
        train, val = [groups[pairs[0]]["starboard"]], [groups[pairs[0]]["port"]]
    else:
        order = [e["run_id"] for e in sorted(zz, key=lambda e: (e.get("rudder_deg") or 0, e["run_id"]))]
        train, val = order[0::3], order[1::3]
        rest = order[2::3]
        return train, val, rest
    used = set(train + val)
    return train, val, [e["run_id"] for e in zz if e["run_id"] not in used]


def run(args: argparse.Namespace) -> int:
    cfg = DiagnoseConfig()
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
        entries = index.get("runs", [])
        train_ids, val_ids, test_ids = pick_catalog_runs(entries)
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

    diag = diagnose(train, val, cfg, progress=True, test=test)
    path = write_outputs(diag, out, plots=not args.no_plots)
    rep = diag.report
    print(
        f"diagnosis: cause {rep['cause']}; held-out MAE psi "
        f"{rep['baseline']['validation']['mae_psi_deg']:.3f} -> "
        f"{rep['extended']['validation']['mae_psi_deg']:.3f} deg "
        f"(held-out gain {_pct(rep['gain']['mae_psi_relative_reduction'])} on "
        f"{', '.join(rep['gain']['measured_on']) or 'no unseen run'}); wrote {path}"
    )
    return 0


def _pct(x) -> str:
    return "n/a" if x is None else f"{x:.0%}"


def register(sub) -> None:
    p = sub.add_parser(
        "diagnose",
        help="what the linear model gets wrong, the cause, the extended model (SPEC 7)",
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
