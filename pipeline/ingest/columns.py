"""A logger's own table read through ``[columns]`` of dataset.toml (docs/dataset.md, "[columns]").

``[columns]`` maps each output column to a column of the logger's table::

    [columns]
    time  = {source = "t [s]"}                     # or: sample_rate_hz = 10 (no time column)
    psi   = {source = "heading [rad]", unit = "rad", wrapped = true}
    r     = {source = "yaw rate [rad/s]", unit = "rad/s"}
    delta = {source = "rudder [rad]", unit = "rad", sign = -1}
    u     = {source = "surge [m/s]", unit = "m/s"}
    wind_speed = {source = "wind [m/s]", unit = "m/s"}     # any other name: an optional column

Each entry is an inline table: ``source`` (the column's header text, exactly as written, or its
name without the bracketed unit, compared without case), ``unit`` (default: the unit in brackets
in the header when it is one the reader knows, else the canonical unit), ``sign``
(+1 or -1: multiplies the values, after the unit), and for the heading ``wrapped`` (true: the
logger wraps it to (-180, 180] deg or (-pi, pi] rad; it is unwrapped either way, as every heading is,
and the flag is recorded).  ``time``, ``psi``, ``r`` and ``delta`` are required (time from a
column or from ``sample_rate_hz``); ``x0, y0, u, v, rpm`` are taken when mapped; any other name
becomes an optional column in the unit of its kind (deg, deg/s, m/s, m, N, N m, 1/min), or as
logged when ``unit`` is ``"1"`` (no unit).  Columns of the file that are not mapped are left out,
with a note naming them.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pipeline.errors import InputError
from pipeline.ingest.formats import (
    COLUMN_UNIT_KIND,
    DECLARED_UNITS,
    DELIMITERS,
    ECHO_CONTENT,
    RawTable,
    _numeric_block,
    _tokens,
    data_block,
    header_meta,
    read_preamble,
    shown,
    split_name,
)

REQUIRED = ("time", "psi", "r", "delta")
# Canonical unit of each kind (docs/dataset.md): the default unit, and what optional columns become.
CANONICAL_UNIT = {"time": "s", "length": "m", "angle": "deg", "rate": "deg/s", "velocity": "m/s",
                  "frequency": "rpm", "force": "n", "moment": "nm"}
UNITLESS = "1"
_NAME = re.compile(r"^[a-z][a-z0-9_]*$")
_ENTRY_KEYS = ("source", "unit", "sign", "wrapped")


@dataclass(frozen=True)
class ColumnSpec:
    """One output column: its source column, the source's unit, the factor to the output unit, the
    sign, whether the source wraps (heading), and its Froude kind (None: no unit, not scaled)."""

    name: str
    source: str
    unit: str
    factor: float
    sign: int = 1
    wrapped: bool = False
    kind: str | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"source": self.source, "unit": self.unit, "sign": self.sign,
                **({"wrapped": True} if self.wrapped else {})}


@dataclass(frozen=True)
class ColumnMap:
    """``[columns]``: the output columns (in the order given) and, without a time column, the
    logger's sample rate (Hz)."""

    specs: tuple[ColumnSpec, ...]
    sample_rate_hz: float | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {s.name: s.as_dict() for s in self.specs}
        if self.sample_rate_hz is not None:
            out["sample_rate_hz"] = self.sample_rate_hz
        return out

    def read(self, lines: list[str], file=None) -> RawTable:
        """The logger's table as canonical columns at the file's scale (time s from 0 as logged, psi
        deg as logged but unwrapped, r deg/s, delta deg, u/v m/s, x0/y0 m, rpm 1/min; optional
        columns in the unit of their kind), with its line numbers and what its header says."""
        notes: list[str] = []
        i, header, comments = read_preamble(lines)
        if i >= len(lines):
            raise InputError("no header row found (dataset.toml [columns] names the columns of a header "
                             "row)", file=file)
        sep, names = self._header(lines[i], file, i + 1)
        rows, linenos, decimal = data_block(lines, i + 1, sep, file, notes)
        wanted = {self._match(s.source, names, file, i + 1) for s in self.specs}
        optional = frozenset(n for n in names if n not in wanted)
        raw = _numeric_block(rows, linenos, tuple(names), sep, file, decimal=decimal, optional=optional,
                             notes=notes)
        left = [n for n in names if n not in wanted]
        if left:
            notes.append(f"columns not mapped in [columns], left out: {', '.join(left[:12])}"
                         + (" ..." if len(left) > 12 else ""))
        out: dict[str, np.ndarray] = {}
        if self.sample_rate_hz is not None:
            out["time"] = np.arange(len(rows), dtype=float) / self.sample_rate_hz
        declared: dict[str, str] = {}
        for spec in self.specs:
            values = raw[self._match(spec.source, names, file, i + 1)].to_numpy(dtype=float)
            values = values * spec.factor * spec.sign
            if spec.wrapped:
                _check_wrap(values, spec, file, linenos)
                values = _unwrap_finite(values)
            out[spec.name] = values
            declared[spec.name] = spec.unit
        frame = pd.DataFrame(out)
        frame = frame[["time"] + [c for c in frame.columns if c != "time"]]
        meta: dict[str, Any] = header_meta(header, comments, file)
        meta["declared_units"] = declared
        meta["column_map"] = self.as_dict()
        meta["column_kinds"] = {s.name: s.kind for s in self.specs
                                if s.kind is not None and s.name not in COLUMN_UNIT_KIND}
        notes.insert(0, "columns mapped by dataset.toml [columns]")
        for spec in self.specs:
            if spec.factor != 1.0 or spec.sign != 1:
                notes.append(f"column '{spec.name}' from '{spec.source}' in {spec.unit}"
                             + (f" (x {spec.factor:.6g})" if spec.factor != 1.0 else "")
                             + (", sign reversed" if spec.sign == -1 else ""))
        meta["ingest_notes"] = notes
        return RawTable("csv", frame, linenos, meta)

    def _header(self, line: str, file, row: int) -> tuple[str, list[str]]:
        """The delimiter under which the header row holds every source column, and its names."""
        for delim in (",", ";", "\t", " "):
            sep = "ws" if delim == " " else delim
            names = [n.strip().strip('"').strip("'").strip() for n in _tokens(line, sep)]
            if len(names) >= 2 and all(self._find(s.source, names) is not None for s in self.specs):
                if len(set(names)) != len(names):
                    dup = next(n for n in names if names.count(n) > 1)
                    raise InputError("column named twice in the header", file=file, row=row, column=dup)
                return sep, names
        for delim in (",", ";", "\t", " "):
            names = [n.strip().strip('"') for n in _tokens(line, "ws" if delim == " " else delim)]
            if len(names) >= 2:
                break
        missing = next(s for s in self.specs if self._find(s.source, names) is None)
        found = ", ".join(shown(n, 30) for n in names[:12]) if ECHO_CONTENT.get() else f"{len(names)}"
        raise InputError(f"dataset.toml [columns] {missing.name}: no column {missing.source!r} in the header "
                         f"(columns found: {found}; {DELIMITERS[delim]}-separated)", file=file, row=row)

    @staticmethod
    def _find(source: str, names: list[str]) -> str | None:
        if source in names:
            return source
        low = source.strip().lower()
        hits = [n for n in names if n.lower() == low] or [n for n in names if split_name(n)[0] == low]
        return hits[0] if len(hits) == 1 else None

    def _match(self, source: str, names: list[str], file, row: int) -> str:
        hit = self._find(source, names)
        if hit is None:
            raise InputError(f"no column {source!r} in the header", file=file, row=row)
        return hit


