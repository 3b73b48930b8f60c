"""The three raw formats of SPEC section 3: recognise them from content and parse them.

Each parser takes the decoded text and returns a :class:`RawTable`: the numeric columns in
**canonical names, units and signs but still at the scale of the file** (Froude scaling to model
scale is done once, for every format, by :func:`pipeline.ingest.core.read_raw`), the 1-based line
number in the file of every data row (so that errors can name the row), and what the header says.

Canonical CSV
    Leading ``#`` lines (``key: value`` pairs, or free text), a header row naming at least
    ``time, psi, r, delta``, comma-separated values in the units and signs of SPEC section 2.

MARIN SIMMAN free-running ``.dat``
    3 header lines (institute; test name; blank), then tab-separated E-format numbers with 3
    significant digits, 11 columns ``time x0 y0 phi psi dx0 dy0 p r delta rev``
    (s, m, m, deg, deg, m/s, m/s, deg/s, deg/s, deg, rpm).  The time column repeats values because
    of its 3-digit rounding: the step is rebuilt by a least-squares line through the sample index
    (the residual must stay within the rounding, otherwise the file has a real jump or gap).
    ``dx0, dy0`` are earth-fixed: body u, v follow by rotating with psi
    (:func:`pipeline.units.body_velocities`).  A positive rudder angle turns the ship to port in
    these files: ``delta = -rudder``.  Empty trailing rows are dropped.

HSVA CPMC ``.dat`` (the measured KVLCC2 zigzags)
    4 header lines (institute; ship; test such as ``Z20°/10° starting to port``, Latin-1; a title),
    then 12 whitespace-separated columns at 0.05 s.  What each column is, established from the
    data of all 13 runs (figures in tests/test_ingest_hsva.py and the ingest report):

    ==  =====================================================================================
    1   time, s
    2   x0, m, earth-fixed position
    3   y0, m (psi is measured from x0 toward y0; the course atan2(dy0, dx0) follows psi)
    4   psi, heading, deg, positive to starboard
    5   **dx0/dt, m/s, earth-fixed velocity** (not body u): it equals the time derivative of
        column 2 (least-squares slope 0.996-1.000, residual 0.0004-0.0009 m/s in every run), and it
        departs from the body surge speed as soon as psi departs from 0.  At the start (psi = 0)
        it equals u, which is why it first looked like u.
    6   **dy0/dt, m/s, earth-fixed velocity**: slope 1.0000-1.0002 against the derivative of
        column 3, residual 0.0002-0.0003 m/s against a signal of standard deviation 0.05-0.29 m/s,
        no time lag.  (Hence the apparent fit v_kin ~ -0.23 c6 - 3.45 m r: c6 ~ U sin(psi).)
        Body velocities: ``u, v = body_velocities(c5, c6, psi)``, the velocities of the point whose
        position columns 2-3 give.  That point is taken as the CG/midship: the resulting sway is
        v ~ -(2.1 ... 3.7 m) r, i.e. a pivot point 0.30-0.52 Lpp ahead of it, as expected for this
        full-form ship (linear MMG derivatives of KVLCC2 give about 0.43 Lpp for a steady turn).
        Had the positions been taken near the aft perpendicular (3.5 m aft), the sway at midship
        would be ~0, i.e. no drift angle in a turn, which is impossible.  No lever-arm correction.
    7   r, yaw rate, deg/s (= d(psi)/dt)
    8   **phi, roll angle, deg, positive starboard down**.  Evidence: it oscillates at 0.37 Hz
        (period 2.69 s model scale = 18.2 s full scale, the roll natural period of a loaded VLCC);
        it holds a steady value through each turn (a rate could not: its integral would reach
        1.5-4.7 deg and keep drifting); and it regresses as phi = -0.07...-0.11 (u r) +
        0.007...0.011 delta (u m/s, r deg/s, canonical delta deg): outward heel in a steady turn
        plus the inward heel of the rudder force at helm, exactly the physics of heel in a turn.
        Kept as the optional column ``phi`` (deg).
    9   rudder angle, deg, positive turns the ship to port: ``delta = -c9``
    10  propeller speed, rev/s: ``rpm = 60 c10``
    11  thrust (as logged, N)
    12  torque (as logged, N m)
    ==  =====================================================================================
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pipeline.errors import InputError
from pipeline.units import body_velocities

FORMATS = ("csv", "marin", "hsva")

MARIN_COLUMNS = ("time", "x0", "y0", "phi", "psi", "dx0", "dy0", "p", "r", "delta", "rev")
HSVA_COLUMNS = ("time", "x0", "y0", "psi", "dx0", "dy0", "r", "phi", "rudder", "revs", "thrust", "torque")
CSV_REQUIRED = ("time", "psi", "r", "delta")

# Full-scale Lpp (m) of ships whose files do not say it; the model Lpp is this over the scale.
KNOWN_SHIPS_LPP_FULL = {"KVLCC2": 320.0, "KCS": 230.0}

_KEY_VALUE = re.compile(r"^#\s*([A-Za-z_][\w .-]*?)\s*:\s*(.*?)\s*$")
_NUMBER = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?$")


@dataclass
class RawTable:
    """Parsed content of a raw file: canonical columns at file scale, line numbers, header."""

    fmt: str
    frame: pd.DataFrame
    lines: np.ndarray                      # 1-based line number in the file of each row
    meta: dict[str, Any] = field(default_factory=dict)
    time_quantised: bool = False           # True: time repeats by rounding, rebuild the step


def decode(data: bytes) -> str:
    """Bytes to text: UTF-8 (with or without BOM), else Latin-1 (HSVA headers)."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def _is_number(tok: str) -> bool:
    return bool(_NUMBER.match(tok))


