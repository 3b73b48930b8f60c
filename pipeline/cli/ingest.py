"""``python -m pipeline ingest``: raw tank files to processed runs (docs/contract.md, docs/dataset.md).

Two forms:

    python -m pipeline ingest --dataset NAME [--raw DIR] [--root DIR] [--out DIR] [--dt S]
    python -m pipeline ingest FILE... --out DIR [--dataset NAME] [--scale S] [--format F] [--rudder-sign -1]

The first finds the dataset's files itself (pipeline.dataset: data/raw/NAME/dataset.toml, its
``files_dir`` and ``files`` patterns; no file or folder name passes through a shell) and writes
``<root>/NAME/runs/`` (default data/processed/NAME/runs).  The dataset's scale, model scale, ship,
particulars, format, rudder sign and per-run overrides are applied; ``--scale`` etc. may not
contradict them.  The second reads the files given; with ``--dataset`` a dataset.toml of that name,
if there is one, is applied too.

All files are read and validated first; only if every one is good are ``<run_id>.parquet``
(run_id = file name without extension) and ``index.json`` written, as one set
(:func:`pipeline.io.atomic_dir`).  A bad file: one line naming the file and the problem, exit
status 2, nothing written, the output folder byte for byte as it was.

The second form adds or replaces only the runs it writes: the other runs already in ``--out`` are
kept unchanged, and ``index.json`` is rebuilt from every run in the folder (other files of the
user's stay).  The first form writes the dataset's whole set: runs in the folder whose raw file is
no longer part of the dataset are removed, with a notice naming them.  Files that are not tank
data (README.md, dataset.toml, .stamp, hidden files) are skipped with a note.

``index.json`` (pipeline/catalog.py): ``{"dataset", "provenance", "ship": {...particulars, scale},
"roles", "runs": [{"run_id", "file", ...meta}]}``.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

from pipeline.config import IngestConfig
from pipeline.dataset import (
    BUILTIN,
    DEFAULT_RAW,
    TOML_NAME,
    Dataset,
    check_run_ids,
    dataset_folder,
    is_tank_file,
    load_dataset,
    run_id_of,
)
from pipeline.errors import InputError
from pipeline.ingest import FORMATS, ingest_file, with_dt
from pipeline.io import atomic_dir, read_json, read_meta, write_json, write_run

__all__ = ["is_tank_file", "register"]


def register(sub) -> None:
    p = sub.add_parser("ingest", help="read, validate and resample raw tank files into processed runs")
    p.add_argument("files", nargs="*", type=Path, metavar="FILE",
                   help="raw files (CSV, MARIN/HSVA .dat); none: the files of --dataset")
    p.add_argument("--out", type=Path, help="output directory (default with --dataset: ROOT/NAME/runs)")
    p.add_argument("--dataset", help="dataset name: data/raw/NAME (its dataset.toml is applied)")
    p.add_argument("--raw", type=Path, default=DEFAULT_RAW, help="raw-data root (default: data/raw)")
    p.add_argument("--root", type=Path, default=Path("data/processed"),
                   help="processed-data root (default: data/processed)")
    p.add_argument("--format", dest="fmt", choices=FORMATS, help="override format recognition")
    p.add_argument("--scale", type=float, help="scale (full/model) of the values")
    p.add_argument("--dt", type=float, help="output step in s (default 0.08)")
    p.add_argument("--rudder-sign", type=int, choices=(1, -1), default=None,
                   help="-1 for files whose rudder is positive to port (canonical: positive delta gives "
                        "positive r)")
    p.set_defaults(func=_run)


def _notice(line: str) -> None:
    print(f"ingest: {line}", file=sys.stderr)


def _described(name: str, raw: Path) -> Dataset | None:
    """The dataset's description when it has one (a dataset.toml, or a built-in one), else None."""
    try:
        folder = dataset_folder(name, raw)
    except InputError:
        return None
    if (folder / TOML_NAME).is_file() or name in BUILTIN:
        return load_dataset(name, raw, write_missing=False)
    return None


