"""Dataset descriptions: ``data/raw/<name>/dataset.toml`` (docs/dataset.md), typed.

A dataset is a folder of raw tank files.  Its ``dataset.toml`` (read with :mod:`tomllib`) says what
the files are.  The keys of docs/dataset.md, the project's own marked *::

    [ship]
    name = "KVLCC2"
    lpp_m = 320.0             # full-scale particulars, m
    beam_m = 58.0
    draught_m = 20.8
    design_speed_kn = 15.5

    [data]
    scale = 45.7              # full/model of the values in the files (1 for model-scale files)
    model_scale = 45.7        # * full/model of the tank model (default: scale); with model-scale files
                              #   (scale = 1) it gives the model's Lpp = lpp_m / model_scale
    tank = "MARIN"
    source = "SIMMAN 2008 free-running tests"
    files_dir = "."           # * where the raw files are, relative to this file (default: its folder)
    files = ["*.dat"]         # * glob patterns of the raw files (default: every tank file)
    format = "marin"          # * force a reader: csv, marin, hsva (default: recognised from content)
    rudder_sign = 1           # * -1 when the files' rudder is positive to port beyond the format's own
    provenance = "measured"   # * 'measured' or 'virtual'

    [roles]                   # optional; run ids (file names without extension)
    identify = "zz_20_s"
    train = ["zz_20_s", "zz_10_s"]
    validate = ["zz_20_p", "zz_10_p"]
    test = []

    [identify]                # * optional; the identification window, scale-free (one of):
    half_periods = 3.4        #   zigzag half-periods after the first execute (or window_s = 46.8, s
                              #   at model scale; or samples = 585, the paper setting and the default)
    measurement_noise = "data"  # R measured from the run ('paper': the paper's R, the default)
    process_noise = "data"    # Q matched to the run's innovations ('paper': the paper's Q, the default)

    [runs.zz_20_p]            # * per-run overrides (the id must be a run of the dataset)
    rudder_sign = -1
    test_name = "zigzag 20/20 port"
    kind = "zigzag"           # * the test when the file's title says none
    skip = false

    [columns]                 # a logger's own table (pipeline.ingest.columns)
    psi = {source = "Heading [rad]", unit = "rad", wrapped = true}

    [control]                 # the autopilot's settings (read by pipeline/control)

Unknown keys are refused (a misspelt key must not be ignored silently), and every key is checked
for its type and range: a description of the wrong shape is one line naming the file, the key and
what it must be.  docs/dataset.md lists every key with its type, unit and default.  A folder without the file
still runs with the defaults (model scale, ship unknown): :func:`load_dataset` says so in one line
and writes a short ``dataset.toml`` beside the files for the user to edit.

Dataset names (:func:`dataset_names`): ``virtual`` (the built-in tank, files in data/raw/virtual),
``hsva`` (the measured KVLCC2 zigzags, when ``../shared/data/kvlcc2_hsva`` exists), every folder
``data/raw/<name>/``, and ``local`` for tank files placed directly in ``data/raw/``.
The descriptions of ``virtual`` and ``hsva`` are :data:`BUILTIN`; the repository holds the same
text as data/raw/virtual/dataset.toml and data/raw/hsva/dataset.toml, and it is written back when
missing (``make clean`` keeps them: it removes only the virtual tank's generated runs).
"""

from __future__ import annotations

import fnmatch
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pipeline.config import KNOWN_SHIPS, IngestConfig
from pipeline.errors import InputError

TOML_NAME = "dataset.toml"
DEFAULT_RAW = Path("data/raw")
LOCAL = "local"
# Files in a data folder that are not tank data.
NOT_TANK_SUFFIXES = {".md", ".stamp", ".gitkeep", ".txt", ".json", ".pdf", ".png", ".toml", ".py", ".ipynb",
                     ".html", ".xlsx", ".xls", ".docx"}

