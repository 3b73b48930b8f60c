"""Build every dataset stage by stage, rerunning only what is out of date (what ``make pipeline`` runs).

Why in Python and not in make: dataset and file names come from the user's folders, and a name
such as ``x$(touch X)`` or ``my runs`` must never become a word of a shell recipe.  Here names are
only ever values: each stage runs in this process through the Python API (:func:`pipeline.api.run`),
its settings given as keyword values, never as words of a command line or a shell.

Datasets (:func:`discover`): ``virtual`` (the built-in tank, always), ``hsva`` (the measured KVLCC2
zigzags, when ``<shared>/data/kvlcc2_hsva/*.dat`` exists), every folder ``data/raw/<name>/``, and
``local`` for tank files dropped straight into ``data/raw/``.

Staleness (:func:`up_to_date`): each stage of a dataset has a stamp ``data/processed/<name>/.stamps/<stage>``
holding the SHA-256 of (a) the content of every input file (raw files, or the upstream stages'
output folders) and (b) the source of every ``pipeline`` module the stage's command imports,
directly or indirectly, and of the API that calls it (pipeline/api.py), found by reading the imports
of the code (:func:`import_closure`; function-level imports count).  So a change to
``pipeline/config.py``, ``model.py``, ``io.py``, ``cli/`` or any module a stage uses reruns that stage
and everything downstream; nothing else reruns.  The stamp's
second line is the SHA-256 of the stage's own outputs as it left them (:func:`output_key`): an output
deleted, truncated or edited since reruns the stage.  A stage's ``timing.json`` is in neither hash.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from pipeline.api import STAGE_DIRS, result_files
from pipeline.catalog import TIMING_FILE
from pipeline.progress import heartbeat

PACKAGE_DIR = Path(__file__).resolve().parent
VIRTUAL, HSVA, LOCAL = "virtual", "hsva", "local"


# ------------------------------------------------------------------------------------ datasets
@dataclass(frozen=True)
class Dataset:
    name: str
    raw: Path              # folder holding the raw files
    described_in: Path | None = None   # raw root holding <name>/dataset.toml, when not raw's parent


def is_tank_file(path: Path) -> bool:
    """A file that may be tank data: a regular file that ingest would not skip
    (:func:`pipeline.dataset.is_tank_file`: not README.md, dataset.toml, stamps, notebooks, hidden files)."""
    from pipeline.dataset import is_tank_file as named_like_tank_data

    return path.is_file() and named_like_tank_data(path)


def raw_root(ds: Dataset) -> Path:
    """The raw root the dataset's description is found under (pipeline.dataset.load_dataset): the
    folder itself for 'local' (files straight in data/raw), else its parent; for 'hsva', whose files
    are in the shared folder, the project's raw root (data/raw/hsva/dataset.toml)."""
    if ds.described_in is not None:
        return ds.described_in
    return ds.raw if ds.name == LOCAL else ds.raw.parent


def raw_files(ds: Dataset) -> list[Path]:
    """The dataset's raw tank files, sorted.  A user's folder with a dataset.toml: the files its
    description names (``files_dir``, the ``files`` globs, less the runs marked ``skip``:
    :meth:`pipeline.dataset.Dataset.raw_files`), as ``ingest --dataset NAME`` reads them; otherwise
    the top level of its folder (the built-in datasets' folders are their files' own).  The
    description decides, not the folder's listing: files behind a ``files_dir`` are found, files
    its globs leave out are not ingested (tests/test_build.py)."""
    if not ds.raw.is_dir():
        return []
    if ds.name not in (VIRTUAL, HSVA) and (ds.raw / "dataset.toml").is_file():
        from pipeline.dataset import load_dataset

        described = load_dataset(ds.name, raw_root(ds), write_missing=False)
        return sorted(described.raw_files(), key=lambda p: p.name)
    return sorted(p for p in ds.raw.iterdir() if is_tank_file(p))


def discover(raw_root: Path = Path("data/raw"), shared: Path = Path("../shared")) -> list[Dataset]:
    """Every dataset the pipeline builds, in order: virtual, hsva (if present), folders, local."""
    raw_root = Path(raw_root)
    out = [Dataset(VIRTUAL, raw_root / VIRTUAL)]
    hsva = Path(shared) / "data" / "kvlcc2_hsva"
    if hsva.is_dir() and any(hsva.glob("*.dat")):
        out.append(Dataset(HSVA, hsva, described_in=raw_root))
    if raw_root.is_dir():
        for d in sorted(p for p in raw_root.iterdir() if p.is_dir() and not p.name.startswith(".")):
            if d.name not in (VIRTUAL, HSVA, LOCAL):
                out.append(Dataset(d.name, d))
        if any(is_tank_file(p) for p in raw_root.iterdir()):
            out.append(Dataset(LOCAL, raw_root))
    return out


