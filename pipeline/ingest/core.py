"""Read, validate, scale and resample raw tank files (docs/contract.md).

Units: everything leaving this module is canonical (docs/contract.md#run-data): time s, x0/y0 m, psi deg
(unwrapped), u/v m/s (v to starboard), r deg/s, delta deg (positive gives positive r), rpm 1/min,
model scale.  Optional columns: phi deg, p deg/s, thrust N, torque N m.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import interpolate, signal

from pipeline.config import KNOWN_SHIPS, IngestChecks, IngestConfig
from pipeline.errors import InputError
from pipeline.ingest import checks
from pipeline.ingest.formats import (
    ECHO_CONTENT,
    FORMATS,
    PARSERS,
    RawTable,
    decode_with_note,
    detect_format,
    unpack,
)
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


def read_raw(path: str | Path, *, fmt: str | None = None, scale: float | None = None,
             config: IngestConfig = DEFAULT_CONFIG, rudder_sign: int = 1, ship: str | None = None,
             lpp_full: float | None = None, model_scale: float | None = None,
             test_name: str | None = None, kind: str | None = None, columns=None) -> Run:
    """Read one raw tank file into a :class:`Run` at its original sampling.

    Parameters
    ----------
    path : str or Path
        Raw file (canonical CSV, MARIN .dat or HSVA .dat; docs/contract.md#raw-formats), optionally
        gzip-compressed.
    fmt : str, optional
        'csv', 'marin' or 'hsva' to override recognition from content.
    scale : float, optional
        Geometric scale factor of the file's values (full/model); None or 1 = model scale.  Froude
        scaling brings the run to model scale (:func:`pipeline.units.froude_to_model`).
    config : IngestConfig
        Limits used by the validation (docs/contract.md#bad-input; the checks' thresholds are
        ``config.checks``).
    rudder_sign : int
        +1, or -1 for files whose rudder is positive to port (beyond what the format's reader
        already converts); applied before the sign check.
    ship : str, optional
        Ship name from the dataset description, used for the scale check and recorded.
    lpp_full : float, optional
        Full-scale Lpp (m) from the dataset description (model Lpp = lpp_full / model_scale).
    model_scale : float, optional
        Full/model of the tank model (default: ``scale``); with model-scale files (scale 1) it is
        what makes a full-scale Lpp a model Lpp.
    test_name : str, optional
        Overrides the test title of the file (dataset.toml per-run override).
    kind : str, optional
        'zigzag', 'turning' or 'other' when the title says none (dataset.toml ``[runs.<id>] kind``);
        the rudder angle, heading trigger and side are then read from the rudder signal.
    columns : pipeline.ingest.columns.ColumnMap, optional
        dataset.toml ``[columns]``: the file is a logger's own table, read through that mapping
        instead of a format (docs/dataset.md).

    Returns
    -------
    Run
        Canonical units and signs (time s, psi deg, r deg/s, delta deg, u v m/s, x0 y0 m), model
        scale, the original (possibly non-uniform) time steps, heading unwrapped.

    Raises
    ------
    InputError
        Naming the file, row (1-based line in the file) or column for every refused input.

    Examples
    --------
    >>> import tempfile
    >>> from pipeline.identify.synthetic import zigzag
    >>> t, delta, _, y = zigzag(n=600, seed=1)
    >>> rows = [f"{a:.2f},{p:.4f},{r:.4f},{d:.3f}" for a, p, r, d in zip(t, y[:, 2], y[:, 1], delta)]
    >>> path = Path(tempfile.mkdtemp()) / "zz_20_s.csv"
    >>> _ = path.write_text("\\n".join(["# test: zigzag 20/20 starboard", "time,psi,r,delta", *rows]))
    >>> run = read_raw(path)
    >>> run.name, run.meta["source_format"], run.meta["first_side"]
    ('zz_20_s', 'csv', 'starboard')
    >>> read_raw(path.with_name("missing.csv"))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pipeline.errors.InputError: .../missing.csv: file not found
    """
    path = Path(path)
    name = path.name
    full = os.path.abspath(path)                 # messages name the file by its full path
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError("file not found", file=full) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a tank file", file=full) from None
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", file=full) from None
    token = ECHO_CONTENT.set(_may_quote(path))
    try:
        return parse_raw(data, name=name, fmt=fmt, scale=scale, config=config, rudder_sign=rudder_sign,
                         ship=ship, lpp_full=lpp_full, model_scale=model_scale, test_name=test_name,
                         kind=kind, columns=columns)
    except InputError as exc:
        if exc.file == name:
            exc.file = full
            exc.args = (str(exc),)
        raise
    finally:
        ECHO_CONTENT.reset(token)


def _may_quote(path: Path) -> bool:
    """Whether messages may quote the file's content: not for a symbolic link (or a path through one)
    or a file outside the working directory (pipeline.ingest.formats.ECHO_CONTENT)."""
    try:
        real = path.resolve(strict=True)
    except OSError:
        return False
    here = Path.cwd().resolve()
    return real == Path(os.path.abspath(path)) and here in real.parents


def parse_raw(data: bytes | str, *, name: str = "<text>", fmt: str | None = None, scale: float | None = None,
              config: IngestConfig = DEFAULT_CONFIG, rudder_sign: int = 1, ship: str | None = None,
              lpp_full: float | None = None, model_scale: float | None = None,
              test_name: str | None = None, kind: str | None = None, columns=None) -> Run:
    """:func:`read_raw` on the file's content (bytes or text).

    Parameters
    ----------
    data : bytes or str
        The file's content (bytes may be gzip-compressed or UTF-16).
    name : str
        The file's name, used in messages and as the run id's source.
    fmt, scale, config, rudder_sign, ship, lpp_full, model_scale, test_name, kind, columns
        As for :func:`read_raw`.

    Returns
    -------
    Run
        As :func:`read_raw` returns it.

    Raises
    ------
    InputError
        Naming ``name``, the row or column, for every refused input.

    Examples
    --------
    A canonical CSV of a 20/20 zigzag simulated from the paper's model (time s, psi deg, r deg/s,
    delta deg), read from text:

    >>> from pipeline.identify.synthetic import zigzag
    >>> t, delta, _, y = zigzag(n=600, seed=1)
    >>> rows = [f"{a:.2f},{p:.4f},{r:.4f},{d:.3f}" for a, p, r, d in zip(t, y[:, 2], y[:, 1], delta)]
    >>> text = "\\n".join(["# test: zigzag 20/20 starboard", "time,psi,r,delta", *rows])
    >>> run = parse_raw(text, name="zz.csv")
    >>> run.meta["kind"], run.meta["rudder_deg"], run.meta["heading_deg"], len(run.frame)
    ('zigzag', 20.0, 20.0, 600)
    >>> parse_raw(text.replace("delta", "rudder"), name="bad.csv")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pipeline.errors.InputError: bad.csv, row 2, column 'delta': required column is missing from the header ...
    """
    raw_bytes = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    content, notes = unpack(raw_bytes, file=name)
    text, encoding = decode_with_note(content)
    if encoding == "utf-16":
        notes.append("UTF-16 text")
    lines = text.splitlines()
    if not any(s.strip() for s in lines):
        raise InputError("file is empty", file=name)
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise InputError(f"scale factor must be a positive finite number, got {scale}", file=name)
    lo, hi = config.scale_range
    if scale is not None and not lo <= scale <= hi:
        raise InputError(f"scale factor must be full/model between {lo:g} and {hi:g}, got {scale:g}",
                         file=name)
    if model_scale is not None and not (np.isfinite(model_scale) and lo <= model_scale <= hi):
        raise InputError(f"model scale must be full/model between {lo:g} and {hi:g}, got {model_scale:g}",
                         file=name)
    if columns is not None:
        table = columns.read(lines, file=name)
    else:
        if fmt is None:
            fmt = detect_format(lines, file=name)
        elif fmt not in FORMATS:
            raise InputError(f"unknown format {fmt!r} (choose from {', '.join(FORMATS)})", file=name)
        table = PARSERS[fmt](lines, file=name)
    if rudder_sign not in (1, -1):
        raise InputError(f"rudder sign must be 1 or -1, got {rudder_sign}", file=name)
    scale = float(scale) if scale else 1.0
    if rudder_sign == -1:
        table.frame["delta"] = -table.frame["delta"]
        notes.append("rudder sign reversed (--rudder-sign -1)")
    if test_name is not None:
        table.meta["test_name"] = test_name
    frame = _validate(table, name, scale, config)
    start, trim_note = checks.steady_start(frame, name, config)
    if start:
        frame = frame.iloc[start:].reset_index(drop=True)
        table.lines = table.lines[start:]
        table.frame = table.frame.iloc[start:].reset_index(drop=True)
        notes.append(trim_note)
    meta = _base_meta(table, name, raw_bytes, scale, frame, kind, limits=config.checks)
    if ship:
        meta["ship"] = ship
    if model_scale:
        meta["model_scale"] = float(model_scale)
    lpp_model, lpp_source = _model_lpp(meta, scale, lpp_full, model_scale)
    if lpp_model is not None:
        meta["lpp"] = lpp_model
        meta["lpp_source"] = lpp_source
    if lpp_full is not None:
        meta["lpp_full"] = float(lpp_full)
    meta["rudder_sign"] = rudder_sign
    t = frame["time"].to_numpy()
    n_grid = int(np.floor((t[-1] - t[0]) / config.dt + 1e-9)) + 1
    if n_grid < config.min_samples:
        raise InputError(f"too few samples: {n_grid} at {config.dt:g} s over {t[-1] - t[0]:.3g} s, need at "
                         f"least {config.min_samples}", file=name)
    meta.update(checks.check_scale(meta, frame, name, scale, lpp_model, lpp_source, checks=config.checks))
    checks.check_spikes(frame, table.lines, name, table.frame, digits=table.digits, checks=config.checks)
    checks.check_units(frame, table.lines, meta, name, config, meta.get("declared_units"))
    meta.update(checks.check_rudder_sign(frame, name, checks=config.checks))
    if notes:
        meta["ingest_notes"] = notes + list(meta.get("ingest_notes", []))
    meta.update(_run_figures(frame, config))
    return Run(frame=frame, meta=meta)


def _model_lpp(meta: dict, scale: float, lpp_full: float | None,
               model_scale: float | None = None) -> tuple[float | None, str | None]:
    """Model Lpp (m) and where it came from: the dataset's full-scale Lpp over the model scale, the
    file's own Lpp (at the file's scale), or a known ship's full-scale Lpp over the scale."""
    if lpp_full:
        ms = model_scale or scale
        return float(lpp_full) / ms, f"dataset Lpp {lpp_full:g} m / model scale {ms:g}"
    if meta.get("lpp"):
        return float(meta["lpp"]), meta.get("lpp_source", "the file's header")
    ship = str(meta.get("ship", "")).upper()
    if ship in KNOWN_SHIPS.lpp_full_m:
        full = KNOWN_SHIPS.lpp_full_m[ship]
        ms = model_scale or scale   # model-scale files (scale 1) of a known ship: its model scale
        return full / ms, f"{ship} Lpp {full:g} m / {'model ' if model_scale else ''}scale {ms:g}"
    return None, None