BUILTIN: dict[str, str] = {
    "virtual": '''# The built-in virtual tank (pipeline.tank): KCS, SIMMAN 2020 deep-water case, model scale.
[ship]
name = "KCS"
lpp_m = 230.0
beam_m = 32.2
draught_m = 10.8
design_speed_kn = 24.0

[data]
scale = 1.0               # the tank writes model-scale values
model_scale = 37.89
tank = "virtual tank (3-DOF MMG model)"
source = "python -m pipeline tank"
provenance = "virtual"

[identify]
samples = 585             # the paper setting (the paper case: 20/20 zigzag at 0.08 s; 3.4 half-periods)
measurement_noise = "data"  # R from the runs' measured noise: the tank logs r and psi with 0.05 deg/s and
                          # 0.05 deg, 2.5 and 5 times the paper's R (the filter then gave mean NIS 18)
process_noise = "data"    # Q matched to the runs' innovations (docs/identification.md): the paper's Q
                          # leaves the mean NIS below its band on this hull
''',
    "hsva": f'''# Measured KVLCC2 zigzags, HSVA CPMC (SIMMAN 2008), model 1:{KNOWN_SHIPS.hsva_kvlcc2_scale:g}.
[ship]
name = "KVLCC2"
lpp_m = 320.0
beam_m = 58.0
draught_m = 20.8
design_speed_kn = 15.5

[data]
scale = 1.0               # the files are model scale
model_scale = {KNOWN_SHIPS.hsva_kvlcc2_scale:g}
tank = "HSVA"
source = "SIMMAN 2008 free-running tests (CPMC)"
files_dir = "../../../../shared/data/kvlcc2_hsva"   # relative to this file: ../shared from the project root
files = ["*.dat"]
format = "hsva"

[identify]
half_periods = 3.4        # the paper case's 585 samples are 3.4 half-periods of its 20/20 zigzag;
                          # the same share of this ship's zigzag (585 samples would be only 2.4 here)

[control]                 # the KVLCC2 model's steering gear and autopilot settings (docs/control.md)
tw_s = 5.9                # s; assumed: the paper's Tw = 3 s is one ship length of travel for the KCS model
                          # (Lpp 6.07 m at 2.0 m/s); the same Tw U/Lpp = 1 here is 7.0 m / 1.178 m/s
rudder_max_deg = 35.0     # deg; measured: the 35/5 zigzag reaches 35 deg (SIMMAN 2008 KVLCC2: 35 deg)
rudder_rate_deg_s = 15.6  # deg/s at model scale; measured: median rudder rate while moving in the 15/x to
                          # 35/5 files (2.3 deg/s at full scale; SIMMAN 2008 gives 2.34 deg/s)
servo_time_constant_s = 0.0   # s; assumed: no lag of the tank's steering gear is stated (the rate limit is)
dead_time_s = 0.0         # s; assumed: no command-to-rudder dead time is stated for the tank
setpoint_deg = 60.0       # deg; assumed: the paper's course change
''',
}


@dataclass(frozen=True)
class Ship:
    """Full-scale particulars (m, kn); None where not given."""

    name: str | None = None
    lpp_m: float | None = None
    beam_m: float | None = None
    draught_m: float | None = None
    design_speed_kn: float | None = None


@dataclass(frozen=True)
class Roles:
    identify: str | None = None
    train: tuple[str, ...] = ()
    validate: tuple[str, ...] = ()
    test: tuple[str, ...] = ()


@dataclass(frozen=True)
class IdentifySettings:
    """``[identify]``: the identification window (at most one of samples, window_s s at model scale,
    half_periods of the zigzag after its first execute) and where R comes from ('paper' or 'data').
    None: the identify stage's defaults (585 samples, the paper setting; R of the paper)."""

    samples: int | None = None
    window_s: float | None = None
    half_periods: float | None = None
    measurement_noise: str | None = None
    process_noise: str | None = None

    def as_dict(self) -> dict[str, Any]:
        return {k: v for k, v in (("samples", self.samples), ("window_s", self.window_s),
                                  ("half_periods", self.half_periods),
                                  ("measurement_noise", self.measurement_noise),
                                  ("process_noise", self.process_noise)) if v is not None}


@dataclass(frozen=True)
class RunOverride:
    """``[runs.<id>]``: the run's rudder sign (+1/-1), its test title (read as a file's title would
    be), whether to leave it out, and its kind when its title says none ('zigzag', 'turning', 'other')."""

    rudder_sign: int | None = None
    test_name: str | None = None
    skip: bool = False
    kind: str | None = None


