"""Study kind ``autopilot_monte_carlo``: CGSA course keeping over wave seeds x Tw x wind x plant.

Each case designs the CGSA autopilot (:mod:`pipeline.control.design`) from the Nomoto indices of the
spec for its closed-loop time constant Tw, and simulates the 0 -> setpoint course change and course
keeping (:func:`pipeline.control.simulate.simulate_course`) with a constant wind (as an equivalent
rudder, deg) and a wave disturbance (the paper's G(s) driven by white noise, seeded by the case's own
seed) on one plant: ``nomoto`` (the linear model the autopilot was designed on) or ``kcs`` (the
virtual tank's nonlinear KCS, noise-free, the autopilot's servo limits).  Results are the control
metrics of docs/contract.md#metrics (:func:`pipeline.control.metrics.course_metrics`).

Summary: per (plant, Tw, wind) the distribution of every metric over the seeds (mean, std, 5 / 50 /
95 % quantiles, worst), and for each metric the ``worst`` cases of the whole study (with their
parameters), "worse" read as in pipeline.control.metrics.WORST.
"""

from __future__ import annotations

import dataclasses as dc
from typing import Any

import numpy as np
import pandas as pd

from pipeline.config import AutopilotStudyConfig, ControlConfig
from pipeline.errors import InputError
from pipeline.study.kind import StudyKind

PLANTS = ("nomoto", "kcs")


def _control(cfg: AutopilotStudyConfig) -> ControlConfig:
    return dc.replace(ControlConfig(), **cfg.control)


def check(cfg: AutopilotStudyConfig) -> None:
    """Refuse settings no case could run with, naming the key (the spec's ``check``)."""
    t = "autopilot_monte_carlo"
    for p in cfg.plants:
        if p not in PLANTS:
            raise InputError(f"key '{t}.plants': unknown plant {p!r} (known: {', '.join(PLANTS)})")
    if cfg.design not in ("first_order", "second_order"):
        raise InputError(f"key '{t}.design': must be first_order or second_order, got {cfg.design!r}")
    if cfg.seeds < 1:
        raise InputError(f"key '{t}.seeds': must be at least 1, got {cfg.seeds}")
    for tw in cfg.tw:                                 # a closed-loop time constant
        if not tw > 0:
            raise InputError(f"key '{t}.tw': time constants must be > 0 s, got {tw}")
    for key in ("K", "T1", "T2", "T3"):               # a stable ship's Nomoto indices
        if not getattr(cfg, key) > 0:
            raise InputError(f"key '{t}.{key}': must be > 0, got {getattr(cfg, key)}")
    for key in ("duration", "dt"):
        v = cfg.control.get(key)
        if v is not None and not (isinstance(v, int | float) and not isinstance(v, bool) and v > 0):
            raise InputError(f"key '{t}.control.{key}': must be > 0 s, got {v!r}")


def cases(cfg: AutopilotStudyConfig) -> list[dict[str, Any]]:
    check(cfg)
    return [{"plant": p, "tw": float(tw), "wind_rudder": float(w), "replicate": k}
            for p in cfg.plants for tw in cfg.tw for w in cfg.wind_rudder for k in range(cfg.seeds)]


def _design(cfg: AutopilotStudyConfig, tw: float, ctl: ControlConfig):
    from pipeline.control.design import design_first_order, design_second_order

    if cfg.design == "first_order":
        return design_first_order(cfg.K, cfg.T1 + cfg.T2 - cfg.T3, tw)
    return design_second_order(cfg.K, cfg.T1, cfg.T2, cfg.T3, tw, ctl.filter_tau)


