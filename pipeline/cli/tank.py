"""``python -m pipeline tank --out DIR [--seed N] [--no-noise]``: write the virtual tank's default runs.

Writes kcs_zigzag_20_20_S.csv, kcs_zigzag_20_20_P.csv, kcs_zigzag_10_10_S.csv,
kcs_zigzag_10_10_P.csv, kcs_turning_35_S.csv, kcs_turning_35_P.csv (canonical CSV, SPEC section 3),
each atomically.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from tqdm import tqdm

from pipeline.config import TankConfig


def register(sub) -> None:
    p = sub.add_parser("tank", help="virtual KCS tank: write the default zigzags and turning circles as CSV")
    p.add_argument("--out", type=Path, required=True, help="output directory for the raw CSV files")
    p.add_argument("--seed", type=int, default=None, help=f"noise seed (default {TankConfig.seed})")
    p.add_argument("--no-noise", action="store_true", help="write noise-free runs")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from pipeline.tank import default_set, simulate, write_csv

    cfg = TankConfig()
    if args.seed is not None:
        cfg = dataclasses.replace(cfg, seed=args.seed)
    if args.no_noise:
        cfg = dataclasses.replace(cfg, noise=False)
    manoeuvres = default_set()
    for m in tqdm(manoeuvres, desc="virtual tank", unit="run"):
        run = simulate(m, cfg)
        write_csv(Path(args.out) / f"{m.file_stem}.csv", run)
    print(f"wrote {len(manoeuvres)} virtual-tank runs to {args.out}")
    return 0