# ------------------------------------------------------------------------- code the stages import
def _module_file(name: str) -> Path | None:
    parts = name.split(".")
    if parts[0] != "pipeline":
        return None
    base = PACKAGE_DIR.joinpath(*parts[1:])
    for cand in (base.with_suffix(".py"), base / "__init__.py"):
        if cand.is_file():
            return cand
    return None


def _imports(path: Path, module: str) -> set[str]:
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    return set(_imports_of_source(path.read_text(encoding="utf-8"), package))


@functools.lru_cache(maxsize=1024)
def _imports_of_source(text: str, package: str) -> frozenset[str]:
    """The pipeline modules a module's source text imports (keyed on the text itself, so an edited
    file is parsed again and an unchanged one once per process)."""
    tree = ast.parse(text)
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            found.add(mod)
            found.update(f"{mod}.{a.name}" for a in node.names)   # "from pkg import module"
    return frozenset(m for m in found if m.split(".")[0] == "pipeline")


def import_closure(*modules: str) -> list[Path]:
    """Source files of ``modules`` and of every pipeline module they import, transitively (sorted).

    Parent packages count too (importing ``pipeline.a.b`` runs ``pipeline/__init__.py`` and
    ``pipeline/a/__init__.py``).
    """
    seen: dict[str, Path] = {}
    todo = list(modules)
    while todo:
        name = todo.pop()
        parts = name.split(".")
        for k in range(1, len(parts) + 1):
            sub = ".".join(parts[:k])
            if sub in seen:
                continue
            path = _module_file(sub)
            if path is None:
                continue
            seen[sub] = path
            todo.extend(_imports(path, sub))
    return sorted(set(seen.values()))


# ------------------------------------------------------------------------------------- stages
#: the options of one call of a stage through :func:`pipeline.api.run` (besides dataset and root)
Options = dict[str, object]


def _once(ds: Dataset, root: Path) -> list[Options]:
    return [{}]


@dataclass(frozen=True)
class Stage:
    name: str
    module: str                      # the CLI module whose import closure the stage depends on
    after: tuple[str, ...]           # stages whose outputs it reads
    outputs: tuple[str, ...]         # files (under data/processed/<name>/) that must exist afterwards
    # the calls of the stage for a dataset: one :func:`pipeline.api.run` per options set
    calls: Callable[[Dataset, Path], list[Options]] = field(default=_once, compare=False)


def _ingest_calls(ds: Dataset, root: Path) -> list[Options]:
    """The ingest call of a dataset: its files, and the raw root its dataset.toml is found under (the
    folder itself for 'local', else its parent, so that a ``run --raw DIR`` applies the description
    under DIR, its scale included)."""
    return [{"files": raw_files(ds), "out": Path(root) / ds.name / "runs", "raw": raw_root(ds)}]


STAGES: tuple[Stage, ...] = (
    Stage("ingest", "pipeline.cli.ingest", (), ("runs/index.json",), _ingest_calls),
    Stage("identify", "pipeline.cli.identify", ("ingest",),
          ("identify/srukf-ffm/estimates.json", "identify/ffm-ukf/estimates.json"),
          lambda ds, root: [{"algorithm": a} for a in ("srukf-ffm", "ffm-ukf")]),
    Stage("validate", "pipeline.cli.validate", ("ingest", "identify"), ("validate/metrics.json",)),
    Stage("indices", "pipeline.cli.indices", ("ingest", "identify"), ("indices/indices.json",)),
    Stage("control", "pipeline.cli.control", ("ingest", "identify", "indices"), ("control/metrics.json",)),
    Stage("diagnose", "pipeline.cli.diagnose", ("ingest",), ("diagnose/diagnosis.json",)),
)


def _hash_files(h, files: Sequence[tuple[str, Path]]) -> None:
    for rel, path in files:
        h.update(rel.encode("utf-8", "surrogateescape") + b"\0")
        with open(path, "rb") as fh:
            for chunk in iter(lambda fh=fh: fh.read(1 << 20), b""):
                h.update(chunk)
        h.update(b"\0")


def _code(paths: Sequence[Path]) -> list[tuple[str, Path]]:
    return [(str(p.relative_to(PACKAGE_DIR)) if PACKAGE_DIR in p.parents else p.name, p) for p in paths]


