"""Identification in the loop: adaptive CGSA on the nonlinear virtual KCS with a speed change
(docs/control.md, "Identification in the loop").

Scenario (:class:`pipeline.config.ControlConfig`, ``adaptive_*``): the KCS at its approach speed keeps
course through alternating course changes of +-``adaptive_step_deg`` every ``adaptive_step_every`` s,
with the constant wind and the wave disturbance of the stage; at ``adaptive_change_s`` the propeller is
cut to the trim for ``adaptive_speed_share`` of the approach speed, and the ship slows down.

The SR-UKF-FFM runs online (:class:`pipeline.identify.stream.StreamingIdentifier`) on the closed-loop
measurements (the tank's logger noise added, seeded), from the identified parameters and covariance.
Every ``adaptive_period`` s the first-order CGSA gains are re-designed from its moving K, T
(T = T1 + T2 - T3), subject to the anti-bursting rule: enough excitation (rudder standard deviation
over the last ``adaptive_window`` s at least ``adaptive_min_rudder_std`` deg), a filter not
over-confident (window mean NIS below ``adaptive_max_nis_ratio`` x 3) and each gain moving at most
``adaptive_max_gain_change`` of its value per re-design.  The same seeds run with the fixed gains.

Metrics after the speed change (t >= adaptive_change_s): heading MAE about the set course (deg),
rudder RMS (deg) and travel (sum |delta change|, deg), and the overshoot of each course change beyond
its new set course (deg; the largest and the mean).
"""

from __future__ import annotations

import time as _time
from dataclasses import replace
from typing import Any

import numpy as np

from pipeline.config import ControlConfig, FilterConfig, TankConfig
from pipeline.control.autopilot import CGSAController
from pipeline.control.design import design_first_order
from pipeline.control.disturbance import wave_sequence, wind_from_config
from pipeline.control.simulate import make_kcs_ship
from pipeline.identify.stream import StreamingIdentifier


def course_schedule(t: np.ndarray, cfg: ControlConfig) -> np.ndarray:
    """Set course (deg) at times t (s): 0, then +step, 0, -step, 0, ... every adaptive_step_every s."""
    k = np.floor(np.asarray(t, float) / cfg.adaptive_step_every).astype(int)
    return np.choose(k % 4, [0.0, cfg.adaptive_step_deg, 0.0, -cfg.adaptive_step_deg])


def _slow_down(ship, share: float) -> None:
    """Cut the KCS's propeller to the trim for ``share`` of its approach speed."""
    from pipeline.tank.kcs import param_vector, trim_rps

    slow = replace(ship.cfg, approach_speed=ship.cfg.approach_speed * share)
    ship._p = param_vector(ship.cfg, ship.coeffs, trim_rps(slow, ship.coeffs))


def limited(new: float, old: float, share: float) -> float:
    """``new`` moved toward from ``old`` by at most ``share`` x |old|."""
    return float(np.clip(new, old - share * abs(old), old + share * abs(old)))


def run_once(theta0, cov0, K0: float, T0: float, seed: int, cfg: ControlConfig,
             adapt: bool) -> dict[str, Any]:
    """One run (module docstring); fixed gains, and no identifier, when ``adapt`` is False."""
    dt, n = cfg.dt, int(round(cfg.adaptive_duration / cfg.dt)) + 1
    t = np.arange(n) * dt
    ref = course_schedule(t, cfg)
    wave = wave_sequence(n, dt, seed, cfg.wave_num, cfg.wave_den) if cfg.wave else np.zeros(n)
    wind = wind_from_config(cfg)
    tank = TankConfig()
    noise_sd = np.array([tank.noise_v, tank.noise_r, tank.noise_psi])
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, seed, 5]))
    ship = make_kcs_ship(cfg.rudder_max, cfg.rudder_rate, cfg.dead_time, cfg.servo_time_constant)
    st = ship.reset()
    fcfg = replace(FilterConfig(), r_std=tuple(noise_sd))
    x0 = np.concatenate([[st["v"], st["r"], st["psi"]], np.asarray(theta0, float)])
    P0 = np.zeros((9, 9))
    P0[:3, :3] = np.diag(noise_sd ** 2)
    P0[3:, 3:] = np.asarray(cov0, float)
    ident = StreamingIdentifier(x0, P0, dt, fcfg)
    design = design_first_order(K0, T0, cfg.tw, name="adaptive")
    ctl = CGSAController(design, dt, cfg.rudder_max)
    kp, kd = design.Kp, design.Kd
    every, win = int(round(cfg.adaptive_period / dt)), int(round(cfg.adaptive_window / dt))
    psi = np.empty(n)
    delta = np.empty(n)
    nis = np.full(n, np.nan)
    gains = [(0.0, kp, kd, "start")]
    id_secs = 0.0
    prev_delta = 0.0
    slowed = False
    for k in range(n):
        if not slowed and t[k] >= cfg.adaptive_change_s:
            _slow_down(ship, cfg.adaptive_speed_share)
            slowed = True
        meas = np.array([st["v"], st["r"], st["psi"]]) + rng.normal(0.0, noise_sd)
        if adapt and k > 0:
            t0 = _time.perf_counter()
            nis[k] = ident.update({"delta": prev_delta, "v": meas[0], "r": meas[1], "psi": meas[2]})["nis"]
            id_secs += _time.perf_counter() - t0
        if adapt and k > 0 and k % every == 0 and k >= win:
            why = None
            rud_sd = float(np.std(delta[k - win:k]))
            nis_w = float(np.nanmean(nis[k - win:k]))
            idx = ident.estimate()["indices"]
            if rud_sd < cfg.adaptive_min_rudder_std:
                why = f"excitation: rudder sd {rud_sd:.2f} deg"
            elif not nis_w < cfg.adaptive_max_nis_ratio * 3:
                why = f"filter over-confident: window mean NIS {nis_w:.3g}"
            elif idx is None or not (idx["K"] > 0 and idx["T"] > 0):
                why = "no positive K, T in the estimate"
            if why is None:
                kp = limited(1.0 / (idx["K"] * cfg.tw), kp, cfg.adaptive_max_gain_change)
                kd = limited(idx["T"] / (idx["K"] * cfg.tw), kd, cfg.adaptive_max_gain_change)
                ctl.design = design_first_order(1.0 / (kp * cfg.tw), kd / kp, cfg.tw, name="adaptive")
                ctl.gain = ctl.design.Kd
            gains.append((float(t[k]), kp, kd, why or "re-designed"))
        cmd = ctl.command(ref[k], st["psi"], st["r"])
        psi[k] = st["psi"]
        st = ship.step(cmd, dt, disturbance_deg=wind + wave[k])
        delta[k] = st["delta"]
        prev_delta = st["delta"]
    return {"t": t, "ref": ref, "psi": psi, "delta": delta, "gains": gains, "id_seconds": id_secs,
            "final": ident.estimate()}


