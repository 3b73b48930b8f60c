"""Study kind ``batch_identify``: identify (and optionally diagnose) every raw file of an archive.

One case per file (any format of docs/contract.md#raw-formats, recognised from its content or forced by
``format``): ingest (:func:`pipeline.ingest.ingest_file`), identify the first ``samples`` samples with
the SR-UKF-FFM (:func:`pipeline.identify.identify_run`), Nomoto indices
(docs/contract.md#the-identification-model), free-run validation on the rest of the run (MSE v, MSE r, MAE
psi; docs/contract.md#metrics), zigzag metrics when the run is a zigzag
(:func:`pipeline.indices.stage.analyse_run`), and with ``diagnose = true`` the diagnosis trained on the
identification window and validated on the rest.  The result is one table, one row per file, ready for a fleet
or archive view; a file that cannot be read is one row with its error.  Each case is serial; the engine runs
one per worker process, so a batch uses every core.

A file's case id includes its SHA-256, so a changed file is identified again on resume.  Paths are
taken relative to the working directory; on a remote cluster the workers must see the same paths.
"""

from __future__ import annotations

import dataclasses as dc
import hashlib
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pipeline.config import BatchIdentifyConfig, FilterConfig, IngestConfig
from pipeline.errors import InputError
from pipeline.study.kind import StudyKind

SKIP_SUFFIXES = (".md", ".txt", ".toml", ".json", ".stamp")


def files(cfg: BatchIdentifyConfig) -> list[Path]:
    out: list[Path] = []
    if not cfg.inputs:
        raise InputError("batch_identify.inputs is empty: give files or folders")
    for item in cfg.inputs:
        p = Path(item)
        if p.is_dir():
            out += sorted(f for f in p.glob(cfg.pattern) if f.is_file() and not f.name.startswith(".")
                          and f.suffix.lower() not in SKIP_SUFFIXES)
        elif p.is_file():
            out.append(p)
        else:
            raise InputError("batch_identify input not found", file=item)
    return out


def check(cfg: BatchIdentifyConfig) -> None:
    """Refuse settings no case could run with, naming the key (the spec's ``check``)."""
    t = "batch_identify"
    if cfg.samples < 2:                               # a filter run needs at least two samples
        raise InputError(f"key '{t}.samples': must be at least 2, got {cfg.samples}")
    if not cfg.dt > 0:
        raise InputError(f"key '{t}.dt': the resampling step must be > 0 s, got {cfg.dt}")
    if cfg.scale is not None and not cfg.scale >= 1:  # full/model: a model is never larger than its ship
        raise InputError(f"key '{t}.scale': must be at least 1 (full/model), got {cfg.scale}")


def cases(cfg: BatchIdentifyConfig) -> list[dict[str, Any]]:
    check(cfg)
    out = []
    for f in files(cfg):
        sha = hashlib.sha256(f.read_bytes()).hexdigest()
        out.append({"file": str(f), "file_sha256": sha})
    if not out:
        raise InputError(f"batch_identify: no files match {cfg.pattern!r} in {', '.join(cfg.inputs)}")
    return out


def run_case(params: dict, seed: int, cfg: BatchIdentifyConfig) -> dict[str, Any]:
    from pipeline.identify import identify_run
    from pipeline.indices.stage import analyse_run
    from pipeline.ingest import ingest_file
    from pipeline.model import nomoto_indices
    from pipeline.validate import free_run, scores

    path = Path(params["file"])
    if hashlib.sha256(path.read_bytes()).hexdigest() != params["file_sha256"]:
        raise InputError("file changed since the study was planned", file=path)
    run = ingest_file(path, fmt=cfg.format, scale=cfg.scale, config=dc.replace(IngestConfig(), dt=cfg.dt))
    fcfg = dc.replace(FilterConfig(), samples=cfg.samples, algorithm=cfg.algorithm)
    ident = identify_run(run, fcfg)
    out: dict[str, Any] = {
        "run_id": run.name, "test_name": run.meta.get("test_name"),
        "source_format": run.meta.get("source_format"), "provenance": run.meta.get("provenance", "measured"),
        "samples_total": len(run.frame), "samples_identified": ident.samples, "dt_s": ident.dt,
        "measured": ",".join(ident.measured),
        **{p: float(v) for p, v in ident.parameters.items()},
        **{f"{p}_std": float(np.sqrt(max(ident.covariance[i, i], 0.0)))
           for i, p in enumerate(ident.parameters)},
        "nis_mean": ident.consistency["nis_mean"],
    }
    try:
        idx = nomoto_indices(ident.parameters)
        out.update({k: float(v) for k, v in idx.items()})
        out["indices_error"] = None
    except Exception as exc:  # noqa: BLE001 - an unstable identified model has no indices; say why
        out["indices_error"] = str(exc)
    n = len(run.frame)
    start = ident.samples - 1
    if n > ident.samples + 10:
        est = {"parameters": ident.parameters}
        _, _, y3 = _arrays(run)
        pred = free_run(est, run, start=start, v_start=float(ident.x_final[0]))
        s = scores(y3[start + 1:], pred)
        out.update({f"validation_{k}": (float(v) if v is not None else None) for k, v in s.items()})
        out["validation_samples"] = int(n - start - 1)
    else:
        out["validation_samples"] = 0
    ana = analyse_run(run)
    if ana.get("metrics") and ana["kind"] == "zigzag":
        for k, v in _flat(ana["metrics"]).items():
            out[f"zigzag_{k}"] = v
    for name, kt in (ana.get("kt") or {}).items():
        if isinstance(kt, dict):
            for k in ("K", "T"):
                if isinstance(kt.get(k), int | float):
                    out[f"kt_{name}_{k}"] = float(kt[k])
    if cfg.diagnose:
        out.update(_diagnose(run, ident.samples))
    return out


