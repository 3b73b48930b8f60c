"""``python -m pipeline report``: execute the notebooks per dataset and render HTML reports."""

from __future__ import annotations

import sys
from pathlib import Path

from pipeline.errors import PipelineError
from pipeline.report.render import KERNEL_NAME, NOTEBOOKS


def register(sub) -> None:
    p = sub.add_parser("report", help="render the HTML reports (papermill + nbconvert)")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--datasets", nargs="+", help="datasets (default: virtual)")
    which.add_argument("--all", action="store_true",
                       help="every dataset with processed runs under --root (names never pass a shell)")
    p.add_argument("--root", type=Path, default=Path("data/processed"),
                   help="processed-data root (default: data/processed)")
    p.add_argument("--out", type=Path, default=Path("reports"), help="output folder (default: reports)")
    p.add_argument("--notebooks", nargs="+", choices=NOTEBOOKS, default=list(NOTEBOOKS),
                   help="notebooks to render (default: all)")
    p.add_argument("--kernel", default=KERNEL_NAME, help=f"Jupyter kernel (default: {KERNEL_NAME})")
    p.add_argument("--changed", action="store_true",
                   help="re-render only pages whose inputs, notebook or report code changed")
    p.add_argument("--keep-going", action="store_true",
                   help="render what can be rendered, list the rest, exit 2 if anything failed")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from pipeline.report.render import datasets_under, render_all

    datasets = datasets_under(args.root) if args.all else (args.datasets or ["virtual"])
    if not datasets:
        raise PipelineError(f"no processed datasets under {args.root} (run the stages first)")
    reports, errors = render_all(datasets, args.notebooks, args.out, root=args.root,
                                 kernel=args.kernel, keep_going=args.keep_going,
                                 progress=lambda name: print(f"rendering {name} ...", flush=True),
                                 force=not args.changed)
    for r in reports:
        print(f"up to date {r.html}" if r.skipped else f"written {r.html} ({r.seconds:.1f} s)")
    print(f"written {Path(args.out) / 'index.html'}")
    for e in errors:
        print(f"error: {e}", file=sys.stderr)
    if errors:
        raise PipelineError(f"{len(errors)} report(s) not rendered (see above)")
    return 0