def after_change_metrics(t, ref, psi, delta, cfg: ControlConfig) -> dict[str, float]:
    """Heading MAE, rudder RMS and travel, and course-change overshoots for t >= adaptive_change_s."""
    w = t >= cfg.adaptive_change_s
    over = []
    starts = np.flatnonzero(np.diff(ref) != 0) + 1
    for i, s in enumerate(starts):
        if t[s] < cfg.adaptive_change_s:
            continue
        e = starts[i + 1] if i + 1 < len(starts) else len(t)
        step = ref[s] - ref[s - 1]
        over.append(max(0.0, float(np.max(np.sign(step) * (psi[s:e] - ref[s])))))
    return {"heading_mae_deg": float(np.mean(np.abs(psi[w] - ref[w]))),
            "rudder_rms_deg": float(np.sqrt(np.mean(delta[w] ** 2))),
            "rudder_travel_deg": float(np.sum(np.abs(np.diff(delta[w])))),
            "overshoot_max_deg": float(max(over)) if over else float("nan"),
            "overshoot_mean_deg": float(np.mean(over)) if over else float("nan")}


def adaptive_block(theta0, cov0, K0: float, T0: float, seeds: list[int],
                   cfg: ControlConfig) -> tuple[dict[str, Any], float]:
    """The ``adaptive`` block of control/metrics.json (adaptive against fixed gains on the same seeds)
    and the seconds spent in the streaming identifier's updates of the adaptive runs (for the terminal
    and the benchmark, never in the document: same inputs, same bytes)."""
    rows = {"adaptive": [], "fixed": []}
    gains, finals, id_secs = [], [], 0.0
    for seed in seeds:
        for name in ("fixed", "adaptive"):
            r = run_once(theta0, cov0, K0, T0, seed, cfg, adapt=name == "adaptive")
            m = after_change_metrics(r["t"], r["ref"], r["psi"], r["delta"], cfg)
            rows[name].append({"seed": seed, **m})
            if name == "adaptive":
                gains.append([{"t_s": g[0], "Kp": g[1], "Kd": g[2], "event": g[3]} for g in r["gains"]])
                finals.append(r["final"]["indices"])
                id_secs += r["id_seconds"]
    keys = [k for k in rows["fixed"][0] if k != "seed"]
    summary = {}
    for name, rs in rows.items():
        summary[name] = {k: {"mean": float(np.nanmean([x[k] for x in rs])),
                             "std": float(np.nanstd([x[k] for x in rs], ddof=1)) if len(rs) > 1 else 0.0}
                         for k in keys}
    pairs = list(zip(rows["adaptive"], rows["fixed"], strict=True))
    diff = {k: float(np.nanmean([a[k] - b[k] for a, b in pairs])) for k in keys}
    return {
        "scenario": {"duration_s": cfg.adaptive_duration, "speed_change_s": cfg.adaptive_change_s,
                     "speed_share": cfg.adaptive_speed_share, "course_step_deg": cfg.adaptive_step_deg,
                     "course_step_every_s": cfg.adaptive_step_every, "plant": "nonlinear virtual KCS",
                     "design": f"first-order CGSA, Tw = {cfg.tw:g} s"},
        "rule": {"period_s": cfg.adaptive_period, "window_s": cfg.adaptive_window,
                 "min_rudder_std_deg": cfg.adaptive_min_rudder_std,
                 "max_nis_ratio": cfg.adaptive_max_nis_ratio,
                 "max_gain_change": cfg.adaptive_max_gain_change},
        "start": {"K": K0, "T": T0},
        "seeds": seeds, "per_seed": rows, "stats": summary,
        "difference": {"what": "adaptive minus fixed, mean over the paired seeds", "metrics": diff},
        "gains_first_seed": gains[0] if gains else [], "final_indices": finals,
    }, id_secs
