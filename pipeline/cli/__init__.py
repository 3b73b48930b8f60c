"""The one thin command-line layer: ``python -m pipeline <stage> ...``.

Each module in this package is one stage's command: it defines ``register(subparsers)`` that adds
its sub-command and sets ``func`` (taking the parsed arguments, returning an exit code).  Commands
read files, call the pure functions of the stage packages, and write files atomically.

Every parser is :class:`Parser`: options are never abbreviated, help is plain text, ``--version``
prints the version, and the program is named ``tanktest`` when run as the installed script.

Any :class:`pipeline.errors.PipelineError` becomes one line on stderr and exit status 2.  The output
location of every command (``--out``, ``--root``) is checked before any work
(:func:`pipeline.cli._common.check_args_outputs`); an operating-system error while writing (disk
full, permission changed during the run) is also one line and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import re
import sys

from pipeline.cli._common import check_args_outputs
from pipeline.errors import PipelineError

_RST = [
    (re.compile(r":[a-z]+:`~?([^`]+)`"), r"\1"),       # :func:`pipeline.x` -> pipeline.x
    (re.compile(r"``([^`]+)``"), r"\1"),               # ``literal`` -> literal
    (re.compile(r"\*\*([^*]+)\*\*"), r"\1"),           # **strong** -> strong
]


def plain(text: str) -> str:
    """Help text without reStructuredText markup (the docstrings that describe the commands use it)."""
    for pattern, repl in _RST:
        text = pattern.sub(repl, text)
    return text


class Parser(argparse.ArgumentParser):
    """The parser of every command: no abbreviated options (``--scal`` is not taken as ``--scale``),
    help and usage as plain text."""

    def __init__(self, *args, **kwargs):
        kwargs["allow_abbrev"] = False
        super().__init__(*args, **kwargs)

    def format_help(self) -> str:
        return plain(super().format_help())

    def format_usage(self) -> str:
        return plain(super().format_usage())


def prog_name(argv0: str | None = None) -> str:
    """``tanktest`` when run as the installed script, else ``python -m pipeline``."""
    name = os.path.basename(argv0 if argv0 is not None else (sys.argv[0] if sys.argv else ""))
    return "tanktest" if name in ("tanktest", "tanktest.exe") else "python -m pipeline"


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    from pipeline import __version__

    parser = Parser(
        prog=prog or prog_name(),
        description="Tank-test analysis pipeline (see README.md and docs/index.md).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="stage", metavar="STAGE", required=True, parser_class=Parser)
    package = sys.modules[__name__]
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    return parser


def error_status(exc: BaseException) -> int:
    """Print ``exc`` as the one line ``error: ...`` on stderr and return its exit status: 2 for a
    refusal (:class:`pipeline.errors.PipelineError`) or an operating-system error (the file named),
    130 for an interrupt.  Any other exception is raised again (a bug: its traceback is wanted)."""
    if isinstance(exc, PipelineError):
        print(f"error: {exc}", file=sys.stderr, flush=True)
        return 2
    if isinstance(exc, OSError):
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"error: {where}cannot write or read ({exc.strerror or exc})", file=sys.stderr, flush=True)
        return 2
    if isinstance(exc, KeyboardInterrupt):
        print("error: interrupted", file=sys.stderr, flush=True)
        return 130
    raise exc


#: commands that say they still run every 30 s in a log, as the build says of each stage
#: (pipeline.progress.heartbeat; docs/operations.md, "Logs"); ``run`` beats per stage itself
BEATING = ("tank", "ingest", "identify", "validate", "indices", "control", "diagnose")


def main(argv: list[str] | None = None) -> int:
    from pipeline import progress

    parser = build_parser()
    args = parser.parse_args(argv)
    label = (f"[{args.dataset}] " if getattr(args, "dataset", None) else "") + args.stage
    try:
        check_args_outputs(args)
        if args.stage not in BEATING:
            return int(args.func(args) or 0)
        with progress.heartbeat(label, every_s=progress.HEARTBEAT_S):
            return int(args.func(args) or 0)
    except (PipelineError, OSError, KeyboardInterrupt) as exc:
        return error_status(exc)
