"""Read, validate, scale and resample raw tank files (SPEC sections 2, 3, 4 and 8).

Units: everything leaving this module is canonical (SPEC section 2): time s, x0/y0 m, psi deg
(unwrapped), u/v m/s (v to starboard), r deg/s, delta deg (positive gives positive r), rpm 1/min,
model scale.  Optional columns: phi deg, p deg/s, thrust N, torque N m.
"""

from __future__ import annotations

import hashlib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import interpolate, signal

from pipeline.config import IngestConfig
from pipeline.errors import InputError
from pipeline.ingest.formats import FORMATS, KNOWN_SHIPS_LPP_FULL, PARSERS, RawTable, decode, detect_format
from pipeline.io import Run
from pipeline.runinfo import parse_test_name
from pipeline.units import froude_to_model

DEFAULT_CONFIG = IngestConfig()

# Froude kind of each canonical column (pipeline.units.FROUDE_EXPONENT).
COLUMN_KIND = {
    "time": "time", "x0": "length", "y0": "length", "psi": "angle", "u": "velocity", "v": "velocity",
    "r": "rate", "delta": "angle", "rpm": "frequency", "phi": "angle", "p": "rate",
    "thrust": "force", "torque": "moment",
}


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def read_raw(path: str | Path, fmt: str | None = None, scale: float | None = None,
             config: IngestConfig = DEFAULT_CONFIG) -> Run:
    """Read one raw tank file into a :class:`Run` at its original sampling.

    Parameters
    ----------
    path : raw file (canonical CSV, MARIN .dat or HSVA .dat; SPEC section 3).
    fmt : 'csv', 'marin' or 'hsva' to override recognition from content.
    scale : geometric scale factor of the file's values (full/model); None or 1 = model scale.
        Froude scaling brings the run to model scale (:func:`pipeline.units.froude_to_model`).
    config : limits used by the validation (SPEC section 8).

    Returns a Run in canonical units and signs, model scale, original (possibly non-uniform) time
    steps, heading unwrapped.  Raises :class:`InputError` naming the file, row (1-based line in the
    file) or column for every refused input.
    """
    path = Path(path)
    name = path.name
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError("file not found", file=name) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a tank file", file=name) from None
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", file=name) from None
    return parse_raw(data, name=name, fmt=fmt, scale=scale, config=config)


def parse_raw(data: bytes | str, *, name: str = "<text>", fmt: str | None = None, scale: float | None = None,
              config: IngestConfig = DEFAULT_CONFIG) -> Run:
    """:func:`read_raw` on the file's content (bytes or text); ``name`` is used in messages."""
    raw_bytes = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    text = decode(raw_bytes)
    lines = text.splitlines()
    if not any(s.strip() for s in lines):
        raise InputError("file is empty", file=name)
    if fmt is None:
        fmt = detect_format(lines, file=name)
    elif fmt not in FORMATS:
        raise InputError(f"unknown format {fmt!r} (choose from {', '.join(FORMATS)})", file=name)
    table = PARSERS[fmt](lines, file=name)
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise InputError(f"scale factor must be positive, got {scale}", file=name)
    scale = float(scale) if scale else 1.0
    frame = _validate(table, name, scale, config)
    meta = _base_meta(table, name, raw_bytes, scale, frame)
    _check_units(frame, table.lines, meta, name, config)
    meta.update(_run_figures(frame, config))
    return Run(frame=frame, meta=meta)