@dataclass(frozen=True)
class Dataset:
    """One dataset: where its files are and what they are (module docstring)."""

    name: str
    folder: Path                          # data/raw/<name> (data/raw for 'local')
    files_dir: Path                       # where the raw files are
    ship: Ship = field(default_factory=Ship)
    scale: float = 1.0                    # full/model of the values in the files
    model_scale: float | None = None      # full/model of the tank model (None: same as scale)
    tank: str | None = None
    source: str | None = None
    files: tuple[str, ...] = ()           # glob patterns ('' = every tank file)
    format: str | None = None
    rudder_sign: int = 1
    provenance: str | None = None
    roles: Roles = field(default_factory=Roles)
    identify: IdentifySettings = field(default_factory=IdentifySettings)
    runs: dict[str, RunOverride] = field(default_factory=dict)
    control: dict[str, Any] = field(default_factory=dict)   # [control], read by pipeline/control
    columns: Any = None                   # [columns]: a pipeline.ingest.columns.ColumnMap, or None
    toml_path: Path | None = None         # None: nothing was read (defaults assumed)
    text: str | None = None               # the description's text as read (None: nothing was read)

    @property
    def lpp_model_m(self) -> float | None:
        """Model Lpp (m) = full-scale Lpp / model scale."""
        if self.ship.lpp_m is None:
            return None
        return self.ship.lpp_m / (self.model_scale or self.scale)

    def raw_files(self, *, with_skipped: bool = False) -> list[Path]:
        """The dataset's raw tank files, sorted by name (discovered here, never through a shell);
        those a ``[runs.<id>] skip = true`` leaves out only ``with_skipped``."""
        if not self.files_dir.is_dir():
            raise InputError("the dataset's files folder does not exist"
                             + (f" (files_dir in {self.toml_path})" if self.toml_path else ""),
                             file=self.files_dir)
        out = []
        for p in sorted(self.files_dir.iterdir(), key=lambda q: q.name):
            if not p.is_file() or not is_tank_file(p):
                continue
            if self.files and not any(fnmatch.fnmatch(p.name, g) for g in self.files):
                continue
            if self.runs.get(run_id_of(p), RunOverride()).skip and not with_skipped:
                continue
            out.append(p)
        return out

    def particulars(self) -> dict[str, Any]:
        """What runs/index.json and every run's metadata record about the ship and scale."""
        return {
            "ship": self.ship.name, "lpp_m": self.ship.lpp_m, "beam_m": self.ship.beam_m,
            "draught_m": self.ship.draught_m, "design_speed_kn": self.ship.design_speed_kn,
            "scale": self.scale, "model_scale": self.model_scale or self.scale,
            "lpp_model_m": self.lpp_model_m, "tank": self.tank, "source": self.source,
            "dataset_toml": str(self.toml_path) if self.toml_path else None,
        }


def run_id_of(path: Path) -> str:
    """Run id of a raw file: its name without the extension(s) ('zz.csv.gz' -> 'zz')."""
    name = path.name
    for suffix in (".gz",):
        if name.lower().endswith(suffix):
            name = name[: -len(suffix)]
    return Path(name).stem


def is_tank_file(path: Path) -> bool:
    """False for files in a data folder that are not tank data (README.md, dataset.toml, dotfiles, ...)."""
    return not (path.name.startswith(".") or path.suffix.lower() in NOT_TANK_SUFFIXES)