def _first_numeric_line(lines: list[str], limit: int = 20) -> int | None:
    for i, line in enumerate(lines[:limit]):
        toks = line.split()
        if len(toks) >= 2 and all(_is_number(t) for t in toks):
            return i
    return None


def detect_format(lines: list[str], file: str | Path | None = None) -> str:
    """Recognise the format from the content: 'csv', 'marin' or 'hsva'."""
    i = 0
    while i < len(lines) and (not lines[i].strip() or lines[i].lstrip().startswith("#")):
        i += 1
    if i < len(lines) and "," in lines[i]:
        names = [_clean_name(n) for n in lines[i].split(",")]
        if "time" in names:
            return "csv"
    head = " ".join(lines[:3]).upper()
    j = _first_numeric_line(lines)
    if j is not None:
        ntok = len(lines[j].split())
        if ntok == 12 and (j >= 3 or "HSVA" in head or "CPMC" in head):
            return "hsva"
        if ntok == 11:
            return "marin"
    raise InputError("unknown format: not a canonical CSV (header with time, psi, r, delta), "
                     "a MARIN .dat (11 columns) or an HSVA .dat (12 columns)", file=file)


def _clean_name(name: str) -> str:
    """'Time [s]' -> 'time'."""
    return re.sub(r"[\[(].*$", "", name).strip().strip('"').strip("'").strip().lower()


def _numeric_block(rows: list[str], linenos: np.ndarray, names: tuple[str, ...], sep: str,
                   file) -> pd.DataFrame:
    """Parse data rows into floats, naming the row and column of the first bad value."""
    n = len(names)
    if sep == ",":
        counts = np.fromiter((r.count(",") + 1 for r in rows), dtype=np.int64, count=len(rows))
    else:
        counts = np.fromiter((len(r.split()) for r in rows), dtype=np.int64, count=len(rows))
    bad = np.flatnonzero(counts != n)
    if bad.size:
        k = int(bad[0])
        raise InputError(f"expected {n} values, found {int(counts[k])}", file=file, row=int(linenos[k]))
    text = "\n".join(r.strip() for r in rows)
    try:
        df = pd.read_csv(io.StringIO(text), header=None, names=list(names),
                         sep="," if sep == "," else r"\s+", engine="c", quoting=csv.QUOTE_NONE,
                         skip_blank_lines=False, low_memory=False, keep_default_na=False,
                         na_values=[""])
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError, OverflowError) as exc:
        raise InputError(f"could not read the data rows ({str(exc).splitlines()[0]})", file=file) from None
    if len(df) != len(rows):
        raise InputError(f"could not read the data rows ({len(df)} parsed of {len(rows)})", file=file)
    out = {}
    for name in names:
        col = df[name]
        if col.dtype.kind in "fi":
            out[name] = col.to_numpy(dtype=float)
            continue
        as_text = col.astype(str).str.strip()
        num = np.full(len(as_text), np.nan)
        for k, tok in enumerate(as_text):
            if tok in ("", "nan", "NaN", "None", "<NA>"):
                continue
            if not _is_number(tok) and tok.lower() not in ("inf", "+inf", "-inf", "infinity", "-infinity"):
                raise InputError(f"value {tok[:20]!r} is not a number", file=file, row=int(linenos[k]),
                                 column=name)
            num[k] = float(tok.replace("d", "e").replace("D", "e"))
        out[name] = num
    return pd.DataFrame(out)


def _data_rows(lines: list[str], start: int) -> tuple[list[str], np.ndarray]:
    """Non-empty lines from ``start`` on (empty rows, e.g. trailing ones, are skipped)."""
    rows, nums = [], []
    for i in range(start, len(lines)):
        s = lines[i]
        if s.strip():
            rows.append(s)
            nums.append(i + 1)
    return rows, np.asarray(nums, dtype=np.int64)


