"""File input/output shared by every stage: atomic writes, runs as Parquet, JSON.

Every output is written to a temporary name in the destination directory and renamed into place,
so a failed stage leaves no partial file and earlier outputs stay intact (docs/contract.md#bad-input).
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import math
import os
import re
import secrets
import shutil
import sys
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
    """One manoeuvre at model scale on a uniform time grid (docs/contract.md#run-data).

    ``frame`` has the canonical columns (time s, x0/y0 m, psi deg, u/v m/s, r deg/s, delta deg,
    rpm 1/min, plus optional ones); ``meta`` holds the provenance (source_file, source_sha256,
    source_format, scale_factor, original_dt, dt, test_name, provenance 'measured'|'virtual', and
    the parsed test: kind, rudder_deg, heading_deg, first_side).

    Examples
    --------
    >>> import pandas as pd
    >>> run = Run(frame=pd.DataFrame({"time": [0.0, 0.08, 0.16], "psi": [0.0, 0.08, 0.16],
    ...                               "r": [1.0, 1.0, 1.0], "delta": [5.0, 5.0, 5.0]}),
    ...           meta={"run_id": "zz_20_s", "provenance": "virtual"})
    >>> run.name, run.dt, run.is_virtual
    ('zz_20_s', 0.08, True)
    >>> run.col("r").tolist()
    [1.0, 1.0, 1.0]
    >>> run.col("v")
    Traceback (most recent call last):
    ...
    pipeline.errors.InputError: zz_20_s, column 'v': column is missing
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


_PID_NAME = re.compile(r"\.(?:out|old|tmp)\.(\d+)\.")


def _pid_alive(pid: int) -> bool:
    """True when a process with this id exists (a temporary of a live run must not be removed)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:                     # exists, belongs to someone else
        return True
    return True


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def clean_stale_temporaries(dest: str | Path) -> list[Path]:
    """Remove the temporaries that killed runs left beside ``dest``; returns what was removed.

    Every temporary this module makes carries the id of the process that made it
    (``.<name>.out.<pid>.*`` directories, ``.<name>.old.<pid>.*`` swapped-out sets,
    ``.<name>.tmp.<pid>.*`` files).  Only those whose process no longer exists are touched, so a
    concurrent run into the same place keeps its own.  A swapped-out set (``.old.``) of a run killed
    between the two renames of the fallback swap is put back when ``dest`` is missing; otherwise it is
    removed.  Temporaries of the earlier naming (``.<name>.`` + 8 random characters, no process id)
    are removed too.

    Parameters
    ----------
    dest : str or Path
        The output file or folder whose temporaries are looked for beside it.

    Returns
    -------
    list of Path
        What was removed (or put back).
    """
    dest = Path(dest)
    parent = dest.parent
    removed: list[Path] = []
    if not parent.is_dir():
        return removed
    prefix = f".{dest.name}."
    legacy = re.compile(re.escape(prefix) + r"[a-z0-9_]{8}(?:\.tmp|\.parquet|\.csv|\.html)?$")
    try:
        entries = sorted(parent.iterdir())
    except OSError:
        return removed
    for item in entries:
        name = item.name
        if not name.startswith(prefix):
            continue
        m = _PID_NAME.match(name[len(prefix) - 1:])
        if m:
            if _pid_alive(int(m[1])):
                continue
            if ".old." in name and not dest.exists() and item.is_dir():
                with contextlib.suppress(OSError):
                    os.rename(item, dest)                 # the set of the last good run comes back
                    continue
            _remove(item)
            removed.append(item)
        elif legacy.match(name):
            _remove(item)
            removed.append(item)
    return removed


@contextlib.contextmanager
def _naming(tmp: Path, dest: Path) -> Iterator[None]:
    """An OSError inside the block (disk full, a quota, a permission) names the file the user asked
    for: ``dest`` (or the file under it) in place of the temporary, and ``dest`` when the error named
    no file at all (a full disk's ENOSPC from ``write``, pyarrow's IOError)."""
    try:
        yield
    except OSError as exc:
        name = None if exc.filename is None else str(exc.filename)
        if name is None or name == str(tmp):
            where = str(dest)
        elif name.startswith(str(tmp) + os.sep):
            where = str(dest) + name[len(str(tmp)):]
        else:
            raise
        why = exc.strerror or " ".join(str(exc).split()) or type(exc).__name__
        raise OSError(exc.errno, why, where) from exc


@contextlib.contextmanager
def atomic_path(dest: str | Path, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``dest``; rename it onto ``dest`` only if the block succeeds.

    Parameters
    ----------
    dest : str or Path
        The file to write; its folder is made when missing.
    suffix : str, optional
        The temporary's suffix (a writer that needs one, e.g. ``.parquet``).

    Yields
    ------
    Path
        The temporary path to write; renamed onto ``dest`` when the block ends without an
        exception, removed when it raises (``dest`` then untouched).

    Examples
    --------
    >>> folder = Path(tempfile.mkdtemp())
    >>> with atomic_path(folder / "a.txt") as tmp:
    ...     _ = tmp.write_text("done")
    >>> (folder / "a.txt").read_text(), sorted(p.name for p in folder.iterdir())
    ('done', ['a.txt'])
    """
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_temporaries(dest)
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.tmp.{os.getpid()}.", suffix=suffix or ".tmp",
                               dir=dest.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        with _naming(tmp_path, dest):
            yield tmp_path
            os.chmod(tmp_path, 0o666 & ~_UMASK)      # mkstemp makes 0600; give the usual mode
            os.replace(tmp_path, dest)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


# ------------------------------------------------------------------ directory sets
_RENAME_EXCHANGE = 2                             # linux/fs.h
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one atomic step (Linux renameat2 RENAME_EXCHANGE); False if unsupported."""
    if sys.platform != "linux":
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    rc = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    return rc == 0


def set_manifest_path(dest: str | Path) -> Path:
    """Where the manifest of the output set ``dest`` lives: ``<parent>/.<name>.set.json``.

    It lists the files of the last complete set written into ``dest``.  It sits beside the
    directory, not in it, so that a directory holds exactly the stage's outputs.

    Parameters
    ----------
    dest : str or Path
        The output folder.

    Returns
    -------
    Path
        The manifest's path.

    Examples
    --------
    >>> set_manifest_path("data/processed/virtual/runs").as_posix()
    'data/processed/virtual/.runs.set.json'
    """
    dest = Path(dest)
    return dest.parent / f".{dest.name}.set.json"


def _listing(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() or p.is_symlink())


def _read_manifest(dest: Path, writer: str = "") -> list[str] | None:
    """The files of the last set written into ``dest`` by ``writer`` (None: none, or another's; a
    manifest that names no writer, written before writers were recorded, is taken as anyone's)."""
    try:
        data = json.loads(set_manifest_path(dest).read_text())
        files = data.get("files")
        if data.get("writer", writer) != writer:
            return None
        return [str(f) for f in files] if isinstance(files, list) else None
    except (OSError, ValueError, AttributeError):
        return None


def _owned(dest: Path, writer: str = "") -> bool:
    """True when everything in ``dest`` belongs to the last set ``writer`` wrote there (or it is empty)."""
    if not dest.exists():
        return True
    if not dest.is_dir():
        return False
    here = Path.cwd().resolve()
    if dest.resolve() == here or dest.resolve() in here.parents:
        return False                             # never swap away the working directory or its parents
    present = _listing(dest)
    dirs_only = not present and not any(dest.iterdir())
    if dirs_only:
        return True
    listed = _read_manifest(dest, writer)
    return listed is not None and set(present) <= set(listed)


@contextlib.contextmanager
def atomic_dir(dest: str | Path, writer: str = "") -> Iterator[Path]:
    """Yield a temporary directory beside ``dest``; its files become ``dest`` as one set, or nothing.

    docs/contract.md#bad-input: a stage's outputs appear together or not at all, earlier outputs stay
    intact when the block fails, and no file of an earlier run is left beside the new ones.

    - The block writes into ``.<name>.out.<pid>.*`` beside ``dest``.  If it raises, that directory is
      removed and ``dest`` is untouched.
    - When ``dest`` holds only the previous set of this function (the manifest
      :func:`set_manifest_path` lists every file in it) or is missing or empty, the new directory
      replaces it in one atomic exchange (Linux ``renameat2``; elsewhere two renames, with the old
      set recoverable by :func:`clean_stale_temporaries` if the process dies between them), and the
      old set is deleted: stale files (plots of an earlier run) do not survive.
    - When ``dest`` also holds files this function did not write (a user's folder given as
      ``--out``), nothing of theirs is removed: the new files are renamed in one by one, files of the
      previous set that the new set does not have are removed, and the manifest is written last.
    - ``writer`` names the command writing the set (a user's ``--out`` folder may receive the sets of
      several commands: ingest's runs, then identify's estimates): only a set of the same writer
      counts as the previous set, so one command never removes another's files.
    - Temporaries of killed runs beside ``dest`` are removed first (:func:`clean_stale_temporaries`).

    Parameters
    ----------
    dest : str or Path
        The output folder.
    writer : str
        The command writing the set.

    Yields
    ------
    Path
        The temporary folder to write the set into.

    Examples
    --------
    >>> folder = Path(tempfile.mkdtemp()) / "runs"
    >>> with atomic_dir(folder, writer="example") as tmp:
    ...     _ = (tmp / "a.json").write_text("{}")
    >>> sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))
    ['a.json']
    """
    dest = Path(os.path.abspath(dest))          # '.' has no name to put a temporary beside
    dest.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_temporaries(dest)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.out.{os.getpid()}.", dir=dest.parent))
    try:
        with _naming(tmp, dest):
            yield tmp
            os.chmod(tmp, 0o777 & ~_UMASK)           # mkdtemp makes 0700; give the usual mode
            files = _listing(tmp)
            if _owned(dest, writer):
                _swap_in(tmp, dest)
            else:
                _merge_in(tmp, dest, files, writer)
        write_json(set_manifest_path(dest), {"files": files, "writer": writer})
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def _swap_in(tmp: Path, dest: Path) -> None:
    for _ in range(5):                           # a concurrent run may swap in between: retry
        if not dest.exists():
            try:
                os.rename(tmp, dest)
                return
            except OSError:
                continue
        if _exchange(tmp, dest):                 # tmp now holds the old set
            shutil.rmtree(tmp, ignore_errors=True)
            return
        old = dest.parent / f".{dest.name}.old.{os.getpid()}.{secrets.token_hex(4)}"
        try:
            os.rename(dest, old)
        except FileNotFoundError:
            continue
        try:
            os.rename(tmp, dest)
        except OSError:
            os.rename(old, dest)                 # put the old set back, try again
            continue
        shutil.rmtree(old, ignore_errors=True)
        return
    raise OSError(f"could not replace {dest} (another run keeps writing it)")


def _merge_in(tmp: Path, dest: Path, files: list[str], writer: str = "") -> None:
    previous = set(_read_manifest(dest, writer) or [])
    for rel in files:
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(tmp / rel, target)
    for rel in sorted(previous - set(files)):
        with contextlib.suppress(OSError):
            (dest / rel).unlink()


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
    """Write ``obj`` as indented JSON atomically (numpy types converted, NaN/inf as null).

    Parameters
    ----------
    path : str or Path
        The file; its folder must exist.  Written to a temporary name and renamed, so a failure
        leaves an earlier file intact.
    obj : Any
        JSON-able data; numpy scalars and arrays become numbers and lists, NaN and inf ``null``.

    Returns
    -------
    Path
        ``path``.

    Examples
    --------
    >>> folder = Path(tempfile.mkdtemp())
    >>> write_json(folder / "x.json", {"K": np.float64(0.39), "T": float("nan"), "a": np.arange(2)}).name
    'x.json'
    >>> read_json(folder / "x.json")
    {'K': 0.39, 'T': None, 'a': [0, 1]}
    """
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(_jsonable(obj), indent=2, allow_nan=False) + "\n")
    return path


def read_json(path: str | Path) -> Any:
    """Read a JSON file.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    Any
        The parsed document.

    Raises
    ------
    InputError
        One line naming the file when it is missing or not valid JSON.

    Examples
    --------
    >>> folder = Path(tempfile.mkdtemp())
    >>> read_json(folder / "missing.json")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pipeline.errors.InputError: .../missing.json: file not found (run the stage that makes it first)
    """
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError("file not found (run the stage that makes it first)", file=path) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON ({exc.msg} at line {exc.lineno})", file=path) from None


def write_frame(path: str | Path, frame: pd.DataFrame, meta: dict[str, Any] | None = None) -> Path:
    """Write a data frame as Parquet atomically, with ``meta`` (JSON) in the schema metadata.

    Parameters
    ----------
    path : str or Path
        The Parquet file; written to a temporary name and renamed.
    frame : pandas.DataFrame
        The table (its index is not stored).
    meta : dict, optional
        JSON-able metadata, stored under the schema key ``tanktest.run``.

    Returns
    -------
    Path
        ``path``.
    """
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
    """Read a Parquet file written by :func:`write_frame`.

    Parameters
    ----------
    path : str or Path
        The Parquet file.

    Returns
    -------
    tuple
        (pandas.DataFrame, dict): the table and its ``tanktest.run`` metadata ({} when none).

    Raises
    ------
    InputError
        One line naming the file when it is missing, not Parquet, or its metadata is damaged.
    """
    path = Path(path)
    table = _parquet(pq.read_table, path)
    return table.to_pandas(), _run_meta(table.schema.metadata, path)


def _parquet(reader, path: Path):
    """``reader(path)`` (pyarrow's read_table or read_schema), its failures one line naming the file."""
    try:
        return reader(path)
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (pa.ArrowInvalid, OSError) as exc:
        raise InputError(f"not a readable Parquet file ({exc})", file=path) from None


def _run_meta(md: dict | None, path: Path) -> dict[str, Any]:
    """The ``tanktest.run`` JSON of a Parquet schema's metadata ({} when there is none)."""
    md = md or {}
    if RUN_META_KEY not in md:
        return {}
    try:
        meta = json.loads(md[RUN_META_KEY])
    except (ValueError, UnicodeDecodeError):
        raise InputError("the run metadata (tanktest.run) is not valid JSON: the file is damaged; "
                         "ingest the raw file again", file=path) from None
    if not isinstance(meta, dict):
        raise InputError("the run metadata (tanktest.run) is not a JSON object: the file is damaged; "
                         "ingest the raw file again", file=path)
    return meta


def read_meta(path: str | Path) -> dict[str, Any] | None:
    """The run metadata of a Parquet file, read from its schema only; None when the file has none
    (a Parquet file that is not a processed run).  Raises :class:`InputError` naming the file when it
    is not readable Parquet or its metadata is damaged."""
    path = Path(path)
    schema = _parquet(pq.read_schema, path)
    if RUN_META_KEY not in (schema.metadata or {}):
        return None
    return _run_meta(schema.metadata, path)


def write_run(path: str | Path, run: Run) -> Path:
    """Write a processed run (docs/contract.md#run-data) atomically.

    Parameters
    ----------
    path : str or Path
        The Parquet file (``runs/<run_id>.parquet`` in a dataset).
    run : Run
        The run; its ``meta`` goes into the file's schema metadata.

    Returns
    -------
    Path
        ``path``.
    """
    return write_frame(path, run.frame, run.meta)


def read_run(path: str | Path) -> Run:
    """Read a processed run and check it has the required columns.

    Parameters
    ----------
    path : str or Path
        A Parquet file written by :func:`write_run`.

    Returns
    -------
    Run
        The run (canonical columns in the units of docs/contract.md#run-data); ``meta["run_id"]``
        defaults to the file's stem.

    Raises
    ------
    InputError
        Naming the file (and column) when it is unreadable or lacks time, psi, r or delta.

    Examples
    --------
    >>> import pandas as pd
    >>> folder = Path(tempfile.mkdtemp())
    >>> frame = pd.DataFrame({"time": [0.0, 0.08], "psi": [0.0, 0.08], "r": [1.0, 1.0], "delta": [5.0, 5.0]})
    >>> path = write_run(folder / "zz_20_s.parquet", Run(frame=frame, meta={"dt": 0.08}))
    >>> run = read_run(path)
    >>> run.meta, run.frame.columns.tolist()
    ({'dt': 0.08, 'run_id': 'zz_20_s'}, ['time', 'psi', 'r', 'delta'])
    """
    frame, meta = read_frame(path)
    for c in REQUIRED_COLUMNS:
        if c not in frame.columns:
            raise InputError("required column is missing from processed run", file=path, column=c)
    meta.setdefault("run_id", Path(path).stem)
    return Run(frame=frame, meta=meta)
