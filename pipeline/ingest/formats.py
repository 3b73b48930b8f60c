"""The three raw formats of docs/contract.md#raw-formats: recognise them from content and parse them.

Each parser takes the decoded text and returns a :class:`RawTable`: the numeric columns in
**canonical names, units and signs but still at the scale of the file** (Froude scaling to model
scale is done once, for every format, by :func:`pipeline.ingest.core.read_raw`), the 1-based line
number in the file of every data row (so that errors can name the row), and what the header says.

Canonical CSV
    Leading ``#`` lines (``key: value`` pairs, or free text), a header row naming at least
    ``time, psi, r, delta``, comma-separated values in the units and signs of docs/contract.md#run-data.

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

import contextvars
import csv
import io
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pipeline.config import KNOWN_SHIPS, IngestConfig
from pipeline.errors import InputError
from pipeline.units import KNOT, body_velocities

FORMATS = ("csv", "marin", "hsva")

MARIN_COLUMNS = ("time", "x0", "y0", "phi", "psi", "dx0", "dy0", "p", "r", "delta", "rev")
HSVA_COLUMNS = ("time", "x0", "y0", "psi", "dx0", "dy0", "r", "phi", "rudder", "revs", "thrust", "torque")
CSV_REQUIRED = ("time", "psi", "r", "delta")

_KEY_VALUE = re.compile(r"^#\s*([A-Za-z_][\w .-]*?)\s*:\s*(.*?)\s*$")
_NUMBER = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?$")


@dataclass
class RawTable:
    """Parsed content of a raw file: canonical columns at file scale, line numbers, header."""

    fmt: str
    frame: pd.DataFrame
    lines: np.ndarray                      # 1-based line number in the file of each row
    meta: dict[str, Any] = field(default_factory=dict)
    digits: int | None = None              # significant digits every value is written with (None: full)

    @property
    def time_quantised(self) -> bool:
        """True when the time column repeats by rounding (few digits): the step is rebuilt."""
        return self.digits is not None


# Whether refusals and notes may quote the file's content.  Off for a file reached through a symbolic
# link or outside the working directory (pipeline.ingest.core.read_raw): a dataset.toml's files_dir
# or a link could otherwise make a message (in a log, a report) show another file's text.  A context
# variable, set by read_raw alone around one parse and reset after it (per thread and task, so
# concurrent reads do not see each other's): it changes only the words of a refusal, never a value
# read, and passing it explicitly would add a parameter to every format's parser (the PARSERS
# registry's signature), to format recognition, the header reader, the column map and the number
# parser, for a message's wording.
ECHO_CONTENT: contextvars.ContextVar[bool] = contextvars.ContextVar("echo_content", default=True)


def shown(text: str, limit: int, before: str = "", after: str = "") -> str:
    """``before + repr(text[:limit]) + after`` when messages may quote the file, else ''."""
    return f"{before}{text[:limit]!r}{after}" if ECHO_CONTENT.get() else ""


GZIP_MAGIC = b"\x1f\x8b"
MAX_DECOMPRESSED = IngestConfig().max_decompressed_bytes   # bytes (pipeline/config.py says why)


def unpack(data: bytes, file=None) -> tuple[bytes, list[str]]:
    """Undo a gzip wrapper (recognised by its magic bytes); returns (bytes, notes).

    Other archive types are refused by name (zip, 7z, xz, bzip2) rather than as an unknown format.
    """
    notes: list[str] = []
    if data[:2] == GZIP_MAGIC:
        import gzip
        import zlib

        try:
            with gzip.GzipFile(fileobj=io.BytesIO(data)) as fh:
                out = fh.read(MAX_DECOMPRESSED + 1)
        except (OSError, EOFError, zlib.error) as exc:
            raise InputError(f"gzip file cannot be decompressed ({exc})", file=file) from None
        if len(out) > MAX_DECOMPRESSED:
            raise InputError(f"gzip file expands beyond {MAX_DECOMPRESSED >> 20} MB", file=file)
        notes.append("gzip-compressed file, decompressed")
        return out, notes
    for magic, kind in ((b"PK\x03\x04", "zip"), (b"7z\xbc\xaf", "7z"), (b"\xfd7zXZ", "xz"),
                        (b"BZh", "bzip2")):
        if data.startswith(magic):
            raise InputError(f"{kind} archive: extract the tank file first (gzip is read directly)",
                             file=file)
    return data, notes


def decode(data: bytes) -> str:
    """Bytes to text: UTF-16 (by its byte-order mark, or by the zero bytes of ASCII text in UTF-16
    without one), UTF-8 (with or without BOM), else Latin-1 (HSVA headers)."""
    text, _ = decode_with_note(data)
    return text


def decode_with_note(data: bytes) -> tuple[str, str]:
    """:func:`decode` and the encoding used ('utf-16', 'utf-8', 'latin-1')."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        return data.decode("utf-16"), "utf-16"
    head = data[:4000]
    if len(head) >= 8 and head.count(0) >= 0.3 * len(head):
        even, odd = head[0::2].count(0), head[1::2].count(0)
        enc = "utf-16-le" if odd > 3 * max(even, 1) else "utf-16-be" if even > 3 * max(odd, 1) else None
        if enc:
            try:
                return data.decode(enc), "utf-16"
            except UnicodeDecodeError:
                pass
    try:
        return data.decode("utf-8-sig"), "utf-8"
    except UnicodeDecodeError:
        return data.decode("latin-1"), "latin-1"


