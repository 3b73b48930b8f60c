"""The one thin command-line layer: ``python -m pipeline <stage> ...``.

Each module in this package is one stage's command: it defines ``register(subparsers)`` that adds
its sub-command and sets ``func`` (taking the parsed arguments, returning an exit code).  Commands
read files, call the pure functions of the stage packages, and write files atomically.

Any :class:`pipeline.errors.PipelineError` becomes one line on stderr and exit status 2.  The output
location of every command (``--out``, ``--root``) is checked before any work
(:func:`pipeline.cli._common.check_args_outputs`); an operating-system error while writing (disk
full, permission changed during the run) is also one line and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from pipeline.cli._common import check_args_outputs
from pipeline.errors import PipelineError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m pipeline",
        description="Tank-test analysis pipeline (see README.md and SPEC.md).",
    )
    sub = parser.add_subparsers(dest="stage", metavar="STAGE", required=True)
    package = sys.modules[__name__]
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        check_args_outputs(args)
        return int(args.func(args) or 0)
    except PipelineError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"error: {where}cannot write or read ({exc.strerror or exc})", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
