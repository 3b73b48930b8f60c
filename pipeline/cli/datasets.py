"""``python -m pipeline datasets [--raw DIR] [-0]``: the dataset names, one per line.

The names the build finds (``python -m pipeline run --list``, :func:`pipeline.build.discover`):
virtual; hsva when its files exist (--shared, default ../shared: data/kvlcc2_hsva); each folder
data/raw/<name>/; 'local' when tank files sit directly in data/raw/.  Each name is a
valid ``--dataset NAME`` for every stage.  ``-0`` separates the names with NUL bytes instead of
newlines (for names that hold newlines; see pipeline.dataset).
"""

from __future__ import annotations

import sys
from pathlib import Path

from pipeline.dataset import DEFAULT_RAW, dataset_names


def register(sub) -> None:
    p = sub.add_parser("datasets", help="list the dataset names, one per line")
    p.add_argument("--raw", type=Path, default=DEFAULT_RAW, help="raw-data root (default: data/raw)")
    p.add_argument("--shared", type=Path, default=None,
                   help="shared data folder with data/kvlcc2_hsva (default: ../shared)")
    p.add_argument("-0", "--null", action="store_true", help="separate names with NUL, not newline")
    p.set_defaults(func=_run)


def _run(args) -> int:
    sep = "\0" if args.null else "\n"
    names = dataset_names(args.raw, args.shared)
    sys.stdout.write(sep.join(names) + sep)
    return 0