def _is_number(tok: str) -> bool:
    return bool(_NUMBER.match(tok))


def _first_numeric_line(lines: list[str], limit: int = 20) -> int | None:
    for i, line in enumerate(lines[:limit]):
        toks = line.split()
        if len(toks) >= 2 and all(_is_number(t) for t in toks):
            return i
    return None


DELIMITERS = {",": "comma", ";": "semicolon", "\t": "tab", " ": "whitespace"}


def table_header(lines: list[str]) -> tuple[int, str] | None:
    """(index, delimiter) of a delimited header row naming a ``time`` column, else None.

    The header is the first line that is neither blank nor a ``#`` comment.  Delimiters tried:
    comma, semicolon, tab, then runs of whitespace; the first that splits the line into at least two
    names, one of them ``time``, wins.
    """
    i = 0
    while i < len(lines) and (not lines[i].strip() or lines[i].lstrip().startswith("#")):
        i += 1
    if i >= len(lines):
        return None
    line = lines[i]
    for delim in (",", ";", "\t", " "):
        parts = line.split() if delim == " " else line.split(delim)
        if len(parts) < 2:
            continue
        names = [split_name(n)[0] for n in parts]
        if "time" in names:
            return i, delim
    return None


def detect_format(lines: list[str], file: str | Path | None = None) -> str:
    """Recognise the format from the content: 'csv', 'marin' or 'hsva'.

    A delimited table whose header names a ``time`` column is read as canonical CSV, whatever the
    delimiter (comma, semicolon, tab, whitespace): :func:`parse_csv` says what is missing.

    Parameters
    ----------
    lines : list of str
        The file's text, line by line (decoded).
    file : str or Path, optional
        The file's name, for messages.

    Returns
    -------
    str
        'csv', 'marin' or 'hsva' (docs/contract.md#raw-formats).

    Raises
    ------
    InputError
        Naming the file when the content is none of the formats.

    Examples
    --------
    >>> detect_format(["# test: zigzag 20/20 starboard", "time,psi,r,delta", "0,0,0,0"])
    'csv'
    """
    if table_header(lines) is not None:
        return "csv"
    head = " ".join(lines[:3]).upper()
    j = _first_numeric_line(lines)
    if j is not None:
        ntok = len(lines[j].split())
        # a header naming its institute decides the format; the column count must then agree
        said = "hsva" if ("HSVA" in head or "CPMC" in head) else "marin" if "MARIN" in head else None
        counts = {"hsva": len(HSVA_COLUMNS), "marin": len(MARIN_COLUMNS)}
        if said is not None and ntok != counts[said]:
            raise InputError(f"the header says {said.upper()} .dat, whose rows have {counts[said]} columns, "
                             f"but row {j + 1} has {ntok}: not a {said.upper()} file of the layout the "
                             "reader knows (docs/dataset.md); give --format to read it as another", file=file)
        if said is not None:
            return said
        if ntok == 12 and j >= 3:
            return "hsva"
        if ntok == 11:
            return "marin"
        raise InputError(f"unknown format: numeric rows of {ntok} columns without a header row naming "
                         "them (a MARIN .dat has 11 columns, an HSVA .dat 12; a table needs a header "
                         "row naming time, psi, r, delta)", file=file)
    first = next((ln for ln in lines if ln.strip() and not ln.lstrip().startswith("#")), "")
    raise InputError("unknown format: no header row naming a 'time' column and no numeric rows "
                     f"{shown(first.strip(), 40, ' (first line ', ')')}", file=file)