# ------------------------------------------------------------------ reading
# What each key must be: a short phrase for the message ("a positive number"), and a check that
# returns the value (converted) or raises TypeError/ValueError.  Every key's unit is in docs/dataset.md.
def _finite_positive(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise TypeError
    v = float(v)
    if not (math.isfinite(v) and v > 0):
        raise ValueError
    return v


def _integer(ok):
    """An integer check (booleans are not integers) with a range ``ok``."""
    def check(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            raise TypeError
        if not ok(v):
            raise ValueError
        return v
    return check


_positive_int = _integer(lambda v: v >= 1)
_sign = _integer(lambda v: v in (1, -1))


def _string(v: Any) -> str:
    if not isinstance(v, str):
        raise TypeError
    return v


def _string_list(v: Any) -> list[str]:
    if isinstance(v, str):
        return [v]
    if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
        raise TypeError
    return list(v)


def _boolean(v: Any) -> bool:
    if not isinstance(v, bool):
        raise TypeError
    return v


def _choice(*options: str):
    def check(v: Any) -> str:
        if not isinstance(v, str):
            raise TypeError
        if v not in options:
            raise ValueError
        return v
    return check


_POS = ("a positive finite number", _finite_positive)
_STR = ("a string", _string)
_STRS = ("a string or a list of strings", _string_list)
_SIGN = ("1 or -1 (an integer)", _sign)
_SECTIONS: dict[str, dict[str, tuple[str, Any]]] = {
    "ship": {"name": _STR, "lpp_m": _POS, "beam_m": _POS, "draught_m": _POS, "design_speed_kn": _POS},
    "data": {"scale": _POS, "model_scale": _POS, "tank": _STR, "source": _STR, "files_dir": _STR,
             "files": _STRS, "format": None, "rudder_sign": _SIGN,
             "provenance": ("'measured' or 'virtual'", _choice("measured", "virtual"))},
    "roles": {"identify": _STR, "train": _STRS, "validate": _STRS, "test": _STRS},
    "identify": {"samples": ("a positive integer (samples)", _positive_int), "window_s": _POS,
                 "half_periods": _POS,
                 "measurement_noise": ("'paper' or 'data'", _choice("paper", "data")),
                 "process_noise": ("'paper' or 'data'", _choice("paper", "data"))},
}
_RUN_KEYS: dict[str, tuple[str, Any]] = {
    "rudder_sign": _SIGN, "test_name": _STR, "skip": ("true or false", _boolean),
    "kind": ("'zigzag', 'turning' or 'other'", _choice("zigzag", "turning", "other")),
}
# Sections whose keys another module reads: [control] (the autopilot, pipeline/control) is checked
# here only for its shape (a table of numbers, strings or booleans); [columns] by pipeline.ingest.columns.
_OTHER_SECTIONS = ("control", "columns")
_KNOWN = ", ".join([*_SECTIONS, "runs", *_OTHER_SECTIONS])


def _what(value: Any) -> str:
    """A value named for a message without echoing a large or deep structure."""
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return f"an array of {len(value)}"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        shown = value[:30] + ("..." if len(value) > 30 else "")
        return f"the string {shown!r}"
    if isinstance(value, (int, float)):
        return f"{value!r}"
    return type(value).__name__


def _key(section: str, key: str) -> str:
    return f"[{section}] {key}" if section else key


def _checked(table: dict, keys: dict[str, tuple[str, Any] | None], section: str, path: Path) -> dict:
    out = {}
    for k, v in table.items():
        if k not in keys:
            raise InputError(f"unknown key {k!r} in [{section}] (known: {', '.join(keys)})", file=path)
        spec = keys[k]
        if spec is None:                         # checked by its reader below
            out[k] = v
            continue
        expected, check = spec
        try:
            out[k] = check(v)
        except (TypeError, ValueError):
            raise InputError(f"{_key(section, k)} must be {expected}, got {_what(v)}", file=path) from None
    return out


def _table(doc: dict, section: str, path: Path) -> dict:
    table = doc.get(section, {})
    if not isinstance(table, dict):
        raise InputError(f"{section} must be a table ([{section}]), got {_what(table)}", file=path)
    return table


def parse_dataset_toml(text: str, *, name: str, folder: Path, path: Path) -> Dataset:
    """A :class:`Dataset` from the text of a dataset.toml (``path`` for messages and files_dir).

    Every key is checked for its type and range: a description of the wrong shape is refused with
    one line naming the file, the key and what it must be (docs/dataset.md lists every key)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML ({exc})", file=path) from None
    except RecursionError:
        raise InputError("not a dataset description: tables or arrays nested too deep", file=path) from None
    for key, value in doc.items():
        if key not in _SECTIONS and key not in ("runs", *_OTHER_SECTIONS):
            what = f"section [{key}]" if isinstance(value, dict) else f"key {key!r}"
            raise InputError(f"unknown {what} (known sections: {_KNOWN})", file=path)
    vals = {sec: _checked(_table(doc, sec, path), keys, sec, path) for sec, keys in _SECTIONS.items()}
    if "control" in doc:                  # the autopilot's keys, checked by their owner (docs/control.md)
        from pipeline.control.settings import parse_control_table

        parse_control_table(_table(doc, "control", path), path)
    ship = Ship(**vals["ship"])
    data = vals["data"]
    scale = data.get("scale", 1.0)
    lo, hi = IngestConfig().scale_range
    for k in ("scale", "model_scale"):
        if k in data and not lo <= data[k] <= hi:
            raise InputError(f"[data] {k} must be a scale factor full/model between {lo:g} and {hi:g}, got "
                             f"{data[k]:g}", file=path)
    model_scale = data.get("model_scale")
    if scale != 1.0 and model_scale is not None and abs(model_scale - scale) > 1e-9 * scale:
        raise InputError(f"[data] scale {scale:g} (files at full scale) and model_scale {model_scale:g} "
                         "differ: full-scale files are brought to the model of that same scale", file=path)
    sign = data.get("rudder_sign", 1)
    fmt = data.get("format")
    if fmt is not None:
        from pipeline.ingest.formats import FORMATS

        if not isinstance(fmt, str) or fmt not in FORMATS:
            raise InputError(f"[data] format must be one of {', '.join(FORMATS)}, got {_what(fmt)}",
                             file=path)
    prov = data.get("provenance")
    files_dir = (path.parent / data["files_dir"]) if "files_dir" in data else folder
    r = vals["roles"]
    roles = Roles(identify=r.get("identify"), train=tuple(r.get("train", ())),
                  validate=tuple(r.get("validate", ())), test=tuple(r.get("test", ())))
    idv = vals["identify"]
    given = [k for k in ("samples", "window_s", "half_periods") if k in idv]
    if len(given) > 1:
        raise InputError(f"[identify] gives {' and '.join(given)}: give one identification window", file=path)
    ident = IdentifySettings(**idv)
    runs_table = _table(doc, "runs", path)
    runs: dict[str, RunOverride] = {}
    for rid, table in runs_table.items():
        if not isinstance(table, dict):
            raise InputError(f"runs.{rid} must be a table ([runs.{rid}] of per-run keys), got {_what(table)}",
                             file=path)
        runs[str(rid)] = RunOverride(**_checked(table, _RUN_KEYS, f"runs.{rid}", path))
    control = _table(doc, "control", path)
    for k, v in control.items():
        if isinstance(v, (dict, list)):
            raise InputError(f"[control] {k} must be a number, string or boolean, got {_what(v)}", file=path)
    columns = None
    if "columns" in doc:
        from pipeline.ingest.columns import parse_columns

        columns = parse_columns(_table(doc, "columns", path), path)
    return Dataset(name=name, folder=folder, files_dir=files_dir, ship=ship, scale=float(scale),
                   model_scale=model_scale, tank=data.get("tank"), source=data.get("source"),
                   files=tuple(data.get("files", ())), format=fmt, rudder_sign=sign, provenance=prov,
                   roles=roles, identify=ident, runs=runs, control=dict(control), columns=columns,
                   toml_path=path, text=text)


def check_run_ids(ds: Dataset, known: list[str] | set[str], *, roles: bool = True, runs: bool = True) -> None:
    """Refuse a ``[runs.<id>]`` (with ``runs``) or a role (with ``roles``) that names no run of
    ``known``; the message names the known ids."""
    known = set(known)
    shown = ", ".join(sorted(known)[:20]) + (" ..." if len(known) > 20 else "")
    for rid in (ds.runs if runs else ()):
        if rid not in known:
            raise InputError(f"[runs.{rid}] names no run of the dataset (run ids: {shown})",
                             file=ds.toml_path)
    if not roles:
        return
    r = ds.roles
    for role, ids in (("identify", (r.identify,) if r.identify else ()), ("train", r.train),
                      ("validate", r.validate), ("test", r.test)):
        for rid in ids:
            if rid not in known:
                raise InputError(f"[roles] {role} names run {rid!r}, which the dataset has not (run ids: "
                                 f"{shown})", file=ds.toml_path)


def dataset_folder(name: str, raw_root: Path = DEFAULT_RAW) -> Path:
    """``data/raw/<name>`` (``data/raw`` itself for 'local').  Names are single folder names."""
    if name == LOCAL:
        return Path(raw_root)
    if not name or name in (".", "..") or "/" in name or "\\" in name or "\0" in name:
        raise InputError(f"dataset name {name!r} is not a single folder name")
    return Path(raw_root) / name


ASSUMED_TOML = '''# Written by `python -m pipeline ingest` because this folder had no dataset.toml.
# It records what was assumed; edit it to describe your files (README: "Your own files").
[ship]
# name = "MYSHIP"
# lpp_m = 100.0           # full-scale particulars, m
# beam_m = 16.0
# draught_m = 6.0
# design_speed_kn = 14.0

[data]
scale = 1.0               # ASSUMED: the files are model scale (full-scale files: the scale factor)
# model_scale = 25.0      # the tank model's scale (with model-scale files, gives its Lpp)
# tank = "my tank"
# source = "free-running tests"

# [identify]              # the identification window, scale-free (default: 585 samples, the paper's)
# half_periods = 3.4      # zigzag half-periods after the first execute (or window_s = 46.8, model s)
# measurement_noise = "data"   # R measured from the run (default "paper": the paper's R)
# process_noise = "data"       # Q matched to the run's innovations (default "paper": the paper's Q)
'''


def load_dataset(name: str, raw_root: Path = DEFAULT_RAW, *, write_missing: bool = True,
                 notice=None) -> Dataset:
    """The description of dataset ``name`` (module docstring).

    Without a dataset.toml: built-in datasets use :data:`BUILTIN` (and write it back); any other
    folder gets the defaults, ``notice`` (a callable taking one line) is told what was assumed, and a
    short dataset.toml is written beside the files (``write_missing``) for the user to edit.
    """
    folder = dataset_folder(name, raw_root)
    path = folder / TOML_NAME
    if path.is_file():
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read ({exc})", file=path) from None
        return parse_dataset_toml(text, name=name, folder=folder, path=path)
    if name in BUILTIN:
        if write_missing and folder.is_dir():
            _write_text(path, BUILTIN[name])
        return parse_dataset_toml(BUILTIN[name], name=name, folder=folder, path=path)
    if not folder.is_dir():
        raise InputError(f"no dataset {name!r}: folder {folder} does not exist "
                         "(`python -m pipeline datasets` lists them)")
    wrote = False
    if write_missing:
        wrote = _write_text(path, ASSUMED_TOML)
    if notice is not None:
        notice(f"dataset {name!r}: no {TOML_NAME} in {folder}: assumed model-scale files (scale 1), ship "
               f"and particulars unknown, format recognised per file"
               + (f"; wrote {path} to edit" if wrote else ""))
    return Dataset(name=name, folder=folder, files_dir=folder, toml_path=None)


def _write_text(path: Path, text: str) -> bool:
    from pipeline.io import atomic_path

    try:
        with atomic_path(path, suffix=".toml") as tmp:
            tmp.write_text(text, encoding="utf-8")
    except OSError:
        return False
    return True


def dataset_names(raw_root: Path = DEFAULT_RAW, shared: Path | None = None) -> list[str]:
    """Every dataset that can run now, in build order: the names :func:`pipeline.build.discover`
    finds (virtual; hsva when ``shared``/data/kvlcc2_hsva holds its files; each folder of
    ``raw_root``; 'local' when tank files sit directly in ``raw_root``).

    Parameters
    ----------
    raw_root : pathlib.Path
        The raw-data root (default data/raw).
    shared : pathlib.Path, optional
        The shared folder with data/kvlcc2_hsva (default ../shared, as the build's).

    Returns
    -------
    list of str
        The names, each a valid ``--dataset NAME``.
    """
    from pipeline.build import discover

    found = discover(raw_root) if shared is None else discover(raw_root, shared)
    return [d.name for d in found]