def _check_wrap(values: np.ndarray, spec: ColumnSpec, file, linenos: np.ndarray) -> None:
    """A heading said to be wrapped must wrap at +-180 deg once converted: one that stays within
    +-pi and jumps by 2 pi is in radians whatever its stated unit (refused, naming the row)."""
    ok = values[np.isfinite(values)]
    if ok.size < 3 or np.max(np.abs(ok)) > np.pi + 1e-6:
        return
    jumps = np.flatnonzero(np.abs(np.diff(values)) > np.pi)
    if jumps.size:
        k = int(jumps[0]) + 1
        raise InputError(f"the heading wraps at +-3.14 (a jump of {values[k] - values[k - 1]:.4g}): it is in "
                         f"radians, not {spec.unit} as dataset.toml [columns] psi says", file=file,
                         row=int(linenos[k]), column=spec.source)


def _unwrap_finite(values: np.ndarray) -> np.ndarray:
    """Unwrap a heading in degrees across +-180, leaving NaN where it is (refused later, by row)."""
    ok = np.isfinite(values)
    out = values.copy()
    if ok.sum() >= 2:
        out[ok] = np.unwrap(values[ok], period=360.0)
    return out


def _unit_factor(name: str, kind: str, unit: str, path: Path) -> float:
    table = DECLARED_UNITS[kind]
    key = unit.strip().lower()
    key2 = key.replace(" ", "") if kind != "moment" else key
    if key in table:
        return table[key]
    if key2 in table:
        return table[key2]
    raise InputError(f"[columns] {name} unit must be a {kind} unit ({', '.join(sorted(table))}), "
                     f"got {unit!r}", file=path)