# Units a header may declare, per canonical column kind: unit -> factor to the canonical unit.
_ANGLE = {"deg": 1.0, "degree": 1.0, "degrees": 1.0, "°": 1.0, "rad": 180.0 / np.pi, "radian": 180.0 / np.pi,
          "radians": 180.0 / np.pi}
_RATE = {"deg/s": 1.0, "°/s": 1.0, "deg_s": 1.0, "degs": 1.0, "deg/sec": 1.0, "rad/s": 180.0 / np.pi,
         "rad_s": 180.0 / np.pi, "rads": 180.0 / np.pi, "rad/sec": 180.0 / np.pi, "deg/min": 1.0 / 60.0}
DECLARED_UNITS = {
    "time": {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0, "ms": 1e-3, "msec": 1e-3, "min": 60.0},
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "angle": _ANGLE,
    "rate": _RATE,
    "velocity": {"m/s": 1.0, "m_s": 1.0, "mps": 1.0, "cm/s": 1e-2, "kn": KNOT, "kt": KNOT,
                 "knots": KNOT, "knot": KNOT},
    "frequency": {"1/min": 1.0, "rpm": 1.0, "rev/min": 1.0, "1/s": 60.0, "rps": 60.0, "rev/s": 60.0,
                  "hz": 60.0},
    "force": {"n": 1.0, "kn": 1e3},
    "moment": {"nm": 1.0, "n m": 1.0, "n.m": 1.0, "knm": 1e3},
}
COLUMN_UNIT_KIND = {
    "time": "time", "x0": "length", "y0": "length", "psi": "angle", "u": "velocity", "v": "velocity",
    "r": "rate", "delta": "angle", "rpm": "frequency", "phi": "angle", "p": "rate", "thrust": "force",
    "torque": "moment",
}
_SUFFIX_UNITS = ("rad_s", "deg_s", "rad", "deg", "ms", "rps", "rpm", "kn", "mm", "cm", "s", "m_s", "mps")


def split_name(name: str) -> tuple[str, str | None]:
    """Header name to (canonical name, declared unit or None).

    ``'Time [s]'`` -> ('time', 's'); ``'psi (rad)'`` -> ('psi', 'rad'); ``'psi_rad'`` -> ('psi', 'rad');
    ``'r_deg_s'`` -> ('r', 'deg_s').  A ``_unit`` suffix counts only after a canonical column name.
    """
    raw = name.strip().strip('"').strip("'").strip()
    m = re.match(r"^(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$", raw)
    if m:
        return m[1].strip().strip('"').lower(), (m[2].strip().lower() or None)
    base = raw.lower()
    for unit in _SUFFIX_UNITS:
        stem = base[: -len(unit) - 1]
        if base.endswith("_" + unit) and stem in COLUMN_UNIT_KIND:
            return stem, unit
    return base, None


def _clean_name(name: str) -> str:
    """'Time [s]' -> 'time'."""
    return split_name(name)[0]


_VOID = {"", "nan", "na", "n/a", "-", "none", "null"}


def _tokens(row: str, sep: str) -> list[str]:
    return row.split() if sep in (" ", "ws") else row.split(sep)