def stage_key(stage: Stage, ds: Dataset, root: Path) -> str:
    """SHA-256 of everything the stage's output depends on (inputs' content, code, argv)."""
    h = hashlib.sha256()
    code = import_closure(stage.module, "pipeline.cli", "pipeline.api")
    _hash_files(h, _code(code))
    if stage.name == "ingest":
        _hash_files(h, [(p.name, p) for p in raw_files(ds)])
        h.update(b"dataset.toml\0" + _description(ds) + b"\0")
    elif stage.name == "control":        # its [control] table (docs/control.md) is read from dataset.toml
        h.update(b"dataset.toml\0" + _description(ds) + b"\0")
    for up in stage.after:
        _hash_files(h, _stage_files(Path(root) / ds.name / STAGE_DIRS[up]))
    for options in stage.calls(ds, root):
        h.update(_canonical(options).encode("utf-8", "surrogateescape") + b"\n")
    return h.hexdigest()


def _canonical(options: Options) -> str:
    """One text for a call's options (keys sorted, paths and lists of paths as strings)."""
    def plain(v):
        return [plain(x) for x in v] if isinstance(v, (list, tuple)) else str(v) if isinstance(v, Path) else v

    return json.dumps({k: plain(v) for k, v in sorted(options.items())}, ensure_ascii=False)


def _description(ds: Dataset) -> bytes:
    """The dataset description ingest reads (pipeline.dataset.load_dataset): its dataset.toml under
    the raw root, else the built-in text, else nothing."""
    from pipeline.dataset import BUILTIN, TOML_NAME, dataset_folder

    path = dataset_folder(ds.name, raw_root(ds)) / TOML_NAME
    if path.is_file():
        return path.read_bytes()
    return BUILTIN.get(ds.name, "").encode()


def _stamp(ds: Dataset, root: Path, stage: Stage) -> Path:
    return Path(root) / ds.name / ".stamps" / stage.name


def output_key(stage: Stage, ds: Dataset, root: Path) -> str:
    """SHA-256 of every file the stage wrote (names and bytes, its folder ``STAGE_DIRS[stage]``, hidden
    files and ``timing.json`` left out): a file deleted, truncated or edited since changes it."""
    h = hashlib.sha256()
    _hash_files(h, _stage_files(Path(root) / ds.name / STAGE_DIRS[stage.name]))
    return h.hexdigest()


def _stage_files(d: Path) -> list[tuple[str, Path]]:
    """(name under the dataset, path) of a stage folder's result files, sorted; the stage's
    ``timing.json`` (how long it took, not what it found: docs/operations.md) is not one of them."""
    return [(str(p.relative_to(d.parent)), p) for p in result_files(d)]


def up_to_date(stage: Stage, ds: Dataset, root: Path) -> bool:
    """True when the stamp holds the stage's current input key and the key of the outputs as the stage
    left them: a missing, truncated or edited output reruns the stage (and what reads it)."""
    stamp = _stamp(ds, root, stage)
    if not stamp.is_file() or not all((Path(root) / ds.name / o).is_file() for o in stage.outputs):
        return False
    lines = stamp.read_text().split()
    return lines == [stage_key(stage, ds, root), output_key(stage, ds, root)]


def _write_stamp(stage: Stage, ds: Dataset, root: Path) -> None:
    from pipeline.io import atomic_path

    with atomic_path(_stamp(ds, root, stage)) as tmp:
        tmp.write_text(f"{stage_key(stage, ds, root)}\n{output_key(stage, ds, root)}\n")


def tank_up_to_date(raw: Path) -> bool:
    stamp = raw / ".stamp"
    return stamp.is_file() and stamp.read_text().strip() == _tank_key() and any(raw.glob("*.csv"))


def _tank_key() -> str:
    h = hashlib.sha256()
    _hash_files(h, _code(import_closure("pipeline.cli.tank", "pipeline.tank")))
    return h.hexdigest()


def _write_timing(ds: Dataset, root: Path, stage: str, seconds: float, status: str) -> None:
    """Record a stage's wall time (s) in ``ROOT/NAME/timing.json`` (``{"dataset", "stages": {stage:
    {"seconds", "status"}}}``, the other stages' entries kept): the one place a build's timings go,
    outside every folder that is hashed or compared (docs/operations.md)."""
    from pipeline.io import write_json

    path = Path(root) / ds.name / TIMING_FILE
    try:
        doc = json.loads(path.read_text())
        stages = doc["stages"] if isinstance(doc, dict) and isinstance(doc.get("stages"), dict) else {}
    except (OSError, ValueError):
        stages = {}                                  # none yet, or torn: timings are not results
    stages[stage] = {"seconds": round(seconds, 3), "status": status}
    order = {s.name: i for i, s in enumerate(STAGES)}
    write_json(path, {"dataset": ds.name,
                      "stages": dict(sorted(stages.items(), key=lambda kv: order.get(kv[0], 99)))})