def _merge(option, from_toml, what: str, toml_path) -> object:
    """The option's value, the dataset's, or refuse when they contradict each other."""
    if option is None:
        return from_toml
    if from_toml is not None and option != from_toml and toml_path is not None:
        raise InputError(f"{what} {option} contradicts {what} {from_toml} in the dataset description",
                         file=toml_path)
    return option


def _run(args) -> int:
    config = with_dt(IngestConfig(), args.dt)
    ds: Dataset | None = None
    if args.dataset:
        if args.files:
            ds = _described(args.dataset, args.raw)
        else:
            ds = load_dataset(args.dataset, args.raw, notice=_notice)
    elif not args.files:
        raise InputError("give raw files, or --dataset NAME (`python -m pipeline datasets` lists them)")
    if args.out is None:
        if not args.dataset:
            raise InputError("--out DIR is required when files are given without --dataset")
        args.out = args.root / args.dataset / "runs"
        from pipeline.cli._common import check_output_location

        check_output_location(args.out)
    toml = ds.toml_path if ds is not None else None
    scale = _merge(args.scale, ds.scale if ds is not None and ds.toml_path else None, "scale", toml)
    fmt = _merge(args.fmt, ds.format if ds is not None else None, "format", toml)
    sign = args.rudder_sign if args.rudder_sign is not None else (ds.rudder_sign if ds is not None else 1)
    if args.files:
        candidates = list(args.files)
    else:
        candidates = ds.raw_files()
        if ds.toml_path is not None:
            check_run_ids(ds, {run_id_of(f) for f in ds.raw_files(with_skipped=True)}, roles=False)
        if not candidates:
            raise InputError(f"no tank files in dataset {args.dataset!r}"
                             + (" (run `python -m pipeline tank --out data/raw/virtual` first)"
                                if args.dataset == "virtual" else ""), file=ds.files_dir)
    files = []
    for f in candidates:
        if is_tank_file(f):
            files.append(f)
        else:
            print(f"ingest: skipped {f} (not tank data)", file=sys.stderr)
    if not files:
        raise InputError("no tank files given")
    ids: dict[str, Path] = {}
    for f in files:
        rid = run_id_of(f)
        if rid in ids:
            raise InputError(f"two files give the same run id {rid!r} (also {ids[rid]})", file=f.name)
        ids[rid] = f
    runs = []
    for f in files:
        rid = run_id_of(f)
        over = ds.runs.get(rid) if ds is not None else None
        kw = {"rudder_sign": (over.rudder_sign if over and over.rudder_sign is not None else sign)}
        if over and over.test_name is not None:
            kw["test_name"] = over.test_name
        if over and over.kind is not None:
            kw["kind"] = over.kind
        if ds is not None and ds.columns is not None:
            if fmt is not None:
                raise InputError("a format and a [columns] mapping are both given: the mapping reads the "
                                 "logger's table, give one", file=ds.toml_path)
            kw["columns"] = ds.columns
        if ds is not None and ds.toml_path is not None:
            kw.update(ship=ds.ship.name, lpp_full=ds.ship.lpp_m, model_scale=ds.model_scale)
        run = ingest_file(f, fmt=fmt, scale=scale, config=config, **kw)
        if ds is not None and ds.provenance:
            # the description's word on what the files are, before anything (the index below) reads it
            run.meta["provenance"] = ds.provenance
        runs.append(run)
    previous = _read_index(args.out)
    dataset = args.dataset or previous.get("dataset") or args.out.resolve().parent.name
    new_ids = {run_id_of(f) for f in files}
    # FILE... adds or replaces only its runs; the dataset form writes the dataset's whole set
    kept = _runs_in(args.out, exclude=new_ids) if args.files else {}
    dropped = [] if args.files or not args.out.is_dir() else sorted(
        p.stem for p in args.out.glob("*.parquet") if p.stem not in new_ids)
    for f, run in zip(files, runs, strict=True):
        run.meta["run_id"] = run_id_of(f)
        run.meta["dataset"] = dataset
        if ds is not None:
            for k, v in ds.particulars().items():
                if v is not None:
                    run.meta.setdefault(k, v)
    entries = {run.meta["run_id"]: {"run_id": run.meta["run_id"], "file": f"{run.meta['run_id']}.parquet",
                                    **run.meta} for run in runs}
    entries.update({rid: {"run_id": rid, "file": path.name, **meta}
                    for rid, (path, meta) in kept.items() if meta is not None})
    provs = {e.get("provenance") for e in entries.values()}
    index = {
        "dataset": dataset,
        "provenance": provs.pop() if len(provs) == 1 else "mixed",
    }
    if ds is not None:
        index["ship"] = ds.particulars()
        index["roles"] = {"identify": ds.roles.identify, "train": list(ds.roles.train),
                          "validate": list(ds.roles.validate), "test": list(ds.roles.test)}
        index["identify"] = ds.identify.as_dict()
    else:
        index.update({k: previous[k] for k in ("ship", "roles", "identify") if k in previous})
    index["runs"] = [entries[k] for k in sorted(entries)]
    if ds is not None and ds.toml_path is not None:
        # the runs a description may name: those in the output folder, and (files given) those of
        # the dataset's own folder, which a later ingest may bring (a skipped one only for [runs])
        mine = set(entries)
        if args.files and ds.files_dir.is_dir():
            listed = {run_id_of(f) for f in ds.raw_files()}
            check_run_ids(ds, mine | {run_id_of(f) for f in ds.raw_files(with_skipped=True)}, roles=False)
            mine |= listed
        check_run_ids(ds, mine, runs=False)
    with atomic_dir(args.out, writer="ingest") as tmp:
        for run in runs:
            write_run(tmp / f"{run.meta['run_id']}.parquet", run)
        for path, _ in kept.values():
            _carry(path, tmp / path.name)
        write_json(tmp / "index.json", index)
    for run in runs:
        m = run.meta
        print(f"ingest: {m['run_id']}: {m['source_format']} {m['test_name']!r}, {m['samples']} samples at "
              f"{m['dt']:g} s, {m['duration']:.1f} s, scale {m['scale_factor']:g}")
    for path, meta in (kept[k] for k in sorted(kept)):
        if meta is None:
            _notice(f"{path} is not a processed run (no ingest metadata): kept, not in the index")
    if dropped:
        _notice(f"removed {len(dropped)} run(s) whose raw file is not in the dataset: "
                + ", ".join(dropped))
    kept_runs = sum(meta is not None for _, meta in kept.values())
    print(f"written {len(runs)} runs and index.json ({len(index['runs'])} runs"
          + (f", {kept_runs} kept from earlier ingests" if kept_runs else "") + f") to {args.out}")
    return 0


