"""``python -m pipeline identify``: online identification (docs/identification.md).

Single run:   python -m pipeline identify RUN --out DIR [--algorithm srukf-ffm|ffm-ukf] [--samples N]
Catalog mode: python -m pipeline identify --dataset D [--algorithm A]   (both algorithms by default)

RUN is a processed Parquet run or a raw tank file (read through pipeline.ingest.ingest_file).
Writes estimates.json and trace.parquet (catalog: data/processed/D/identify/<alg>/).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

from pipeline.cli._common import add_dataset_args, catalog
from pipeline.config import FilterConfig
from pipeline.errors import InputError
from pipeline.io import Run, atomic_dir, read_json, read_run, write_frame, write_json


def register(sub) -> None:
    p = sub.add_parser("identify", help="online identification of the sway-yaw model (SR-UKF-FFM / FFM-UKF)")
    p.add_argument("run", nargs="?", type=Path, help="processed run (.parquet) or raw tank file")
    p.add_argument("--out", type=Path, help="output directory (single-run mode)")
    p.add_argument("--algorithm", choices=("srukf-ffm", "ffm-ukf"),
                   help="filter (default: srukf-ffm for one run, both in catalog mode)")
    p.add_argument("--samples", type=int, default=None, help="identification window (default 585)")
    p.add_argument("--window-s", type=float, default=None,
                   help="identification window as a duration in s at the run's scale (scale-free)")
    p.add_argument("--half-periods", type=float, default=None,
                   help="identification window as a number of zigzag half-periods after the first execute")
    p.add_argument("--measurement-noise", choices=("paper", "data"), default=None,
                   help="R of the filter: the paper's setting (default) or measured from the run")
    p.add_argument("--process-noise", choices=("paper", "data"), default=None,
                   help="Q of the motion states: the paper's setting (default) or matched to the run's "
                        "innovations (mean NIS = m)")
    p.add_argument("--scale", type=float, default=None, help="scale factor of a full-scale raw file")
    p.add_argument("--run-id", default=None, help="catalog mode: identify this run instead of the default")
    p.add_argument("--reference", action="store_true", help="SR-UKF: numpy reference path instead of numba")
    add_dataset_args(p)
    p.set_defaults(func=_run)


def load_run(path: Path, scale: float | None = None) -> Run:
    """A processed Parquet run, or a raw file through the ingest stage."""
    if not path.exists():
        raise InputError("file not found", file=os.path.abspath(path))
    if path.suffix.lower() == ".parquet":
        return read_run(path)
    try:
        from pipeline.ingest import ingest_file
    except ImportError:
        raise InputError("raw files need the ingest stage (pipeline.ingest), which is not available",
                         file=path) from None
    return ingest_file(path, scale=scale) if scale is not None else ingest_file(path)


def _write(out_dir: Path, ident, meta: dict, cfg: FilterConfig, dataset: str | None) -> None:
    from pipeline.catalog import TIMING_FILE
    from pipeline.identify import estimates_json

    with atomic_dir(out_dir, writer="identify") as tmp:
        write_frame(tmp / "trace.parquet", ident.trace, {"run_id": meta.get("run_id"),
                                                         "algorithm": ident.algorithm,
                                                         "provenance": meta.get("provenance")})
        write_json(tmp / "estimates.json", estimates_json(ident, meta, cfg, dataset=dataset))
        write_json(tmp / TIMING_FILE, ident.timing)     # seconds: kept out of the compared results


def _summary(ident, where: Path) -> str:
    p = ", ".join(f"{k} {v:.4g}" for k, v in ident.parameters.items())
    kt = (f"K {ident.indices['K']:.4g} T {ident.indices['T']:.4g}" if ident.indices
          else f"indices n/a ({ident.indices_error})")
    t = ident.timing
    line = (f"{ident.algorithm}: {ident.samples} samples, {p}; {kt}; loop {t['seconds_total'] * 1e3:.2f} ms "
            f"({t['seconds_per_step'] * 1e6:.1f} us/step); "
            f"mean NIS {ident.consistency['nis_mean']:.2f} -> {where}")
    for f in ident.flags:
        line += f"\nwarning: {ident.algorithm}: flagged {f['check']}: {f['reason']}"
    return line


def dataset_settings(cfg: FilterConfig, settings: dict, args, where: Path) -> FilterConfig:
    """The dataset's ``[identify]`` settings (dataset.toml, recorded in runs/index.json) where the
    command line gives none: the window (samples, window_s or half_periods) and measurement_noise."""
    if not isinstance(settings, dict):
        raise InputError("'identify' must be a table of settings", file=where)
    if all(x is None for x in (args.samples, args.window_s, args.half_periods)):
        if settings.get("window_s") is not None:
            cfg = dataclasses.replace(cfg, window_s=float(settings["window_s"]))
        elif settings.get("half_periods") is not None:
            cfg = dataclasses.replace(cfg, window_half_periods=float(settings["half_periods"]))
        elif settings.get("samples") is not None:
            cfg = dataclasses.replace(cfg, samples=int(settings["samples"]))
    if args.measurement_noise is None and settings.get("measurement_noise") is not None:
        cfg = dataclasses.replace(cfg, measurement_noise=str(settings["measurement_noise"]))
    if args.process_noise is None and settings.get("process_noise") is not None:
        cfg = dataclasses.replace(cfg, process_noise=str(settings["process_noise"]))
    return cfg


def _run(args) -> int:
    from pipeline.identify import identify_run
    from pipeline.runinfo import choose_runs

    cfg = FilterConfig()
    if sum(x is not None for x in (args.samples, args.window_s, args.half_periods)) > 1:
        raise InputError("give one of --samples, --window-s, --half-periods")
    if args.window_s is not None:
        if not args.window_s > 0:
            raise InputError(f"--window-s must be positive, got {args.window_s}")
        cfg = dataclasses.replace(cfg, window_s=args.window_s)
    if args.half_periods is not None:
        if not args.half_periods > 0:
            raise InputError(f"--half-periods must be positive, got {args.half_periods}")
        cfg = dataclasses.replace(cfg, window_half_periods=args.half_periods)
    if args.reference:
        cfg = dataclasses.replace(cfg, fast=False)
    if args.measurement_noise is not None:
        cfg = dataclasses.replace(cfg, measurement_noise=args.measurement_noise)
    if args.process_noise is not None:
        cfg = dataclasses.replace(cfg, process_noise=args.process_noise)
    if args.samples is not None and args.samples < 10:
        raise InputError(f"--samples must be at least 10, got {args.samples}")
    if args.run is not None:
        if args.out is None:
            raise InputError("--out DIR is required with a RUN")
        run = load_run(args.run, args.scale)
        alg = args.algorithm or "srukf-ffm"
        ident = identify_run(run, cfg, algorithm=alg, samples=args.samples)
        _write(args.out, ident, run.meta, cfg, None)
        print(_summary(ident, args.out))
        return 0
    cat = catalog(args)
    index = read_json(cat.runs_index)
    cfg = dataset_settings(cfg, index.get("identify") or {}, args, cat.runs_index)
    entries = index.get("runs") or []
    try:
        ident_id, _ = choose_runs(entries, args.run_id or (index.get("roles") or {}).get("identify"))
    except ValueError as exc:
        raise InputError(str(exc), file=cat.runs_index) from None
    entry = next(e for e in entries if e["run_id"] == ident_id)
    run = read_run(cat.runs_dir / entry.get("file", f"{ident_id}.parquet"))
    run.meta.setdefault("run_id", ident_id)
    run.meta.setdefault("provenance", entry.get("provenance", index.get("provenance")))
    algs = [args.algorithm] if args.algorithm else ["srukf-ffm", "ffm-ukf"]
    # all succeed before writing
    idents = [(a, identify_run(run, cfg, algorithm=a, samples=args.samples)) for a in algs]
    for alg, ident in idents:
        out = cat.identify_dir(alg)
        _write(out, ident, run.meta, cfg, args.dataset)
        print(_summary(ident, out))
    return 0
