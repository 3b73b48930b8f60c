"""The Python API: run a stage of a dataset in this process, get a typed result (docs/api.md).

The command line (``python -m pipeline STAGE ...``) and the build (``python -m pipeline run``, what
``make pipeline`` runs) call the same code: each stage's command function, given its settings as
Python values, never as words of an argument list.  A dataset name is only ever a value here: a name
starting with ``-`` or holding ``$``, spaces or ``#`` is just a name.

>>> import pipeline
>>> pipeline.stages()
('tank', 'ingest', 'identify', 'validate', 'indices', 'control', 'diagnose')

``run(stage, dataset, root=..., **options)``: the options are the command's own, by the names
``python -m pipeline STAGE --help`` gives them, ``-`` written ``_`` (``--no-plots`` is
``no_plots=True``, ``--algorithm srukf-ffm`` is ``algorithm="srukf-ffm"``).  A refused input raises
:class:`pipeline.errors.PipelineError` (its subclass :class:`~pipeline.errors.InputError` for bad
input), with the one-line message the command line prints.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pipeline.catalog import TIMING_FILE
from pipeline.errors import InputError, PipelineError

#: the folder (under ``ROOT/DATASET/``) each stage of a dataset writes, as one set
STAGE_DIRS: dict[str, str] = {"ingest": "runs", "identify": "identify", "validate": "validate",
                              "indices": "indices", "control": "control", "diagnose": "diagnose"}
#: the stages, in the order a dataset is built; ``tank`` (the virtual tank's raw files) comes first
STAGES: tuple[str, ...] = ("tank", *STAGE_DIRS)


@dataclass(frozen=True)
class StageResult:
    """What one stage wrote.

    Attributes
    ----------
    stage : str
        The stage (one of :func:`stages`).
    dataset : str or None
        The dataset, or None for ``tank`` (which writes raw files to a folder).
    folder : pathlib.Path
        The folder the stage wrote as one set (``ROOT/DATASET/<stage dir>``, or ``out``).
    files : tuple of pathlib.Path
        Every result file in ``folder`` (sorted; hidden files and ``timing.json`` left out).
    seconds : float
        Wall time of the stage in this process (s); not part of any result file.
    log : tuple of str
        The lines the stage said (what its command prints on stdout), in order.
    """

    stage: str
    dataset: str | None
    folder: Path
    files: tuple[Path, ...]
    seconds: float
    log: tuple[str, ...] = ()

    def path(self, name: str) -> Path:
        """The result file ``name`` (relative to :attr:`folder`, e.g. ``"srukf-ffm/estimates.json"``);
        :class:`~pipeline.errors.InputError` when the stage did not write it."""
        p = self.folder / name
        if p not in self.files:
            raise InputError(f"stage {self.stage} wrote no {name!r} (it wrote: "
                             f"{', '.join(str(f.relative_to(self.folder)) for f in self.files)})",
                             file=p)
        return p

    def json(self, name: str) -> Any:
        """The parsed JSON result file ``name`` (see :meth:`path`)."""
        return json.loads(self.path(name).read_text(encoding="utf-8"))


def stages() -> tuple[str, ...]:
    """The stages :func:`run` knows.

    Returns
    -------
    tuple of str
        Their names, in build order: ``"tank"`` (the virtual tank's runs), then ``"ingest"`` to
        ``"diagnose"``.
    """
    return STAGES


def _command(stage: str) -> argparse.ArgumentParser:
    from pipeline.cli import build_parser

    if stage not in STAGES:
        raise InputError(f"unknown stage {stage!r} (known: {', '.join(STAGES)})")
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return commands.choices[stage]


def _value(stage: str, action: argparse.Action, value: Any) -> Any:
    """An option's value as the command would have parsed it (paths as Path, choices checked)."""
    name = action.dest
    if action.nargs == 0:                                    # a switch (store_true)
        if not isinstance(value, bool):
            raise InputError(f"{stage}: option {name} is a switch, give True or False, not {value!r}")
        return value
    many = action.nargs in ("*", "+") or isinstance(action.nargs, int)
    items = list(value) if many and isinstance(value, (list, tuple)) else [value]
    out = []
    for v in items:
        if v is not None and action.type is not None and isinstance(v, str):
            try:
                v = action.type(v)
            except (TypeError, ValueError):
                raise InputError(f"{stage}: option {name}: {v!r} is not a valid value") from None
        elif v is not None and action.type is Path:
            v = Path(v)
        if action.choices is not None and v is not None and v not in action.choices:
            known = ", ".join(map(str, action.choices))
            raise InputError(f"{stage}: option {name}: {v!r} is not one of {known}")
        out.append(v)
    return out if many else out[0]


def _namespace(stage: str, dataset: str | None, root: Path | None, options: dict[str, Any]):
    """The parsed arguments of ``python -m pipeline STAGE`` with these settings, built from values."""
    cmd = _command(stage)
    actions = {a.dest: a for a in cmd._actions if a.dest not in ("help", "version")}
    ns = argparse.Namespace(stage=stage)
    for dest, a in actions.items():
        default = a.default
        if default is None and a.nargs == "*" and not a.option_strings:
            default = []                                      # what argparse gives a bare FILE...
        setattr(ns, dest, default)
    for key, val in cmd._defaults.items():
        setattr(ns, key, val)
    given = dict(options)
    if dataset is not None:
        if "dataset" not in actions:
            raise InputError(f"{stage} takes no dataset (give its options: {', '.join(sorted(actions))})")
        given["dataset"] = dataset
    if root is not None and "root" in actions:
        given["root"] = root
    for key, val in given.items():
        if key not in actions:
            raise InputError(f"{stage}: unknown option {key!r} (known: {', '.join(sorted(actions))})")
        setattr(ns, key, _value(stage, actions[key], val))
    for dest, a in actions.items():
        if a.required and getattr(ns, dest) is None:
            raise InputError(f"{stage}: option {dest} is required")
    return ns


def _folder(stage: str, ns: argparse.Namespace) -> Path:
    if getattr(ns, "out", None) is not None:
        return Path(ns.out)
    from pipeline.catalog import Catalog

    return Catalog(root=Path(ns.root), dataset=ns.dataset).base / STAGE_DIRS[stage]


def result_files(folder: Path) -> tuple[Path, ...]:
    """Every result file under ``folder`` (sorted): hidden files, files in hidden folders and
    ``timing.json`` (how long, not what) left out."""
    folder = Path(folder)
    if not folder.is_dir():
        return ()
    return tuple(sorted(p for p in folder.rglob("*") if p.is_file() and p.name != TIMING_FILE
                        and not any(q.startswith(".") for q in p.relative_to(folder).parts)))


class _Said(io.TextIOBase):
    """stdout while a stage runs: kept (for :attr:`StageResult.log`) and, with ``echo``, passed on."""

    def __init__(self, echo):
        self.kept = io.StringIO()
        self.echo = echo

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        self.kept.write(text)
        if self.echo is not None:
            self.echo.write(text)
        return len(text)

    def flush(self) -> None:
        if self.echo is not None:
            self.echo.flush()


def run(stage: str, dataset: str | None = None, *, root: str | Path | None = None, echo: bool = False,
        **options: Any) -> StageResult:
    """Run one stage in this process, as ``python -m pipeline STAGE`` would.

    Parameters
    ----------
    stage : str
        One of :func:`stages`: ``tank``, ``ingest``, ``identify``, ``validate``, ``indices``,
        ``control``, ``diagnose``.
    dataset : str, optional
        The dataset (``virtual``, ``hsva`` or a folder of ``data/raw``); its outputs go to
        ``ROOT/DATASET/<stage>/``.  None for ``tank``, or for a stage given files and ``out``.
    root : str or pathlib.Path, optional
        The processed-data root (default ``data/processed``, relative to the working folder).
    echo : bool
        Also print what the stage says (as the command line does); always kept in
        :attr:`StageResult.log`.  Warnings and notices go to stderr either way.
    **options
        The command's options by name (``python -m pipeline STAGE --help``, ``-`` as ``_``):
        e.g. ``algorithm="srukf-ffm"`` for identify, ``no_plots=True`` for diagnose, ``out=...``
        for tank.

    Returns
    -------
    StageResult
        The stage, dataset, the folder it wrote, its result files and the wall time (s).

    Raises
    ------
    pipeline.errors.PipelineError
        A refused input or setting (:class:`~pipeline.errors.InputError`, one line naming the file,
        key or option), or a stage that failed.  Nothing partial is left: every stage writes its
        folder as one set.
    """
    from pipeline.cli._common import check_args_outputs

    ns = _namespace(stage, dataset, Path(root) if root is not None else None, options)
    check_args_outputs(ns)
    said = _Said(sys.stdout if echo else None)
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(said):
        code = int(ns.func(ns) or 0)
    seconds = time.perf_counter() - t0
    if code != 0:
        raise PipelineError(f"stage {stage}" + (f" of dataset {dataset!r}" if dataset else "")
                            + f" failed (exit {code})")
    folder = _folder(stage, ns)
    return StageResult(stage, getattr(ns, "dataset", None), folder, result_files(folder), seconds,
                       tuple(said.kept.getvalue().splitlines()))