def run_case(params: dict, seed: int, cfg: AutopilotStudyConfig) -> dict[str, Any]:
    from pipeline.control.disturbance import wave_sequence
    from pipeline.control.metrics import course_metrics
    from pipeline.control.simulate import NomotoShip, make_kcs_ship, simulate_course

    ctl = _control(cfg)
    design = _design(cfg, float(params["tw"]), ctl)
    n = int(round(ctl.duration / ctl.dt)) + 1
    wave_seed = int(seed % (2**32))
    wave = (wave_sequence(n, ctl.dt, wave_seed, num=ctl.wave_num, den=ctl.wave_den) if ctl.wave
            else np.zeros(n))
    if params["plant"] == "nomoto":
        ship = NomotoShip(cfg.K, cfg.T1, cfg.T2, cfg.T3, rudder_max=ctl.rudder_max,
                          rudder_rate=ctl.rudder_rate)
    else:
        ship = make_kcs_ship(ctl.rudder_max, ctl.rudder_rate)
    fr = simulate_course(design, ship, setpoint=ctl.setpoint, duration=ctl.duration, dt=ctl.dt,
                         rudder_max=ctl.rudder_max, wind=float(params["wind_rudder"]), wave=wave)
    m = course_metrics(fr["time"], fr["psi"], fr["delta"], ctl.setpoint, band=ctl.settle_band,
                       steady_start=ctl.steady_start, reversal_threshold=ctl.reversal_threshold)
    m["max_rate"] = float(np.max(np.abs(np.diff(fr["delta"].to_numpy(), prepend=0.0))) / ctl.dt)
    m["wave_seed"] = wave_seed
    m["Kp"], m["Kd"] = float(design.Kp), float(design.Kd)
    return m


def warm(cfg: AutopilotStudyConfig) -> None:
    """Compile the KCS kernel on a worker (the Nomoto plant is numpy only)."""
    if "kcs" in cfg.plants:
        from pipeline.control.simulate import make_kcs_ship

        gear = ControlConfig()
        ship = make_kcs_ship(gear.rudder_max, gear.rudder_rate)
        ship.reset()
        ship.step(1.0, 0.08, disturbance_deg=0.0)


def _worst_order(how: str, values: pd.Series) -> pd.Series:
    return {"max": values, "min": -values, "absmax": values.abs()}[how]


def summarise(frame: pd.DataFrame, cfg: AutopilotStudyConfig, study_seed: int) -> dict[str, Any]:
    from pipeline.control.metrics import WORST

    ok = frame[frame["status"] == "ok"]
    metrics = [m for m in [*WORST, "max_rate"] if m in ok.columns]
    groups = []
    for (plant, tw, wind), g in ok.groupby(["plant", "tw", "wind_rudder"], sort=True):
        stats = {}
        for m in metrics:
            v = pd.to_numeric(g[m], errors="coerce").to_numpy(float)
            fin = v[np.isfinite(v)]
            how = WORST.get(m, "max")
            pick = {"max": np.max, "min": np.min}.get(how, lambda a: a[np.argmax(np.abs(a))])
            stats[m] = {
                "n": int(fin.size), "not_finite": int(v.size - fin.size),
                "mean": float(np.mean(fin)) if fin.size else None,
                "std": float(np.std(fin, ddof=1)) if fin.size > 1 else None,
                "q05": float(np.quantile(fin, 0.05)) if fin.size else None,
                "median": float(np.median(fin)) if fin.size else None,
                "q95": float(np.quantile(fin, 0.95)) if fin.size else None,
                "worst": float(pick(fin)) if fin.size else None,
            }
        groups.append({"plant": plant, "tw": float(tw), "wind_rudder": float(wind), "seeds": len(g),
                       "metrics": stats})
    worst = {}
    for m in metrics:
        v = pd.to_numeric(ok[m], errors="coerce")
        order = _worst_order(WORST.get(m, "max"), v).fillna(np.inf)   # never reached (NaN) is worst
        top = ok.assign(_o=order).sort_values(["_o", "case_id"], ascending=[False, True]).head(cfg.worst)
        worst[m] = [{"case_id": r["case_id"], "plant": r["plant"], "tw": float(r["tw"]),
                     "wind_rudder": float(r["wind_rudder"]), "replicate": int(r["replicate"]),
                     "wave_seed": int(r["wave_seed"]), "value": None if pd.isna(r[m]) else float(r[m])}
                    for _, r in top.iterrows()]
    ctl = _control(cfg)
    return {
        "design": {"kind": cfg.design, "K": cfg.K, "T1": cfg.T1, "T2": cfg.T2, "T3": cfg.T3},
        "control": dc.asdict(ctl),
        "groups": groups,
        "worst_cases": worst,
        "definitions": {"worst": "per metric, the cases that are worst in the sense of "
                                 "pipeline.control.metrics.WORST; a metric never reached (NaN) counts worst"},
    }


KIND = StudyKind(name="autopilot_monte_carlo", config=AutopilotStudyConfig, cases=cases, run_case=run_case,
                 summarise=summarise, warm=warm, check=check, summary_only=("worst",),
                 grid=("plants", "tw", "wind_rudder", "seeds"))