def _kind_of_unit(unit: str) -> str | None:
    """The kind a unit belongs to, for an optional column ('kn' is a speed here, not kilonewtons)."""
    key = unit.strip().lower()
    for kind in ("angle", "rate", "velocity", "length", "frequency", "time", "force", "moment"):
        if key in DECLARED_UNITS[kind] or key.replace(" ", "") in DECLARED_UNITS[kind]:
            return kind
    return None


def parse_columns(table: dict, path: Path, header_units: bool = True) -> ColumnMap:
    """A :class:`ColumnMap` from the ``[columns]`` table of dataset.toml; refused in one line naming
    the key and what it must be."""
    specs: list[ColumnSpec] = []
    rate = None
    for name, entry in table.items():
        if name == "sample_rate_hz":
            if isinstance(entry, bool) or not isinstance(entry, (int, float)) or not (
                    math.isfinite(entry) and entry > 0):
                raise InputError(f"[columns] sample_rate_hz must be a positive finite number (Hz), got "
                                 f"{entry!r}", file=path)
            rate = float(entry)
            continue
        if not isinstance(entry, dict):
            raise InputError(f"[columns] {name} must be an inline table such as {{source = \"Heading\", "
                             f"unit = \"rad\"}}, got {type(entry).__name__}", file=path)
        if not _NAME.match(name):
            raise InputError(f"[columns] {name!r} is not a column name (lower-case letters, digits, _)",
                             file=path)
        if name == "time" and "sample_rate_hz" in entry:
            rate_entry = {"sample_rate_hz": entry["sample_rate_hz"]}
            rest = {k: v for k, v in entry.items() if k != "sample_rate_hz"}
            if rest:
                raise InputError("[columns] time gives sample_rate_hz and a source: give one", file=path)
            rate = parse_columns(rate_entry, path).sample_rate_hz
            continue
        for k in entry:
            if k not in _ENTRY_KEYS:
                raise InputError(f"unknown key {k!r} in [columns] {name} (known: {', '.join(_ENTRY_KEYS)})",
                                 file=path)
        source = entry.get("source")
        if not isinstance(source, str) or not source.strip():
            raise InputError(f"[columns] {name} source must be the column's name in the file (a string), "
                             f"got {source!r}", file=path)
        sign = entry.get("sign", 1)
        if isinstance(sign, bool) or sign not in (1, -1):
            raise InputError(f"[columns] {name} sign must be 1 or -1, got {sign!r}", file=path)
        wrapped = entry.get("wrapped", False)
        if not isinstance(wrapped, bool):
            raise InputError(f"[columns] {name} wrapped must be true or false, got {wrapped!r}", file=path)
        if wrapped and name != "psi":
            raise InputError(f"[columns] {name} wrapped: only the heading (psi) is unwrapped", file=path)
        unit = entry.get("unit")
        if unit is not None and not isinstance(unit, str):
            raise InputError(f"[columns] {name} unit must be a string such as \"rad\", got {unit!r}",
                             file=path)
        kind = COLUMN_UNIT_KIND.get(name)
        if unit is None:
            bracket = split_name(source)[1]
            unit = bracket if bracket is not None and header_units and (
                kind is None or _kind_of_unit(bracket) == kind) else None
        if kind is None:                                     # an optional column of the user's
            if unit is None or unit == UNITLESS:
                specs.append(ColumnSpec(name, source, UNITLESS, 1.0, sign, False, None))
                continue
            kind = _kind_of_unit(unit)
            if kind is None:
                raise InputError(f"[columns] {name} unit {unit!r} is not one the reader knows (say unit = "
                                 "\"1\" to keep the values as logged)", file=path)
        unit = unit if unit is not None else CANONICAL_UNIT[kind]
        factor = _unit_factor(name, kind, unit, path)
        specs.append(ColumnSpec(name, source, unit, factor, sign, wrapped, kind))
    names = [s.name for s in specs]
    if "time" in names and rate is not None:
        raise InputError("[columns] gives both a time column and sample_rate_hz: give one", file=path)
    missing = [c for c in REQUIRED if c not in names and not (c == "time" and rate is not None)]
    if missing:
        raise InputError(f"[columns] must map {', '.join(missing)} (required: time or sample_rate_hz, "
                         "psi, r, delta)", file=path)
    sources = [s.source for s in specs]
    dup = next((s for s in sources if sources.count(s) > 1), None)
    if dup is not None:
        raise InputError(f"[columns] maps the source column {dup!r} twice", file=path)
    return ColumnMap(tuple(specs), rate)
