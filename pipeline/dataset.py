"""Dataset descriptions: ``data/raw/<name>/dataset.toml`` (SPEC section 9), typed.

A dataset is a folder of raw tank files.  Its ``dataset.toml`` (read with :mod:`tomllib`) says what
the files are.  The SPEC keys, and the project's own (marked *)::

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

    [runs.zz_20_p]            # * per-run overrides
    rudder_sign = -1
    test_name = "zigzag 20/20 port"
    skip = false

Unknown keys are refused (a misspelt key must not be ignored silently).  A folder without the file
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
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
''',
    "hsva": '''# Measured KVLCC2 zigzags, HSVA CPMC (SIMMAN 2008), model 1:45.7.
[ship]
name = "KVLCC2"
lpp_m = 320.0
beam_m = 58.0
draught_m = 20.8
design_speed_kn = 15.5

[data]
scale = 1.0               # the files are model scale
model_scale = 45.7
tank = "HSVA"
source = "SIMMAN 2008 free-running tests (CPMC)"
files_dir = "../../../../shared/data/kvlcc2_hsva"   # relative to this file: ../shared from the project root
files = ["*.dat"]
format = "hsva"

[identify]
half_periods = 3.4        # the paper case's 585 samples are 3.4 half-periods of its 20/20 zigzag;
                          # the same share of this ship's zigzag (585 samples would be only 2.4 here)
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

    def as_dict(self) -> dict[str, Any]:
        return {k: v for k, v in (("samples", self.samples), ("window_s", self.window_s),
                                  ("half_periods", self.half_periods),
                                  ("measurement_noise", self.measurement_noise)) if v is not None}


@dataclass(frozen=True)
class RunOverride:
    rudder_sign: int | None = None
    test_name: str | None = None
    skip: bool = False


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
    toml_path: Path | None = None         # None: nothing was read (defaults assumed)

    @property
    def lpp_model_m(self) -> float | None:
        """Model Lpp (m) = full-scale Lpp / model scale."""
        if self.ship.lpp_m is None:
            return None
        return self.ship.lpp_m / (self.model_scale or self.scale)

    def raw_files(self) -> list[Path]:
        """The dataset's raw tank files, sorted by name (discovered here, never through a shell)."""
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
            if self.runs.get(run_id_of(p), RunOverride()).skip:
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
_SECTIONS = {
    "ship": {"name": str, "lpp_m": float, "beam_m": float, "draught_m": float, "design_speed_kn": float},
    "data": {"scale": float, "model_scale": float, "tank": str, "source": str, "files_dir": str,
             "files": list, "format": str, "rudder_sign": int, "provenance": str},
    "roles": {"identify": str, "train": list, "validate": list, "test": list},
    "identify": {"samples": int, "window_s": float, "half_periods": float, "measurement_noise": str},
}
_RUN_KEYS = {"rudder_sign": int, "test_name": str, "skip": bool}


def _typed(value: Any, typ: type, where: str, path: Path) -> Any:
    if typ is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if typ is list and isinstance(value, str):
        value = [value]
    if not isinstance(value, typ) or (typ is int and isinstance(value, bool)):
        raise InputError(f"{where} must be {typ.__name__}, got {value!r}", file=path)
    if typ is list and not all(isinstance(v, str) for v in value):
        raise InputError(f"{where} must be a list of strings", file=path)
    return value


