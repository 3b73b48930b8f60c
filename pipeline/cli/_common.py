"""Helpers shared by the stage commands (argument conventions, dataset catalog, output checks)."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from pipeline.catalog import Catalog
from pipeline.errors import PipelineError


class OutputError(PipelineError):
    """An output location that cannot be written (exit 2, one line)."""


def add_dataset_args(p: argparse.ArgumentParser) -> None:
    """``--dataset NAME`` and ``--root DIR`` select the catalog (data/processed/<NAME>/...).  There is
    no default dataset: a stage run bare refuses (:func:`catalog`) rather than overwrite the virtual
    tank's outputs."""
    p.add_argument("--dataset", default=None,
                   help="dataset name (required unless files are given; `datasets` lists them)")
    p.add_argument("--root", type=Path, default=Path("data/processed"),
                   help="processed-data root (default: data/processed)")


def catalog(args: argparse.Namespace) -> Catalog:
    """The catalog of ``--dataset`` under ``--root``; refused (one line) when no dataset is given."""
    if not getattr(args, "dataset", None):
        stage = getattr(args, "stage", None) or "this stage"
        raise PipelineError(f"{stage}: give --dataset NAME (`python -m pipeline datasets` lists them) "
                            "or the files to work on; there is no default dataset")
    return Catalog(root=args.root, dataset=args.dataset)


def check_output_location(path: str | Path, *, is_file: bool = False, what: str = "--out") -> None:
    """Refuse, before any work, an output location that cannot be written.

    ``path`` is a directory to create or replace (``is_file`` False, every stage's ``--out``) or a
    file (``is_file`` True, e.g. ``bench --out``).  Refused: a directory location that is an
    existing file (or a file location that is a directory), a path through a file, and a location
    whose nearest existing folder the user may not write into.  Raises :class:`OutputError` naming
    the path.
    """
    p = Path(path)
    if not is_file and p.exists() and not p.is_dir():
        raise OutputError(f"{what} is an existing file, not a folder", file=p)
    if is_file and p.is_dir():
        raise OutputError(f"{what} is an existing folder, not a file", file=p)
    # outputs are written beside the target (temporary name, then rename): its parent must be writable
    probe = p.parent if (is_file or p.exists()) else p
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise OutputError(f"{what} goes through {probe}, which is a file, not a folder", file=p)
    if probe.exists() and not os.access(probe, os.W_OK | os.X_OK):
        raise OutputError(f"{what} cannot be written: no write permission in {probe}", file=p)


def check_args_outputs(args: argparse.Namespace) -> None:
    """:func:`check_output_location` on the ``--out`` (and catalog ``--root``) of any stage command."""
    out = getattr(args, "out", None)
    if out is not None:
        check_output_location(out, is_file=bool(getattr(args, "out_is_file", False)))
    root = getattr(args, "root", None)
    if root is not None and Path(root).exists() and not Path(root).is_dir():
        raise OutputError("--root is an existing file, not a folder", file=root)