def _validate(table: RawTable, name: str, scale: float, config: IngestConfig) -> pd.DataFrame:
    """NaN/inf, time order and gaps, step rebuild, Froude scaling, heading unwrap."""
    frame = table.frame
    lines = table.lines
    for col in frame.columns:
        vals = frame[col].to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(vals))
        if bad.size:
            k = int(bad[0])
            what = "missing or NaN value" if np.isnan(vals[k]) else "infinite value"
            raise InputError(what, file=name, row=int(lines[k]), column=col)
    if len(frame) < 2:
        raise InputError(f"too few samples ({len(frame)}): a run needs at least {config.min_samples}",
                         file=name)
    t = frame["time"].to_numpy(dtype=float)
    dtt = np.diff(t)
    back = np.flatnonzero(dtt < 0)
    if back.size:
        k = int(back[0]) + 1
        raise InputError(f"time goes backwards ({t[k - 1]:g} s then {t[k]:g} s)", file=name,
                         row=int(lines[k]), column="time")
    if table.time_quantised:
        t = _rebuild_step(t, lines, name)
    else:
        rep = np.flatnonzero(dtt == 0)
        if rep.size:
            k = int(rep[0]) + 1
            raise InputError(f"time does not advance (repeated {t[k]:g} s)", file=name,
                             row=int(lines[k]), column="time")
    frame = frame.copy()
    frame["time"] = t
    for col in frame.columns:
        kind = COLUMN_KIND.get(col)
        if scale != 1.0 and kind is not None:
            frame[col] = froude_to_model(frame[col].to_numpy(dtype=float), kind, scale)
    t = frame["time"].to_numpy()
    gaps = np.diff(t)
    big = np.flatnonzero(gaps > config.max_gap)
    if big.size:
        k = int(big[0]) + 1
        raise InputError(f"gap of {gaps[k - 1]:.3g} s in time (limit {config.max_gap:g} s)", file=name,
                         row=int(lines[k]), column="time")
    frame["psi"] = np.unwrap(frame["psi"].to_numpy(dtype=float), period=360.0)
    return frame


def _rebuild_step(t: np.ndarray, lines: np.ndarray, name: str) -> np.ndarray:
    """Rebuild a uniform time base t_k = a + h k from a time column rounded to 3 significant digits.

    Each logged value pins t_k to within half a unit of its third digit.  The step h is the
    least-squares slope, snapped to 4 significant digits when that stays consistent with every
    sample (loggers run at round steps); the origin a is then the middle of the interval that all
    samples allow.  A residual beyond the rounding means a real jump or gap: refused, naming the row.
    """
    n = len(t)
    k = np.arange(n, dtype=float)
    h, a = np.polyfit(k, t, 1)
    if not h > 0:
        raise InputError("time column does not advance", file=name, column="time")
    mag = np.abs(t)
    q = np.where(mag > 0, 0.5 * 10.0 ** (np.floor(np.log10(np.where(mag > 0, mag, 1.0))) - 2), 0.0)
    q = q * (1 + 1e-9) + 1e-12
    res = t - (a + h * k)
    if np.any(np.abs(res) > q + 0.25 * h):
        j = int(np.argmax(np.abs(np.diff(res)))) + 1      # a gap or jump is a step in the residual
        raise InputError("time column is not a uniform step even allowing for its rounding "
                         f"(jump from {t[j - 1]:g} s to {t[j]:g} s)", file=name, row=int(lines[j]),
                         column="time")
    for step in (float(f"{h:.4g}"), h):
        lo = np.max(t - q - step * k)
        hi = np.min(t + q - step * k)
        if lo <= hi:
            return 0.5 * (lo + hi) + step * k
    return a + h * k


def _base_meta(table: RawTable, name: str, raw: bytes, scale: float, frame: pd.DataFrame) -> dict[str, Any]:
    meta: dict[str, Any] = {
        "run_id": Path(name).stem,
        "source_file": name,
        "source_sha256": _sha256(raw),
        "source_format": table.fmt,
        "scale_factor": scale,
    }
    meta.update(table.meta)
    meta.setdefault("test_name", "")
    meta.setdefault("provenance", "measured")
    if "lpp" not in meta and meta.get("ship", "").upper() in KNOWN_SHIPS_LPP_FULL and scale != 1.0:
        meta["lpp"] = KNOWN_SHIPS_LPP_FULL[meta["ship"].upper()] / scale
    t = frame["time"].to_numpy()
    meta["original_dt"] = float(f"{np.median(np.diff(t)):.10g}")
    test = parse_test_name(meta["test_name"])
    meta.update(test)
    if test["first_side"] is None and test["kind"] in ("zigzag", "turning"):
        meta["first_side"] = _first_side(frame["delta"].to_numpy())
        meta["first_side_from"] = "rudder"
    return meta