def _validate(table: RawTable, name: str, scale: float, config: IngestConfig) -> pd.DataFrame:
    """NaN/inf, time order and gaps, step rebuild, Froude scaling, heading unwrap."""
    frame = table.frame
    lines = table.lines
    if len(frame) >= 3:
        step = float(np.median(np.diff(frame["time"].to_numpy(dtype=float))))
        declared_time = "time" in table.meta.get("declared_units", {})
        if step > config.max_gap * max(scale, 1.0) ** 0.5 and not declared_time:
            raise InputError(f"time step {step:g} is longer than the gap limit ({config.max_gap:g} s at "
                             "model scale) at almost every sample: time is probably not in seconds "
                             "(declare it in the header, e.g. 'time [ms]')", file=name, column="time")
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
        t = _rebuild_step(t, lines, name, limits=config.checks)
    else:
        rep = np.flatnonzero(dtt == 0)
        if rep.size:
            k = int(rep[0]) + 1
            raise InputError(f"time does not advance (repeated {t[k]:g} s)", file=name,
                             row=int(lines[k]), column="time")
    frame = frame.copy()
    frame["time"] = t
    kinds = {**table.meta.get("column_kinds", {}), **COLUMN_KIND}
    for col in frame.columns:
        kind = kinds.get(col)
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


