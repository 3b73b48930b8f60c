"""``python -m pipeline tank --out DIR [--seed N] [--no-noise] [--pull-out S]``: write the virtual
tank's default runs.

Writes kcs_zigzag_20_20_S.csv, kcs_zigzag_20_20_P.csv, kcs_zigzag_10_10_S.csv,
kcs_zigzag_10_10_P.csv, kcs_turning_35_S.csv, kcs_turning_35_P.csv (canonical CSV,
docs/contract.md#raw-formats), each atomically.  With ``--pull-out S`` the turning circles end in a
pull-out: the rudder is returned to midships S seconds after the execute
(kcs_turning_35_S_pulloutS.csv, ...), the manoeuvre in which the KCS's speed dependence shows
(docs/diagnosis.md, docs/virtual-tank.md).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from pipeline.config import TankConfig
from pipeline.progress import bar


def register(sub) -> None:
    p = sub.add_parser("tank", help="virtual KCS tank: write the default zigzags and turning circles as CSV")
    p.add_argument("--out", type=Path, required=True, help="output directory for the raw CSV files")
    p.add_argument("--seed", type=int, default=None, help=f"noise seed (default {TankConfig.seed})")
    p.add_argument("--no-noise", action="store_true", help="write noise-free runs")
    p.add_argument("--pull-out", type=float, default=None, metavar="S",
                   help="end the turning circles in a pull-out: rudder to midships S seconds after the "
                        "execute (inside the 90 s record)")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from pipeline.tank import default_set, simulate, turning_circle, write_csv

    cfg = TankConfig()
    if args.seed is not None:
        cfg = dataclasses.replace(cfg, seed=args.seed)
    if args.no_noise:
        cfg = dataclasses.replace(cfg, noise=False)
    manoeuvres = default_set()
    if args.pull_out is not None:
        manoeuvres = [turning_circle(m.rudder_deg, m.side, m.duration, pull_out_s=args.pull_out)
                      if m.kind == "turning" else m for m in manoeuvres]
    for m in bar(manoeuvres, desc="virtual tank", unit="run"):
        run = simulate(m, cfg)
        write_csv(Path(args.out) / f"{m.file_stem}.csv", run)
    print(f"wrote {len(manoeuvres)} virtual-tank runs to {args.out}")
    return 0