def _first_side(delta: np.ndarray) -> str | None:
    """Side of the first rudder execute: the first sample where |delta| reaches half its maximum."""
    d = delta
    peak = np.max(np.abs(d)) if d.size else 0.0
    if peak < 0.5:
        return None
    k = int(np.argmax(np.abs(d) >= 0.5 * peak))
    return "starboard" if d[k] > 0 else "port"


def _check_units(frame: pd.DataFrame, lines: np.ndarray, meta: dict, name: str, config: IngestConfig) -> None:
    """Values that cannot be in the units of SPEC section 2 (e.g. radians, rudder beyond its stop)."""
    delta = frame["delta"].to_numpy()
    k = int(np.argmax(np.abs(delta)))
    if abs(delta[k]) > config.max_abs_rudder:
        raise InputError(f"rudder angle {delta[k]:.4g} deg is beyond +-{config.max_abs_rudder:g} deg: "
                         "units cannot be right", file=name, row=int(lines[k]), column="delta")
    r = frame["r"].to_numpy()
    k = int(np.argmax(np.abs(r)))
    if abs(r[k]) > config.max_abs_rate:
        raise InputError(f"yaw rate {r[k]:.4g} deg/s is beyond +-{config.max_abs_rate:g} deg/s at model "
                         "scale: units (or --scale) cannot be right", file=name, row=int(lines[k]),
                         column="r")
    t = frame["time"].to_numpy()
    psi = frame["psi"].to_numpy()
    if len(t) >= 5 and np.std(r) > 0.2:
        dpsi = np.gradient(psi, t)
        slope = float(np.dot(dpsi, r) / np.dot(r, r))
        if abs(slope) < 0.1 and np.max(np.abs(psi)) < 7.0:
            raise InputError(f"heading looks like radians (d(psi)/dt is {slope:.3g} times r)", file=name,
                             column="psi")
        if abs(slope) > 10:
            raise InputError(f"yaw rate looks like rad/s (d(psi)/dt is {slope:.3g} times r)", file=name,
                             column="r")
        if slope < -0.5:
            raise InputError("yaw rate has the opposite sign of d(psi)/dt", file=name, column="r")
    rud = meta.get("rudder_deg")
    amax = float(np.max(np.abs(delta)))
    if rud and rud >= 5 and amax < 0.2 * rud and amax <= 0.7:
        raise InputError(f"rudder looks like radians (largest {amax:.3g} for a {rud:g} deg test)", file=name,
                         column="delta")


def _run_figures(frame: pd.DataFrame, config: IngestConfig) -> dict[str, Any]:
    t = frame["time"].to_numpy()
    out: dict[str, Any] = {"duration": float(t[-1] - t[0]), "samples": int(len(t))}
    if "u" in frame.columns:
        sel = t - t[0] <= config.approach_window
        out["approach_speed"] = float(np.mean(frame["u"].to_numpy()[sel]))
    else:
        out["approach_speed"] = None
    return out


def lowpass(x: np.ndarray, fs: float, cutoff: float, order: int) -> np.ndarray:
    """Zero-phase Butterworth low-pass (forwards and backwards), columns along axis 0.

    ``fs`` and ``cutoff`` in Hz.  The magnitude response is the Butterworth one squared: -6 dB at the
    corner, falling at 2 * order * 6 dB per octave above it.
    """
    sos = signal.butter(order, cutoff, btype="low", fs=fs, output="sos")
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    # remove the least-squares line first (ramps such as x0 or a turning heading then see no edge
    # transient), filter, put the line back: exact for the line, the filter acts on the rest
    k = np.arange(n, dtype=float) - (n - 1) / 2.0
    kk = k.reshape((n,) + (1,) * (x.ndim - 1))
    mean = x.mean(axis=0)
    slope = np.tensordot(k, x - mean, axes=(0, 0)) / max(np.dot(k, k), 1e-300)
    trend = mean + kk * slope
    # odd (point-mirror) extension of the detrended signal, as long as the filter memory (~2 order / cutoff)
    padlen = min(int(np.ceil(2.0 * order / cutoff * fs)), n - 1)
    return signal.sosfiltfilt(sos, x - trend, axis=0, padtype="odd", padlen=padlen) + trend


