"""Helpers shared by the stage commands (argument conventions, dataset catalog)."""

from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.catalog import Catalog


def add_dataset_args(p: argparse.ArgumentParser) -> None:
    """``--dataset NAME`` and ``--root DIR`` select the catalog (data/processed/<NAME>/...)."""
    p.add_argument("--dataset", default="virtual", help="dataset name (default: virtual)")
    p.add_argument("--root", type=Path, default=Path("data/processed"),
                   help="processed-data root (default: data/processed)")


def catalog(args: argparse.Namespace) -> Catalog:
    return Catalog(root=args.root, dataset=args.dataset)