def parse_dataset_toml(text: str, *, name: str, folder: Path, path: Path) -> Dataset:
    """A :class:`Dataset` from the text of a dataset.toml (``path`` for messages and files_dir)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML ({exc})", file=path) from None
    for key in doc:
        if key not in _SECTIONS and key not in ("runs", "control"):
            raise InputError(f"unknown section [{key}] (known: ship, data, roles, identify, control, runs)",
                             file=path)
    if "control" in doc:                  # the autopilot's keys, checked by their owner (docs/control.md)
        from pipeline.control.settings import parse_control_table

        parse_control_table(doc["control"], path)
    vals: dict[str, dict[str, Any]] = {}
    for sec, keys in _SECTIONS.items():
        table = doc.get(sec, {})
        if not isinstance(table, dict):
            raise InputError(f"[{sec}] must be a table", file=path)
        vals[sec] = {}
        for k, v in table.items():
            if k not in keys:
                raise InputError(f"unknown key {k!r} in [{sec}] (known: {', '.join(keys)})", file=path)
            vals[sec][k] = _typed(v, keys[k], f"[{sec}] {k}", path)
    ship = Ship(**vals["ship"])
    for k in ("lpp_m", "beam_m", "draught_m", "design_speed_kn"):
        v = getattr(ship, k)
        if v is not None and not v > 0:
            raise InputError(f"[ship] {k} must be positive, got {v}", file=path)
    data = vals["data"]
    scale = data.get("scale", 1.0)
    if not scale > 0:
        raise InputError(f"[data] scale must be positive, got {scale}", file=path)
    model_scale = data.get("model_scale")
    if model_scale is not None and not model_scale > 0:
        raise InputError(f"[data] model_scale must be positive, got {model_scale}", file=path)
    if scale != 1.0 and model_scale is not None and abs(model_scale - scale) > 1e-9 * scale:
        raise InputError(f"[data] scale {scale:g} (files at full scale) and model_scale {model_scale:g} "
                         "differ: full-scale files are brought to the model of that same scale", file=path)
    sign = data.get("rudder_sign", 1)
    if sign not in (1, -1):
        raise InputError(f"[data] rudder_sign must be 1 or -1, got {sign}", file=path)
    fmt = data.get("format")
    if fmt is not None:
        from pipeline.ingest.formats import FORMATS

        if fmt not in FORMATS:
            raise InputError(f"[data] format must be one of {', '.join(FORMATS)}, got {fmt!r}", file=path)
    prov = data.get("provenance")
    if prov is not None and prov not in ("measured", "virtual"):
        raise InputError(f"[data] provenance must be 'measured' or 'virtual', got {prov!r}", file=path)
    files_dir = (path.parent / data["files_dir"]) if "files_dir" in data else folder
    r = vals["roles"]
    roles = Roles(identify=r.get("identify"), train=tuple(r.get("train", ())),
                  validate=tuple(r.get("validate", ())), test=tuple(r.get("test", ())))
    idv = vals["identify"]
    given = [k for k in ("samples", "window_s", "half_periods") if k in idv]
    if len(given) > 1:
        raise InputError(f"[identify] gives {' and '.join(given)}: give one identification window", file=path)
    for k in given:
        if not idv[k] > 0:
            raise InputError(f"[identify] {k} must be positive, got {idv[k]}", file=path)
    if idv.get("measurement_noise", "paper") not in ("paper", "data"):
        raise InputError(f"[identify] measurement_noise must be 'paper' or 'data', got "
                         f"{idv['measurement_noise']!r}", file=path)
    ident = IdentifySettings(**idv)
    runs: dict[str, RunOverride] = {}
    for rid, table in (doc.get("runs") or {}).items():
        if not isinstance(table, dict):
            raise InputError(f"[runs.{rid}] must be a table", file=path)
        kw = {}
        for k, v in table.items():
            if k not in _RUN_KEYS:
                raise InputError(f"unknown key {k!r} in [runs.{rid}] (known: {', '.join(_RUN_KEYS)})",
                                 file=path)
            kw[k] = _typed(v, _RUN_KEYS[k], f"[runs.{rid}] {k}", path)
        if kw.get("rudder_sign", 1) not in (1, -1):
            raise InputError(f"[runs.{rid}] rudder_sign must be 1 or -1", file=path)
        runs[str(rid)] = RunOverride(**kw)
    return Dataset(name=name, folder=folder, files_dir=files_dir, ship=ship, scale=float(scale),
                   model_scale=model_scale, tank=data.get("tank"), source=data.get("source"),
                   files=tuple(data.get("files", ())), format=fmt, rudder_sign=sign, provenance=prov,
                   roles=roles, identify=ident, runs=runs, toml_path=path)


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


def dataset_names(raw_root: Path = DEFAULT_RAW) -> list[str]:
    """Every dataset that can run now: virtual; hsva when its files exist; each folder of
    ``raw_root``; 'local' when tank files sit directly in ``raw_root``."""
    raw_root = Path(raw_root)
    names = ["virtual"]
    try:
        hsva = load_dataset("hsva", raw_root, write_missing=False)
        if hsva.files_dir.is_dir() and hsva.raw_files():
            names.append("hsva")
    except InputError:
        pass
    if raw_root.is_dir():
        for p in sorted(raw_root.iterdir(), key=lambda q: q.name):
            if p.is_dir() and not p.name.startswith((".", "_")) and p.name not in ("virtual", "hsva"):
                names.append(p.name)
        if any(p.is_file() and is_tank_file(p) for p in raw_root.iterdir()):
            names.append(LOCAL)
    return names
