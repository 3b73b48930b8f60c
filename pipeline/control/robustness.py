"""The robustness block of control/metrics.json (docs/control.md, "Sampled-loop robustness").

For every design: the margins of the sampled loop (pipeline.control.robust: dt, servo lag, dead time)

* on the design model;
* over draws of the identified parameters from the filter's covariance (``ControlConfig.robust_draws``,
  seeded from ``ControlConfig.seed``): the fraction of draws whose closed loop is stable and the worst
  margins over the stable ones;
* on the ship linearised straight ahead (the course-keeping operating point; the KCS only);
* on the KCS linearised at each reduced speed (``ControlConfig.reduced_speeds`` of the approach speed);

and the percent overshoot and 2 % settling time of a clean course step (``step_deg``, no wind, no
waves) on the design model and, for the KCS, on the nonlinear ship at full and reduced speeds.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pipeline.config import ControlConfig
from pipeline.control.robust import (
    discrete_margins,
    loop_tf,
    nyquist_data,
    parameters_plant,
    sampled_margins,
)
from pipeline.control.simulate import NomotoShip, make_kcs_ship, simulate_course

WORST_MARGIN = {"gain_margin_db": min, "phase_margin_deg": min, "delay_margin_s": min,
                "sensitivity_peak": max}


def step_figures(t: np.ndarray, psi: np.ndarray, step: float, settle_share: float) -> dict[str, float]:
    """Percent overshoot and settling time (s: last time |psi - step| > settle_share |step|) of a step."""
    t, psi = np.asarray(t, dtype=float), np.asarray(psi, dtype=float)
    over = max(0.0, float(np.max(np.sign(step) * (psi - step)))) / abs(step) * 100.0
    outside = np.flatnonzero(np.abs(psi - step) > settle_share * abs(step))
    if outside.size and outside[-1] == t.size - 1:
        settle = float("nan")                        # not settled within the run
    else:
        settle = float(t[outside[-1] + 1]) if outside.size else 0.0
    return {"overshoot_pct": over, "settling_time_s": settle}


def _step(design, ship, cfg: ControlConfig) -> dict[str, float]:
    fr = simulate_course(design, ship, setpoint=cfg.step_deg, duration=cfg.step_duration, dt=cfg.dt,
                         rudder_max=cfg.rudder_max)
    return step_figures(fr["time"].to_numpy(), fr["psi"].to_numpy(), cfg.step_deg, cfg.settle_share)


def _draws(designs: dict, theta: np.ndarray, cov: np.ndarray, cfg: ControlConfig) -> dict[str, dict]:
    """Per design: the stable share and worst margins over ``cfg.robust_draws`` draws of the parameters
    from N(theta, cov) (the same draws and sampled plants for every design)."""
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, 41]))
    cov = 0.5 * (cov + cov.T)
    draws = rng.multivariate_normal(theta, cov, size=cfg.robust_draws, method="eigh")
    plants = [parameters_plant(th, cfg.dt, servo_time_constant=cfg.servo_time_constant,
                               dead_time=cfg.dead_time) for th in draws]
    result = {}
    for name, design in designs.items():
        rows = [discrete_margins(loop_tf(design, plant, cfg.dt), n_grid=600) for plant in plants]
        stable = [r for r in rows if r["stable"]]
        out: dict[str, Any] = {"draws": len(rows),
                               "stable_fraction": len(stable) / len(rows) if rows else None}
        for k, how in WORST_MARGIN.items():
            vals = [r[k] for r in stable if np.isfinite(r[k])]
            out[f"worst_{k}"] = float(how(vals)) if vals else None
        result[name] = out
    return result


def robustness(designs: dict, control_model: dict, cfg: ControlConfig, extra: dict) -> dict[str, Any]:
    """Per design: margins on the design model, over draws, straight ahead and at reduced speed; steps.

    ``extra``: optional "parameters" (six, the order of docs/contract.md#the-identification-model) and
    "covariance" (6 x 6) of the identified model, "linearised" ({"1.0": K, T1, T2, T3 at each speed share},
    the KCS only) and "kcs" (True to simulate the nonlinear KCS steps).
    """
    cm = control_model
    gear = {"servo_time_constant": cfg.servo_time_constant, "dead_time": cfg.dead_time}
    theta = extra.get("parameters")
    cov = extra.get("covariance")
    lin = extra.get("linearised") or {}
    out: dict[str, Any] = {"dt_s": cfg.dt, "servo_time_constant_s": cfg.servo_time_constant,
                           "dead_time_s": cfg.dead_time,
                           "dead_time_samples": int(round(cfg.dead_time / cfg.dt)),
                           "designs": {}}
    drawn = (_draws(designs, np.asarray(theta, float), np.asarray(cov, float), cfg)
             if theta is not None and cov is not None else {})
    for name, d in designs.items():
        row: dict[str, Any] = {"design_model": sampled_margins(d, cm["K"], cm["T1"], cm["T2"], cm["T3"],
                                                               cfg.dt, **gear)}
        row["step_design_model"] = _step(d, NomotoShip(cm["K"], cm["T1"], cm["T2"], cm["T3"],
                                                       rudder_max=cfg.rudder_max, rudder_rate=cfg.rudder_rate,
                                                       **gear), cfg)
        if name in drawn:
            row["identified_draws"] = drawn[name]
        for share, m in lin.items():
            key = "straight_ahead" if float(share) == 1.0 else f"speed_{float(share):.2f}"
            try:
                row[key] = sampled_margins(d, m["K"], m["T1"], m["T2"], m["T3"], cfg.dt, **gear)
            except Exception as exc:  # noqa: BLE001 - an unstable or odd linearisation is reported, not fatal
                row[key] = {"error": str(exc)}
            row[key]["plant"] = {k: m[k] for k in ("K", "T1", "T2", "T3")}
        if extra.get("kcs"):
            for share in (1.0, *cfg.reduced_speeds):
                ship = make_kcs_ship(cfg.rudder_max, cfg.rudder_rate, dead_time=cfg.dead_time,
                                     servo_time_constant=cfg.servo_time_constant,
                                     speed_share=share)
                row[f"step_kcs_{share:.2f}"] = _step(d, ship, cfg)
        out["designs"][name] = row
    return out


def nyquist_for(designs: dict, control_model: dict, cfg: ControlConfig, *, n: int = 300) -> dict[str, dict]:
    """Nyquist and sensitivity data of every design's sampled loop on the design model."""
    cm = control_model
    return {name: nyquist_data(d, cm["K"], cm["T1"], cm["T2"], cm["T3"], cfg.dt,
                               servo_time_constant=cfg.servo_time_constant, dead_time=cfg.dead_time, n=n)
            for name, d in designs.items()}