def _numeric_block(rows: list[str], linenos: np.ndarray, names: tuple[str, ...], sep: str,
                   file, *, decimal: str = ".", optional: frozenset[str] | None = None,
                   notes: list[str] | None = None) -> pd.DataFrame:
    """Parse data rows into floats, naming the row and column of the first bad value.

    ``sep``: ',', ';', '\\t' or 'ws' (runs of whitespace).  ``decimal``: '.' or ',' (decimal comma,
    only with a separator other than the comma).  Numbers in double quotes are numbers.  A column in
    ``optional`` (a name the pipeline does not use) holding text is dropped with a line in ``notes``
    instead of refusing the file; text in any other column is refused, naming row and column.
    """
    n = len(names)
    if sep in (" ", "ws"):
        counts = np.fromiter((len(r.split()) for r in rows), dtype=np.int64, count=len(rows))
    else:
        counts = np.fromiter((r.count(sep) + 1 for r in rows), dtype=np.int64, count=len(rows))
    bad = np.flatnonzero(counts != n)
    if bad.size:
        k = int(bad[0])
        raise InputError(f"expected {n} values, found {int(counts[k])}", file=file, row=int(linenos[k]))
    body = [r.strip() for r in rows]
    if decimal == ",":
        body = [r.replace(",", ".") for r in body]
    text = "\n".join(body)
    try:
        df = pd.read_csv(io.StringIO(text), header=None, names=list(names),
                         sep=r"\s+" if sep in (" ", "ws") else sep, engine="c",
                         quoting=csv.QUOTE_MINIMAL if sep != "ws" else csv.QUOTE_NONE,
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
        # a copy: written below, and pandas 3 (copy-on-write) may hand out a read-only view
        num = pd.to_numeric(col, errors="coerce").to_numpy(dtype=float, copy=True)
        miss = np.isnan(num)
        if miss.any():
            as_text = col.astype(str).str.strip().str.strip('"').str.strip("'").str.strip()
            for k in np.flatnonzero(miss):
                tok = as_text.iat[k]
                if tok.lower() in _VOID or tok == "<NA>":
                    continue
                low = tok.lower()
                if low in ("inf", "+inf", "-inf", "infinity", "+infinity", "-infinity"):
                    num[k] = float(low.replace("infinity", "inf"))
                    continue
                if _is_number(tok):
                    num[k] = float(tok.replace("d", "e").replace("D", "e"))
                    continue
                if optional is not None and name in optional:
                    if notes is not None:
                        notes.append(f"column '{name}' ignored: not numeric (row {int(linenos[k])}: "
                                     f"{shown(tok, 20)})")
                    num = None
                    break
                raise InputError(f"value{shown(tok, 20, ' ')} is not a number", file=file,
                                 row=int(linenos[k]), column=name)
        if num is not None:
            out[name] = num
    return pd.DataFrame(out)


def _data_rows(lines: list[str], start: int, sep: str = "ws") -> tuple[list[str], np.ndarray, int]:
    """Data lines from ``start`` on, their 1-based line numbers, and how many void rows ended the file.

    Empty rows and rows of separators only (``,,,,`` as spreadsheets export them) are skipped
    wherever they are.  Rows at the end of the file whose every value is empty or NaN (real MARIN
    files end with them) are dropped and counted; a NaN row inside the run stays and is refused later.
    """
    rows, nums = [], []
    strip_chars = " \t\r" + ("" if sep == "ws" else sep)
    for i in range(start, len(lines)):
        s = lines[i]
        if s.strip(strip_chars):
            rows.append(s)
            nums.append(i + 1)
    dropped = 0
    while rows and all(t.strip().strip('"').lower() in _VOID for t in _tokens(rows[-1], sep)):
        rows.pop()
        nums.pop()
        dropped += 1
    # rows of separators only after the last data row are empty rows at the end too (counted)
    last = nums[-1] if nums else start
    dropped += sum(1 for s in lines[last:] if s.strip(" \t\r") and not s.strip(strip_chars))
    return rows, np.asarray(nums, dtype=np.int64), dropped


USED_COLUMNS = frozenset(COLUMN_UNIT_KIND)


def read_preamble(lines: list[str]) -> tuple[int, dict[str, str], list[str]]:
    """The leading blank and ``#`` lines: (index of the first other line, ``key: value`` pairs with
    lower-case keys, free-text comments)."""
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
    return i, header, comments


def data_block(lines: list[str], start: int, sep: str, file, notes: list[str]
               ) -> tuple[list[str], np.ndarray, str]:
    """The data rows of a delimited table from line ``start`` (0-based) on: (rows, their 1-based line
    numbers, the decimal mark).  Trailing empty rows are dropped and noted; a decimal comma is
    recognised in a table not separated by commas (and noted), refused where it cannot be told from
    a separator."""
    rows, linenos, dropped = _data_rows(lines, start, sep)
    if not rows:
        raise InputError("no data rows", file=file)
    decimal = "."
    if sep != ",":
        sample = " ".join(rows[:50])
        if "," in sample:
            if re.search(r"\d,\d", sample) and not re.search(r"\d\.\d", sample):
                decimal = ","
                notes.append(f"{DELIMITERS[' ' if sep == 'ws' else sep]}-separated with decimal commas")
            else:
                raise InputError("commas inside values of a table that is not comma-separated, mixed with "
                                 "decimal points: cannot tell a decimal comma from a separator", file=file,
                                 row=int(linenos[0]))
    if sep != ",":
        notes.append(f"{DELIMITERS[' ' if sep == 'ws' else sep]}-separated table")
    if dropped:
        notes.append(f"{dropped} empty or NaN rows at the end of the file dropped")
    return rows, linenos, decimal


def header_meta(header: dict[str, str], comments: list[str], file) -> dict[str, Any]:
    """What a table's ``# key: value`` lines say: provenance, test, ship, Lpp (m, at the file's scale),
    the model's scale (full/model), the logged step (s), the seed.  Lpp, scale and step must be
    positive finite numbers, and the scale a factor full/model (``IngestConfig.scale_range``): a
    header that says otherwise is refused, naming the key."""
    from pipeline.config import IngestConfig

    meta: dict[str, Any] = {}
    prov = header.get("provenance", "").strip().lower()
    meta["provenance"] = "virtual" if "virtual" in prov else "measured"
    meta["test_name"] = header.get("test", header.get("test_name", "")).strip()
    if header.get("ship"):
        meta["ship"] = header["ship"].strip()
    lo, hi = IngestConfig().scale_range
    for key, dest in (("lpp", "lpp"), ("scale", "model_scale"), ("dt", "logged_dt"), ("seed", "seed")):
        if key in header:
            try:
                val = float(header[key])
            except ValueError:
                raise InputError(f"header value {key!r} is not a number{shown(header[key], 20, ': ')}",
                                 file=file) from None
            if key != "seed" and not (math.isfinite(val) and val > 0):
                raise InputError(f"header value {key!r} must be a positive finite number, got {val:g}",
                                 file=file)
            if key == "scale" and not lo <= val <= hi:
                raise InputError(f"header value 'scale' must be a scale factor full/model between {lo:g} "
                                 f"and {hi:g}, got {val:g}", file=file)
            meta[dest] = int(val) if key == "seed" and val.is_integer() else val
    if "model_scale" in meta:
        # CSV values are model scale (docs/contract.md#raw-formats); 'scale' is the model's scale factor
        meta["file_states_model_scale"] = True
    if header:
        meta["header"] = header
    if comments:
        meta["comments"] = comments
    return meta


def parse_csv(lines: list[str], file=None) -> RawTable:
    """Canonical CSV (docs/contract.md#raw-formats), also semicolon- (with decimal commas), tab- or
    whitespace-delimited, with declared units in the header names converted to canonical ones."""
    meta: dict[str, Any] = {}
    notes: list[str] = []
    found = table_header(lines)
    i, header, comments = read_preamble(lines)
    if i >= len(lines):
        raise InputError("no header row (time, psi, r, delta, ...) found", file=file)
    sep = found[1] if found else ","
    if sep == " ":
        sep = "ws"
    parts = _tokens(lines[i], sep)
    split = [split_name(n) for n in parts]
    names = [n for n, _ in split]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError("column named twice in the header", file=file, row=i + 1, column=dup)
    if any(not n for n in names):
        raise InputError("empty column name in the header", file=file, row=i + 1)
    for c in CSV_REQUIRED:
        if c not in names:
            have = f"columns found: {', '.join(names[:8])}; " if ECHO_CONTENT.get() else ""
            raise InputError(f"required column is missing from the header ({have}a logger's own layout is "
                             "described by [columns] in dataset.toml, docs/dataset.md)", file=file, row=i + 1,
                             column=c)
    rows, linenos, decimal = data_block(lines, i + 1, sep, file, notes)
    optional = frozenset(n for n in names if n not in USED_COLUMNS)
    frame = _numeric_block(rows, linenos, tuple(names), sep, file, decimal=decimal, optional=optional,
                           notes=notes)
    declared: dict[str, str] = {}
    for (name, unit) in split:
        if unit is None or name not in frame.columns:
            continue
        kind = COLUMN_UNIT_KIND.get(name)
        if kind is None:
            continue
        table = DECLARED_UNITS[kind]
        key = unit.replace(" ", "") if kind != "moment" else unit
        if key not in table and unit not in table:
            raise InputError(f"declared unit {unit!r} is not a {kind} unit the reader knows "
                             f"({', '.join(sorted(table))})", file=file, row=i + 1, column=name)
        factor = table.get(key, table.get(unit))
        if factor != 1.0:
            frame[name] = frame[name] * factor
            notes.append(f"column '{name}' converted from declared {unit} (x {factor:.6g})")
        declared[name] = unit
    if declared:
        meta["declared_units"] = declared
    meta.update(header_meta(header, comments, file))
    if notes:
        meta["ingest_notes"] = notes
    return RawTable("csv", frame, linenos, meta)


def _check_count(rows: list[str], linenos: np.ndarray, names: tuple[str, ...], fmt: str, file) -> None:
    """The first data row of a fixed-layout .dat must have the format's column count (named)."""
    if rows and len(rows[0].split()) != len(names):
        raise InputError(f"a {fmt} .dat has {len(names)} columns, this row has {len(rows[0].split())}: "
                         f"not the {fmt} layout (docs/dataset.md)", file=file, row=int(linenos[0]))


def _fixed_layout(lines: list[str], names: tuple[str, ...], fmt: str, file, test_line: int):
    """The numeric block of a fixed-layout .dat (columns ``names``, whitespace-separated, after a
    header of text lines) and the metadata its header gives: (raw frame, line numbers, header lines,
    meta with provenance, the test's name from header line ``test_line`` (0-based; '' where the
    header is shorter), the institute (the first line) and a note of the empty rows dropped at the
    end).  InputError (naming the file) without numeric rows or with another column count."""
    j = _first_numeric_line(lines)
    if j is None:
        raise InputError(f"no numeric data rows found ({fmt} .dat)", file=file)
    rows, linenos, dropped = _data_rows(lines, j)
    _check_count(rows, linenos, names, fmt, file)
    raw = _numeric_block(rows, linenos, names, "ws", file)
    head = [s.strip() for s in lines[:j]]
    test = head[test_line] if len(head) > test_line else ""
    meta: dict[str, Any] = {"provenance": "measured", "test_name": test}
    if dropped:
        meta["ingest_notes"] = [f"{dropped} empty or NaN rows at the end of the file dropped"]
    if head:
        meta["institute"] = head[0]
    return raw, linenos, head, meta


def parse_marin(lines: list[str], file=None) -> RawTable:
    """MARIN SIMMAN free-running .dat: rudder sign flipped, u, v from dx0, dy0 and psi."""
    raw, linenos, head, meta = _fixed_layout(lines, MARIN_COLUMNS, "MARIN", file, 1)
    if len(head) == 1:
        meta["test_name"] = head[0]
    test = meta["test_name"]
    m = re.search(r"\bfor\s+([A-Za-z0-9-]+)", test)
    if m:
        meta["ship"] = m[1].upper()
    u, v = body_velocities(raw["dx0"].to_numpy(), raw["dy0"].to_numpy(), raw["psi"].to_numpy())
    frame = pd.DataFrame({
        "time": raw["time"], "x0": raw["x0"], "y0": raw["y0"], "psi": raw["psi"], "u": u, "v": v,
        "r": raw["r"], "delta": -raw["delta"], "rpm": raw["rev"], "phi": raw["phi"], "p": raw["p"],
    })
    return RawTable("marin", frame, linenos, meta, digits=3)


def parse_hsva(lines: list[str], file=None) -> RawTable:
    """HSVA CPMC .dat (column meanings in this module's docstring)."""
    raw, linenos, head, meta = _fixed_layout(lines, HSVA_COLUMNS, "HSVA", file, 2)
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
        meta["lpp"] = KNOWN_SHIPS.hsva_kvlcc2_lpp_m       # HSVA's model, as the data's README states it
        meta["lpp_source"] = "HSVA KVLCC2 model"
        meta["model_scale"] = KNOWN_SHIPS.hsva_kvlcc2_scale
        meta["file_states_model_scale"] = True      # CPMC files are model-scale measurements
    return RawTable("hsva", frame, linenos, meta)


PARSERS = {"csv": parse_csv, "marin": parse_marin, "hsva": parse_hsva}