def _rebuild_step(t: np.ndarray, lines: np.ndarray, name: str, *, limits: IngestChecks) -> np.ndarray:
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
    if np.any(np.abs(res) > q + limits.time_jitter_share * h):
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


def gap_note(t: np.ndarray, *, limits: IngestChecks = DEFAULT_CONFIG.checks) -> str | None:
    """A note on samples missing from a time base ``t`` (s), which the resampling bridges by
    interpolation (a gap beyond ``IngestConfig.max_gap`` is refused before this); None when none are.

    A step is a gap when it is longer than 1.5 local logging steps (the larger of the median steps
    of the ``limits.gap_window`` steps before and after it: a logger changing its rate is not missing
    samples) and the time base after it is shifted by more than half a step against the one before
    it: the stamps of ``limits.gap_window`` samples each side are fitted with one step and an offset that
    changes between them; a dropped sample moves every later stamp by a step, a jittered stamp only
    itself.  Within ``limits.gap_edge`` samples of either end the offset cannot be measured: there a
    step counts as a gap only beyond 1.9 local steps (a stamp jittered by less than 0.45 of a step on
    either side of it cannot make one).

    Parameters
    ----------
    t : numpy.ndarray
        The time stamps, s, increasing.
    limits : IngestChecks
        ``gap_window`` and ``gap_edge`` (pipeline/config.py says why).

    Returns
    -------
    str or None
        One sentence: how many gaps, the longest (s) and where (s); None when no sample is missing.

    Examples
    --------
    >>> t = np.arange(60) * 0.1
    >>> gap_note(t) is None
    True
    >>> gap_note(np.delete(t, 30))
    '1 gap in time (samples missing), the longest 0.2 s after 2.9 s; interpolated over by the resampling'
    """
    steps = np.diff(t)
    if steps.size < 2:
        return None
    w = limits.gap_window
    holes, longest = [], -1
    for k in np.flatnonzero(steps > limits.gap_step_factor * np.median(steps)):
        prev, nxt = steps[max(0, k - w):k], steps[k + 1:k + 1 + w]
        h = max(float(np.median(prev)) if prev.size else 0.0, float(np.median(nxt)) if nxt.size else 0.0)
        if h <= 0 or steps[k] <= limits.gap_step_factor * h:
            continue
        j0, j1 = np.arange(max(0, k - w + 1), k + 1), np.arange(k + 1, min(len(t), k + 1 + w))
        if min(j0.size, j1.size) < limits.gap_edge:
            if steps[k] <= limits.gap_unmeasured_factor * h:
                continue
        else:
            j = np.concatenate([j0, j1]).astype(float)
            design = np.column_stack([np.ones_like(j), j - k, (j > k).astype(float)])
            shift = float(np.linalg.lstsq(design, t[j.astype(int)], rcond=None)[0][2])
            if shift <= 0.5 * h:
                continue
        holes.append(k)
        if longest < 0 or steps[k] > steps[longest]:
            longest = int(k)
    if not holes:
        return None
    k = longest
    return (f"{len(holes)} gap{'s' if len(holes) > 1 else ''} in time (samples missing), the longest "
            f"{steps[k]:.3g} s after {t[k] - t[0]:.4g} s; interpolated over by the resampling")