def _read_index(out: Path) -> dict:
    """The index.json already in ``out`` ({} when there is none or it is unreadable: it is rebuilt)."""
    try:
        index = read_json(out / "index.json")
    except InputError:
        return {}
    return index if isinstance(index, dict) else {}


def _runs_in(out: Path, *, exclude: set[str]) -> dict[str, tuple[Path, dict | None]]:
    """The Parquet files already in ``out`` other than the runs ``exclude`` names: run id ->
    (path, run metadata, or None for a Parquet file that is not a processed run of ingest).  A damaged run
    (unreadable Parquet or metadata) is refused, naming it: the index cannot be rebuilt without it."""
    found: dict[str, tuple[Path, dict | None]] = {}
    if not out.is_dir():
        return found
    for path in sorted(out.glob("*.parquet")):
        rid = path.stem
        if rid in exclude or not path.is_file() or path.is_symlink():
            continue
        meta = read_meta(path)
        # a processed run says where it came from (other stages' Parquet files, e.g. identify's
        # trace.parquet, carry metadata too, but not a source file)
        if meta is not None and not ("source_sha256" in meta and "source_format" in meta):
            meta = None
        if meta is not None:
            meta = {**meta, "run_id": rid}
        found[rid] = (path, meta)
    return found


def _carry(src: Path, dst: Path) -> None:
    """Put an earlier run into the new set unchanged (a hard link; a copy across file systems)."""
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)
