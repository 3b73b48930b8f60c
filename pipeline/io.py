"""File input/output shared by every stage: atomic writes, runs as Parquet, JSON.

Every output is written to a temporary name in the destination directory and renamed into place,
so a failed stage leaves no partial file and earlier outputs stay intact (SPEC section 8).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from pipeline.errors import InputError

RUN_META_KEY = b"tanktest.run"
_UMASK = os.umask(0o022)
os.umask(_UMASK)
REQUIRED_COLUMNS = ("time", "psi", "r", "delta")
CANONICAL_COLUMNS = ("time", "x0", "y0", "psi", "u", "v", "r", "delta", "rpm")
COLUMN_UNITS = {
    "time": "s", "x0": "m", "y0": "m", "psi": "deg", "u": "m/s", "v": "m/s", "r": "deg/s",
    "delta": "deg", "rpm": "1/min", "phi": "deg", "p": "deg/s",
}


@dataclass
class Run:
    """One manoeuvre at model scale on a uniform time grid (SPEC section 2).

    ``frame`` has the canonical columns (time s, x0/y0 m, psi deg, u/v m/s, r deg/s, delta deg,
    rpm 1/min, plus optional ones); ``meta`` holds the provenance (source_file, source_sha256,
    source_format, scale_factor, original_dt, dt, test_name, provenance 'measured'|'virtual', and
    the parsed test: kind, rudder_deg, heading_deg, first_side).
    """

    frame: pd.DataFrame
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return str(self.meta.get("run_id") or self.meta.get("source_file") or "run")

    @property
    def dt(self) -> float:
        t = self.frame["time"].to_numpy()
        return float(self.meta.get("dt") or (t[1] - t[0]))

    def col(self, name: str) -> np.ndarray:
        """Column as a float array (raises InputError naming the run and column if absent)."""
        if name not in self.frame.columns:
            raise InputError("column is missing", file=self.name, column=name)
        return self.frame[name].to_numpy(dtype=float)

    @property
    def is_virtual(self) -> bool:
        return self.meta.get("provenance") == "virtual"


@contextlib.contextmanager
def atomic_path(dest: str | Path, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``dest``; rename it onto ``dest`` only if the block succeeds."""
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=suffix or ".tmp", dir=dest.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.chmod(tmp_path, 0o666 & ~_UMASK)      # mkstemp makes 0600; give the usual mode
        os.replace(tmp_path, dest)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


@contextlib.contextmanager
def atomic_dir(dest: str | Path) -> Iterator[Path]:
    """Yield a temporary directory beside ``dest``; it replaces ``dest`` only if the block succeeds.

    Files already in ``dest`` that the block does not rewrite are kept (the new files are moved
    in one by one, each with an atomic rename).
    """
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.", dir=dest.parent))
    try:
        yield tmp
        dest.mkdir(parents=True, exist_ok=True)
        for item in sorted(tmp.rglob("*")):
            if item.is_file():
                target = dest / item.relative_to(tmp)
                target.parent.mkdir(parents=True, exist_ok=True)
                os.replace(item, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_json(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as indented JSON atomically (numpy types converted, NaN/inf as null)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(_jsonable(obj), indent=2, allow_nan=False) + "\n")
    return path


def read_json(path: str | Path) -> Any:
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError("file not found (run the stage that makes it first)", file=path) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON ({exc.msg} at line {exc.lineno})", file=path) from None


def write_frame(path: str | Path, frame: pd.DataFrame, meta: dict[str, Any] | None = None) -> Path:
    """Write a data frame as Parquet atomically, with ``meta`` (JSON) in the schema metadata."""
    path = Path(path)
    table = pa.Table.from_pandas(frame, preserve_index=False)
    if meta is not None:
        md = dict(table.schema.metadata or {})
        md[RUN_META_KEY] = json.dumps(_jsonable(meta)).encode()
        table = table.replace_schema_metadata(md)
    with atomic_path(path, suffix=".parquet") as tmp:
        pq.write_table(table, tmp)
    return path


def read_frame(path: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Read a Parquet file written by :func:`write_frame`; returns (frame, meta)."""
    path = Path(path)
    try:
        table = pq.read_table(path)
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (pa.ArrowInvalid, OSError) as exc:
        raise InputError(f"not a readable Parquet file ({exc})", file=path) from None
    md = table.schema.metadata or {}
    meta = json.loads(md[RUN_META_KEY]) if RUN_META_KEY in md else {}
    return table.to_pandas(), meta


def write_run(path: str | Path, run: Run) -> Path:
    """Write a processed run (SPEC section 2) atomically."""
    return write_frame(path, run.frame, run.meta)


def read_run(path: str | Path) -> Run:
    """Read a processed run and check it has the required columns."""
    frame, meta = read_frame(path)
    for c in REQUIRED_COLUMNS:
        if c not in frame.columns:
            raise InputError("required column is missing from processed run", file=path, column=c)
    meta.setdefault("run_id", Path(path).stem)
    return Run(frame=frame, meta=meta)