def resample(run: Run, dt: float | None = None, *, config: IngestConfig = DEFAULT_CONFIG) -> Run:
    """Bring a run to the uniform step ``dt`` (s) over its valid span, without aliasing.

    Time restarts at 0 at the first sample.  Heading is unwrapped first.  When ``dt`` is coarser than
    the original step, every column is low-passed (zero-phase Butterworth, corner at
    ``config.cutoff_ratio`` times the new Nyquist frequency 0.5/dt) on a uniform grid at the original
    step, then interpolated linearly onto the new grid; a finer or equal ``dt`` interpolates only
    (nothing is invented above the original content).  The output grid never extends past the last
    sample.  Raises :class:`InputError` if fewer than ``config.min_samples`` samples result.
    """
    dt = float(dt if dt is not None else config.dt)
    name = str(run.meta.get("source_file") or run.name)
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"resampling step must be positive, got {dt}", file=name)
    frame = run.frame
    t = frame["time"].to_numpy(dtype=float)
    if len(t) < 2:
        raise InputError(f"too few samples ({len(t)}): need at least {config.min_samples}", file=name)
    t = t - t[0]
    cols = [c for c in frame.columns if c != "time"]
    x = frame[cols].to_numpy(dtype=float).copy()
    if "psi" in cols:
        j = cols.index("psi")
        x[:, j] = np.unwrap(x[:, j], period=360.0)
    steps = np.diff(t)
    h = float(np.median(steps))
    n_new = int(np.floor(t[-1] / dt + 1e-9)) + 1
    if n_new < config.min_samples:
        raise InputError(f"too few samples: {n_new} at {dt:g} s over {t[-1]:.3g} s, need at least "
                         f"{config.min_samples}", file=name)
    t_new = np.arange(n_new) * dt
    uniform = np.max(np.abs(steps - h)) <= 1e-3 * h
    if uniform and abs(h - dt) <= 1e-6 * dt:
        y = x                                   # already on the grid: copy, do not touch
        n_new = len(t)
        t_new = np.arange(n_new) * dt
    else:
        if not uniform:                         # bring to a uniform grid at the original step first
            n_fine = int(np.floor(t[-1] / h + 1e-9)) + 1
            t_fine = np.arange(n_fine) * h
            x = np.column_stack([np.interp(t_fine, t, x[:, i]) for i in range(x.shape[1])])
        else:
            t_fine = np.arange(len(t)) * h
        cutoff = config.cutoff_ratio * 0.5 / dt
        if dt > h * (1 + 1e-9) and cutoff < 0.5 / h * 0.999 and x.shape[0] > 3:
            # band-limited now: a cubic spline interpolates it without the droop of linear interpolation
            x = lowpass(x, 1.0 / h, cutoff, config.filter_order)
            y = interpolate.make_interp_spline(t_fine, x, k=3, axis=0)(np.minimum(t_new, t_fine[-1]))
        else:
            # finer (or equal) step: linear interpolation, which adds nothing between the samples
            y = np.column_stack([np.interp(t_new, t_fine, x[:, i]) for i in range(x.shape[1])])
    out = pd.DataFrame(y, columns=cols)
    out.insert(0, "time", t_new)
    meta = dict(run.meta)
    meta["dt"] = dt
    meta.setdefault("original_dt", h)
    meta["antialias"] = (f"Butterworth order {config.filter_order} forwards-backwards, corner "
                         f"{config.cutoff_ratio * 0.5 / dt:.4g} Hz" if dt > h * (1 + 1e-9) else "none")
    meta.update(_run_figures(out, config))
    return Run(frame=out, meta=meta)


def ingest_file(path: str | Path, *, fmt: str | None = None, scale: float | None = None,
                config: IngestConfig = DEFAULT_CONFIG) -> Run:
    """Read, validate and resample a raw file to ``config.dt``: what every stage calls for a raw file."""
    return resample(read_raw(path, fmt=fmt, scale=scale, config=config), config.dt, config=config)


def with_dt(config: IngestConfig, dt: float | None) -> IngestConfig:
    """``config`` with another output step (None keeps it)."""
    return config if dt is None else replace(config, dt=float(dt))
