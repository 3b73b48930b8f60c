"""``python -m pipeline control --dataset D``: CGSA course keeping with wind and waves.

Reads ``data/processed/D/indices/indices.json`` (or ``--indices FILE``; ``--paper`` uses the paper's
Table 7 and graphical K, T instead) and writes ``control/metrics.json`` and
``control/timeseries.parquet`` (or into ``--out DIR``), atomically.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

from pipeline.cli._common import add_dataset_args, catalog
from pipeline.config import ControlConfig
from pipeline.errors import InputError
from pipeline.io import atomic_dir, read_json, write_frame, write_json


def register(sub) -> None:
    p = sub.add_parser("control", help="CGSA autopilot design and course-keeping simulation (wind, waves)")
    add_dataset_args(p)
    p.add_argument("--indices", type=Path, help="indices.json to read (default: the dataset's)")
    p.add_argument("--paper", action="store_true",
                   help="design from the paper's Table 7 and graphical K, T instead of the dataset's indices")
    p.add_argument("--out", type=Path, help="output directory (default: data/processed/D/control)")
    p.add_argument("--seeds", type=int, help="number of wave seeds (default: ControlConfig.seeds)")
    p.add_argument("--seed", type=int, help="base seed (default: ControlConfig.seed)")
    p.add_argument("--plants", nargs="+", choices=["nomoto", "kcs"],
                   help="plants to simulate (default: nomoto, plus kcs for virtual-tank data)")
    p.add_argument("--wind-model", choices=["constant", "eq14"], help="wind as constant or Eq. 14 form")
    p.add_argument("--no-waves", action="store_true", help="switch the wave disturbance off")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_run)


def paper_indices() -> dict:
    """An indices document holding the paper's Table 7 (identified) and graphical K, T."""
    from pipeline.model import PAPER_GRAPHICAL, PAPER_TABLE7

    return {"dataset": None, "provenance": "paper",
            "control_model": {"source": "paper Table 7", **PAPER_TABLE7},
            "graphical_model": {"source": "paper (graphical method)", **PAPER_GRAPHICAL}}


def dataset_inputs(cat, indices: dict, cfg: ControlConfig):
    """(settings, notice, robustness inputs) of a dataset from its processed files.

    Settings: the ``[control]`` table of the dataset.toml that runs/index.json names.  Which model to
    design from is not decided here: the indices stage decides it on the held-out runs
    (``control_model.design_model`` of indices.json, pipeline/indices/design_model.py).  The
    robustness inputs are the identified parameters and covariance and, for the built-in tank's KCS,
    its linearisation straight ahead and at the reduced speeds.
    """
    from pipeline.control.settings import apply, read_dataset_control
    from pipeline.model import PARAM_NAMES

    index = read_json(cat.runs_index) if cat.runs_index.is_file() else {}
    part = index.get("ship") if isinstance(index.get("ship"), dict) else {}
    ship = part.get("ship")
    cfg, notice = apply(cfg, read_dataset_control(part.get("dataset_toml")),
                        ship if isinstance(ship, str) else None)
    est_path = cat.identify_dir("srukf-ffm") / "estimates.json"
    est = read_json(est_path) if est_path.is_file() else None
    extra: dict = {}
    if est is not None:
        try:
            theta = [float(est["parameters"][n]) for n in PARAM_NAMES]
            extra = {"parameters": theta, "covariance": est["covariance"]}
            q = (est.get("settings") or {}).get("q_std")
            if isinstance(q, list) and len(q) >= 3:     # the identify stage's Q, for the in-loop filter
                extra["q_std"] = [float(x) for x in q[:3]]
        except (KeyError, TypeError, ValueError):
            raise InputError("parameters or covariance missing or not numbers", file=est_path) from None
    if indices.get("builtin_tank"):
        from dataclasses import replace as _replace

        from pipeline.config import TankConfig
        from pipeline.control.simulate import kcs_available

        if kcs_available():
            from pipeline.tank.kcs import linearise

            base = TankConfig()
            extra["linearised"] = {s: linearise(_replace(base, approach_speed=base.approach_speed * s))
                                   for s in (1.0, *cfg.reduced_speeds)}
            extra["kcs"] = True
    return cfg, notice, extra


def _run(args) -> int:
    from pipeline.control.stage import control_result

    # the catalog only where a default comes from it (--indices/--paper with --out need none)
    cat = catalog(args) if args.out is None or (args.indices is None and not args.paper) else None
    cfg = ControlConfig()
    changes = {}
    if args.seeds is not None:
        if args.seeds < 1:
            raise InputError(f"--seeds {args.seeds}: must be >= 1")
        changes["seeds"] = args.seeds
    if args.seed is not None:
        changes["seed"] = args.seed
    if args.wind_model:
        changes["wind_model"] = args.wind_model
    if args.no_waves:
        changes["wave"] = False
    cfg = replace(cfg, **changes)

    extra, notice = {}, None
    if args.paper:
        doc, source = paper_indices(), "paper"
        doc["dataset"] = args.dataset
    else:
        path = args.indices or (cat.indices_dir / "indices.json")
        doc, source = read_json(path), str(path)
        cfg, notice, extra = dataset_inputs(cat, doc, cfg)
    if args.plants is not None and "kcs" not in args.plants:
        extra.pop("kcs", None)
    result, ts = control_result(doc, cfg, source=source, plants=tuple(args.plants) if args.plants else None,
                                progress=not args.no_progress, robustness=extra)
    if notice:                                   # one line, once the run has succeeded
        print(notice, file=sys.stderr)
        result = replace(result, notes=[*result.notes, notice])
    metrics = replace(result, indices_source=source).to_json()
    out = args.out or cat.control_dir
    with atomic_dir(out, writer="control") as tmp:
        write_json(tmp / "metrics.json", metrics)
        write_frame(tmp / "timeseries.parquet", ts,
                    meta={"dataset": metrics["dataset"], "provenance": metrics["provenance"],
                          "units": {"time": "s", "psi_ref": "deg", "psi": "deg", "r": "deg/s",
                                    "delta_cmd": "deg", "delta": "deg", "wave": "deg", "wind": "deg"}})
    if metrics.get("refused"):
        print(f"control: autopilot not designed: {metrics['reason']}", file=sys.stderr)
    else:
        _print_summary(metrics)
    print(f"written {Path(out) / 'metrics.json'} and {Path(out) / 'timeseries.parquet'}")
    return 0


def _print_summary(m: dict) -> None:
    keys = ("rise_time", "max_deviation", "steady_mae", "max_rudder", "steady_rudder_min",
            "steady_rudder_max", "mean_rudder", "rudder_reversals")
    print(f"provenance: {m['provenance']}" + ("  (VIRTUAL TANK)" if m.get("builtin_tank") else
                                               "  (SIMULATED, not measured)" if m.get("virtual") else ""))
    print(f"{'plant':<7} {'design':<15} " + " ".join(f"{k[:14]:>14}" for k in keys))
    for r in m["results"]:
        vals = " ".join(f"{r['stats'][k]['mean']:>8.3f}±{r['stats'][k]['std']:<5.2f}" for k in keys)
        print(f"{r['plant']:<7} {r['design']:<15} {vals}")