def parse_csv(lines: list[str], file=None) -> RawTable:
    """Canonical CSV (SPEC section 3)."""
    meta: dict[str, Any] = {}
    header: dict[str, str] = {}
    comments: list[str] = []
    i = 0
    while i < len(lines) and (not lines[i].strip() or lines[i].lstrip().startswith("#")):
        s = lines[i].strip()
        if s:
            m = _KEY_VALUE.match(s)
            if m:
                header[m[1].strip().lower()] = m[2]
            else:
                comments.append(s.lstrip("#").strip())
        i += 1
    if i >= len(lines):
        raise InputError("no header row (time, psi, r, delta, ...) found", file=file)
    names = [_clean_name(n) for n in lines[i].split(",")]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError("column named twice in the header", file=file, row=i + 1, column=dup)
    if any(not n for n in names):
        raise InputError("empty column name in the header", file=file, row=i + 1)
    for c in CSV_REQUIRED:
        if c not in names:
            raise InputError("required column is missing from the header", file=file, row=i + 1, column=c)
    rows, linenos = _data_rows(lines, i + 1)
    if not rows:
        raise InputError("no data rows", file=file)
    frame = _numeric_block(rows, linenos, tuple(names), ",", file)
    prov = header.get("provenance", "").strip().lower()
    meta["provenance"] = "virtual" if "virtual" in prov else "measured"
    meta["test_name"] = header.get("test", header.get("test_name", "")).strip()
    if header.get("ship"):
        meta["ship"] = header["ship"].strip()
    for key, dest in (("lpp", "lpp"), ("scale", "model_scale"), ("dt", "logged_dt"), ("seed", "seed")):
        if key in header:
            try:
                val = float(header[key])
            except ValueError:
                raise InputError(f"header value {key!r} is not a number: {header[key][:20]!r}",
                                 file=file) from None
            meta[dest] = int(val) if key == "seed" and val.is_integer() else val
    if header:
        meta["header"] = header
    if comments:
        meta["comments"] = comments
    return RawTable("csv", frame, linenos, meta)


def parse_marin(lines: list[str], file=None) -> RawTable:
    """MARIN SIMMAN free-running .dat: rudder sign flipped, u, v from dx0, dy0 and psi."""
    j = _first_numeric_line(lines)
    if j is None:
        raise InputError("no numeric data rows found (MARIN .dat)", file=file)
    rows, linenos = _data_rows(lines, j)
    raw = _numeric_block(rows, linenos, MARIN_COLUMNS, "ws", file)
    head = [s.strip() for s in lines[:j]]
    test = head[1] if len(head) > 1 else (head[0] if head else "")
    meta: dict[str, Any] = {"provenance": "measured", "test_name": test}
    if head:
        meta["institute"] = head[0]
    m = re.search(r"\bfor\s+([A-Za-z0-9-]+)", test)
    if m:
        meta["ship"] = m[1].upper()
    u, v = body_velocities(raw["dx0"].to_numpy(), raw["dy0"].to_numpy(), raw["psi"].to_numpy())
    frame = pd.DataFrame({
        "time": raw["time"], "x0": raw["x0"], "y0": raw["y0"], "psi": raw["psi"], "u": u, "v": v,
        "r": raw["r"], "delta": -raw["delta"], "rpm": raw["rev"], "phi": raw["phi"], "p": raw["p"],
    })
    return RawTable("marin", frame, linenos, meta, time_quantised=True)


def parse_hsva(lines: list[str], file=None) -> RawTable:
    """HSVA CPMC .dat (column meanings in this module's docstring)."""
    j = _first_numeric_line(lines)
    if j is None:
        raise InputError("no numeric data rows found (HSVA .dat)", file=file)
    rows, linenos = _data_rows(lines, j)
    raw = _numeric_block(rows, linenos, HSVA_COLUMNS, "ws", file)
    head = [s.strip() for s in lines[:j]]
    meta: dict[str, Any] = {"provenance": "measured", "test_name": head[2] if len(head) > 2 else ""}
    if head:
        meta["institute"] = head[0]
    if len(head) > 1 and head[1]:
        meta["ship"] = head[1].split()[0].upper()
    if len(head) > 3:
        meta["title"] = head[3]
    u, v = body_velocities(raw["dx0"].to_numpy(), raw["dy0"].to_numpy(), raw["psi"].to_numpy())
    frame = pd.DataFrame({
        "time": raw["time"], "x0": raw["x0"], "y0": raw["y0"], "psi": raw["psi"], "u": u, "v": v,
        "r": raw["r"], "delta": -raw["rudder"], "rpm": 60.0 * raw["revs"], "phi": raw["phi"],
        "thrust": raw["thrust"], "torque": raw["torque"],
    })
    if meta.get("ship") == "KVLCC2":
        meta["lpp"] = 7.0           # HSVA model, scale 1:45.7 (shared/data/kvlcc2_hsva/README.md)
        meta["model_scale"] = 45.7
    return RawTable("hsva", frame, linenos, meta)


PARSERS = {"csv": parse_csv, "marin": parse_marin, "hsva": parse_hsva}