def _base_meta(table: RawTable, name: str, raw: bytes, scale: float, frame: pd.DataFrame,
               kind: str | None = None, *, limits: IngestChecks = DEFAULT_CONFIG.checks) -> dict[str, Any]:
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
    if meta.get("lpp") and table.fmt == "csv":
        meta["lpp"] = float(meta["lpp"]) / scale          # the header's Lpp is at the file's scale
        meta["lpp_source"] = "the file's header"
    t = frame["time"].to_numpy()
    meta["original_dt"] = float(f"{np.median(np.diff(t)):.10g}")
    note = gap_note(t, limits=limits)
    if note:
        meta.setdefault("ingest_notes", []).append(note)
    test = parse_test_name(meta["test_name"])
    meta.update(test)
    t, psi, delta = (frame[c].to_numpy(dtype=float) for c in ("time", "psi", "delta"))
    if kind is not None and test["kind"] == "other":
        # the description says what the test is; its angles and side come from the rudder signal
        guess = checks.infer_test_from_rudder(t, delta, psi, checks=limits)
        meta.update(kind=kind, rudder_deg=guess["rudder_deg"] if kind != "other" else None,
                    heading_deg=guess["heading_deg"] if kind == "zigzag" else None,
                    first_side=guess["first_side"] if kind != "other" else None,
                    test_from="dataset.toml [runs] kind", first_side_from="rudder")
    elif test["kind"] == "other":
        guess = checks.infer_test_from_rudder(t, delta, psi, checks=limits)
        if guess["kind"] != "other":
            meta.update(guess)
            meta["test_from"] = "rudder signal"
            meta["first_side_from"] = "rudder"
            why = f" (title {meta['test_name']!r} not understood)" if meta["test_name"] else " (no title)"
            note = f"test read from the rudder signal: {guess['kind']} {guess['rudder_deg']:g} deg{why}"
            meta.setdefault("ingest_notes", []).append(note)
    elif test["kind"] == "turning" and test["rudder_deg"] is None:
        guess = checks.infer_test_from_rudder(t, delta, psi, checks=limits)
        meta["rudder_deg"] = guess["rudder_deg"]
        meta["rudder_from"] = "rudder signal"
    if meta.get("first_side") is None and meta["kind"] in ("zigzag", "turning"):
        meta["first_side"] = _first_side(delta)
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

    The magnitude response is the Butterworth one squared: -6 dB at the corner, falling at
    2 * order * 6 dB per octave above it.

    Parameters
    ----------
    x : numpy.ndarray
        Samples at the uniform rate ``fs``, one column per signal (axis 0 is time).
    fs : float
        Sampling rate, Hz.
    cutoff : float
        Corner frequency, Hz (below fs / 2).
    order : int
        Butterworth order of one pass.

    Returns
    -------
    numpy.ndarray
        The filtered samples, same shape and units as ``x``.

    Examples
    --------
    A constant passes unchanged; a tone at the Nyquist frequency is removed:

    >>> x = np.column_stack([np.ones(200), np.cos(np.pi * np.arange(200))])
    >>> y = lowpass(x, 12.5, 2.5, 8)
    >>> bool(np.max(np.abs(y[:, 0] - 1.0)) < 1e-9), bool(np.max(np.abs(y[50:150, 1])) < 1e-4)
    (True, True)
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
    sample.

    Parameters
    ----------
    run : Run
        A run as :func:`read_raw` returns it (time s, heading deg).
    dt : float, optional
        The new step, s (default ``config.dt``, 0.08 s).
    config : IngestConfig
        Filter order, corner ratio and the fewest samples a run may have.

    Returns
    -------
    Run
        The same columns on the grid 0, dt, 2 dt, ...; ``meta["dt"]`` the step and ``meta["antialias"]``
        the filter used.

    Raises
    ------
    InputError
        When fewer than ``config.min_samples`` samples result or ``dt`` is not positive.

    Examples
    --------
    >>> from pipeline.identify.synthetic import zigzag_run
    >>> run = resample(zigzag_run("zz", n=600), 0.16)       # 0.08 s to 0.16 s, anti-aliased
    >>> len(run.frame), run.meta["dt"], run.meta["antialias"]
    (300, 0.16, 'Butterworth order 8 forwards-backwards, corner 2.5 Hz')
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
                config: IngestConfig = DEFAULT_CONFIG, **kwargs) -> Run:
    """Read, validate and resample a raw file to ``config.dt``: what every stage calls for a raw file.

    Parameters
    ----------
    path : str or Path
        The raw file (docs/contract.md#raw-formats).
    fmt, scale, config
        As for :func:`read_raw`.
    **kwargs
        rudder_sign, ship, lpp_full, model_scale, test_name, kind, columns (see :func:`read_raw`).

    Returns
    -------
    Run
        :func:`resample` of :func:`read_raw`: canonical units, model scale, step ``config.dt`` (s).

    Examples
    --------
    A logger's CSV of a zigzag simulated from the paper's model, its test named by the caller:

    >>> import tempfile
    >>> from pipeline.identify.synthetic import zigzag_run
    >>> path = Path(tempfile.mkdtemp()) / "zz_20_s.csv"
    >>> zigzag_run("zz", n=600).frame[["time", "psi", "r", "delta"]].to_csv(path, index=False)
    >>> run = ingest_file(path, test_name="zigzag 20/20 starboard")
    >>> run.meta["dt"], len(run.frame), run.meta["kind"], run.meta["rudder_deg"]
    (0.08, 600, 'zigzag', 20.0)
    """
    return resample(read_raw(path, fmt=fmt, scale=scale, config=config, **kwargs), config.dt, config=config)


def with_dt(config: IngestConfig, dt: float | None) -> IngestConfig:
    """``config`` with another output step.

    Parameters
    ----------
    config : IngestConfig
        The settings.
    dt : float, optional
        The new step, s; None keeps ``config.dt``.

    Returns
    -------
    IngestConfig
        ``config`` with ``dt`` replaced.

    Examples
    --------
    >>> with_dt(IngestConfig(), 0.1).dt, with_dt(IngestConfig(), None).dt
    (0.1, 0.08)
    """
    return config if dt is None else replace(config, dt=float(dt))