def _arrays(run):
    from pipeline.identify.core import _arrays as arrays

    return arrays(run)


def _flat(d: dict, prefix: str = "") -> dict[str, Any]:
    """Numeric leaves of a nested dict, keys joined with '_' (lists and texts left out)."""
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flat(v, key + "_"))
        elif isinstance(v, bool):
            out[key] = v
        elif isinstance(v, int | float | np.floating | np.integer):
            out[key] = float(v)
    return out


def _diagnose(run, samples: int) -> dict[str, Any]:
    from pipeline.diagnose import diagnose
    from pipeline.io import Run

    f = run.frame
    cut = min(samples, len(f) // 2)
    train = Run(frame=f.iloc[:cut].reset_index(drop=True), meta={**run.meta, "run_id": f"{run.name}:train"})
    rest = f.iloc[cut:].reset_index(drop=True)
    rest["time"] = rest["time"] - rest["time"].iloc[0]
    val = Run(frame=rest, meta={**run.meta, "run_id": f"{run.name}:validate"})
    try:
        rep = diagnose([train], [val]).report
    except Exception as exc:  # noqa: BLE001 - a diagnosis that cannot run is a column, not a lost file
        return {"diagnosis_cause": None, "diagnosis_error": " ".join(str(exc).split())}
    return {"diagnosis_cause": rep["cause"],
            "diagnosis_effects": ",".join(rep["extended"]["effects"]),
            "diagnosis_gain": rep.get("gain", {}).get("mae_psi_relative_reduction"),
            "diagnosis_error": None}


def warm(cfg: BatchIdentifyConfig) -> None:
    """Compile the SR-UKF kernel on a worker."""
    from pipeline.identify import identify_arrays, synthetic

    t, d, _, y = synthetic.zigzag(n=40, seed=1)
    identify_arrays(t, d, y, FilterConfig(), algorithm="srukf-ffm", samples=40)


def summarise(frame: pd.DataFrame, cfg: BatchIdentifyConfig, study_seed: int) -> dict[str, Any]:
    ok = frame[frame["status"] == "ok"]
    cols = [c for c in ("K", "T", "T1", "T2", "T3", "a11", "a12", "a21", "a22", "b11", "b21",
                        "validation_mae_psi", "validation_mse_r", "validation_mse_v") if c in ok.columns]
    stats = {}
    for c in cols:
        v = pd.to_numeric(ok[c], errors="coerce").to_numpy(float)
        v = v[np.isfinite(v)]
        stats[c] = {"n": int(v.size), "median": float(np.median(v)) if v.size else None,
                    "min": float(v.min()) if v.size else None, "max": float(v.max()) if v.size else None}
    return {"files": len(frame), "identified": len(ok), "by_format": {str(k): int(v) for k, v in
            ok["source_format"].value_counts().sort_index().items()} if "source_format" in ok else {},
            "statistics": stats, "algorithm": cfg.algorithm, "samples": cfg.samples}


KIND = StudyKind(name="batch_identify", config=BatchIdentifyConfig, cases=cases, run_case=run_case,
                 summarise=summarise, warm=warm, check=check,
                 grid=("inputs", "pattern"))