#: runs one call of a stage: ``(stage, dataset or None, options) -> exit status`` (0 = done)
Runner = Callable[[str, "str | None", Options], int]


def run_stage(stage: str, dataset: str | None, options: Options) -> int:
    """One stage call through :func:`pipeline.api.run`, in this process: 0 when done; a refusal or a
    failure is its one line ``error: ...`` on stderr (as the command line prints it) and status 2."""
    from pipeline.api import run
    from pipeline.cli import error_status
    from pipeline.errors import PipelineError

    try:
        run(stage, dataset, echo=True, **options)
    except (PipelineError, OSError) as exc:
        return error_status(exc)
    return 0


def build_dataset(ds: Dataset, root: Path = Path("data/processed"), *, until: str | None = None,
                  run: Runner = run_stage,
                  say: Callable[[str], None] = print,
                  on_stage: Callable[[str, str, str, float], None] | None = None) -> list[str]:
    """Bring every stage of ``ds`` up to date (up to and including ``until``); returns the stages run.

    Each stage run is said twice (its start, then its status and wall time in s), with a heartbeat
    line every 30 s between in a log (:func:`pipeline.progress.heartbeat`); its time is kept in
    ``ROOT/NAME/timing.json`` (:func:`_write_timing`) and handed to ``on_stage(dataset, stage, status,
    seconds)``.

    ``run`` executes one call of a stage (default :func:`run_stage`, the Python API in this process:
    ``(stage, dataset, options)``, the dataset's name only ever a value).  A stage whose call fails
    stops only the stages that read its outputs (directly or not, ``Stage.after``): the others
    still run, as ``make -k`` would (a campaign of turning circles alone has no zigzag to identify
    from, and its diagnosis needs none).  Then :class:`pipeline.errors.PipelineError` names the
    dataset, the failed stage, the stages not run and those that ran.
    """
    from pipeline.errors import InputError, PipelineError

    names = [s.name for s in STAGES]
    if until is not None and until not in names:
        raise InputError(f"unknown stage {until!r} (known: {', '.join(names)})")
    stages = STAGES[: names.index(until) + 1] if until else STAGES
    if ds.name == VIRTUAL and not tank_up_to_date(ds.raw):
        say(f"[{ds.name}] tank")
        if run("tank", None, {"out": ds.raw}) != 0:
            raise PipelineError(f"dataset {ds.name!r}: stage tank failed (see above)")
        from pipeline.io import atomic_path

        with atomic_path(ds.raw / ".stamp") as tmp:
            tmp.write_text(_tank_key() + "\n")
    if not raw_files(ds):
        raise InputError(f"dataset {ds.name!r}: no tank files in {ds.raw}")
    if ds.name not in (VIRTUAL, HSVA) and not (ds.raw / "dataset.toml").is_file():
        # a user's folder without a description: say what is assumed and write one beside the files
        # to edit, as `ingest --dataset NAME` does (ingest is handed the files here, and was silent),
        # and before ingest's key is formed, so that the next build finds it unchanged
        from pipeline.dataset import load_dataset

        load_dataset(ds.name, raw_root(ds), notice=lambda line: say(f"[{ds.name}] {line}"))
    done: list[str] = []
    failed: list[tuple[str, int]] = []
    blocked: list[str] = []
    for stage in stages:
        if any(u in blocked or u in dict(failed) for u in stage.after):
            blocked.append(stage.name)
            continue
        if up_to_date(stage, ds, root):
            continue
        say(f"[{ds.name}] {stage.name}")
        code = 0
        t0 = time.perf_counter()
        with heartbeat(f"[{ds.name}] {stage.name}"):
            for options in stage.calls(ds, root):
                code = run(stage.name, ds.name, {"root": Path(root), **options})
                if code != 0:
                    break
        secs = time.perf_counter() - t0
        status = "ran" if code == 0 else f"failed (exit {code})"
        say(f"[{ds.name}] {stage.name} {status} in {secs:.1f} s")
        _write_timing(ds, root, stage.name, secs, status)
        if on_stage is not None:
            on_stage(ds.name, stage.name, status, secs)
        if code != 0:
            failed.append((stage.name, code))
            continue
        _write_stamp(stage, ds, root)
        done.append(stage.name)
    if failed:
        name, code = failed[0]
        more = "".join(f"; stage {n} failed too (exit {c})" for n, c in failed[1:])
        raise PipelineError(f"dataset {ds.name!r}: stage {name} failed (exit {code}, see above){more}"
                            + (f"; not run, they read its outputs: {', '.join(blocked)}" if blocked else "")
                            + (f"; ran {', '.join(done)}" if done else ""))
    return done
