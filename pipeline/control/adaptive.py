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

The rudder the identifier is fed is the servo angle less its offset (``adaptive_remove_rudder_offset``):
the mean rudder over the last ``adaptive_bias_cycles`` whole course-change cycles (before that many
are complete, over the course held before the first change).  A constant disturbance held by a
constant rudder is not in the sway-yaw model; unremoved, it reads as "rudder without yaw" and drives
b21, hence K, toward zero.  Over a whole cycle of the symmetric schedule the course-changing rudder
cancels and the mean is the offset (docs/control.md, "Identification in the loop").

Metrics after the speed change (t >= adaptive_change_s): heading MAE about the set course (deg),
rudder RMS (deg) and travel (sum |delta change|, deg), and the overshoot of each course change beyond
its new set course (deg; the largest and the mean).
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from pipeline.config import ControlConfig, FilterConfig, TankConfig
from pipeline.control.autopilot import CGSAController, PIDController, design_pid
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


class SwayYawShip:
    """The linear sway-yaw model of the identifier (pipeline.model.step, parameters a11 ... b21 in the
    units of docs/contract.md) as a plant with the stepping interface of :class:`NomotoShip`: the servo
    moves toward the command within ``rudder_max`` deg and ``rudder_rate`` deg/s, the hull sees the
    servo angle plus the disturbance (deg of equivalent rudder).  ``slow_down(share)`` scales the
    parameters as a change of speed U -> share U does (a_ij by share, b_i by share^2: K by share, the
    time constants by 1/share), so its Nomoto K after the change is known exactly."""

    def __init__(self, theta, *, rudder_max: float = TankConfig.rudder_max,
                 rudder_rate: float = TankConfig.rudder_rate):
        from pipeline.model import as_theta

        self.theta = as_theta(theta).astype(float)
        self.rudder_max, self.rudder_rate = float(rudder_max), float(rudder_rate)
        self.reset()

    def reset(self) -> dict:
        self.x = np.zeros(3)
        self.delta = 0.0
        self.time = 0.0
        return self._out()

    def _out(self) -> dict:
        return {"time": self.time, "v": float(self.x[0]), "r": float(self.x[1]), "psi": float(self.x[2]),
                "delta": self.delta}

    def step(self, delta_cmd_deg: float, dt: float, disturbance_deg: float = 0.0) -> dict:
        from pipeline.model import step

        cmd = float(np.clip(delta_cmd_deg, -self.rudder_max, self.rudder_max))
        self.delta += float(np.clip(cmd - self.delta, -self.rudder_rate * dt, self.rudder_rate * dt))
        self.x = step(self.x, self.delta + float(disturbance_deg), self.theta, dt)
        self.time += dt
        return self._out()

    def slow_down(self, share: float) -> None:
        self.theta = self.theta * np.array([share, share, share, share, share ** 2, share ** 2])


def pid_design(K: float, T: float, cfg: ControlConfig):
    """The project's PID autopilot for the first-order model K (1/s), T (s) (control/autopilot.py)."""
    return design_pid(K, T, cfg.tw, rudder_max=cfg.rudder_max, zeta=cfg.pid_zeta, ki_ratio=cfg.pid_ki_ratio,
                      ref_wn_ratio=cfg.ref_wn_ratio, ref_zeta=cfg.ref_zeta, ref_rate_share=cfg.ref_rate_share)


def rudder_offset(delta: np.ndarray, k: int, window: int, first: int) -> float:
    """Rudder offset (deg) before sample k: the mean over the last ``window`` samples (whole
    course-change cycles) once there are that many; before that, the mean over the first ``first``
    samples (the course held before the first change) or as many of them as there are."""
    if k >= window:
        return float(np.mean(delta[k - window:k]))
    m = min(k, first)
    return float(np.mean(delta[:m])) if m > 0 else 0.0


@dataclass(frozen=True)
class AdaptiveStart:
    """Where an in-loop run starts.

    Attributes
    ----------
    theta : sequence of float
        The identifier's prior parameters a11 .. b21 (units of docs/contract.md#the-identification-model).
    cov : array_like
        Their 6 x 6 covariance (the same units squared).
    K : float
        Gain the first autopilot gains are designed from, 1/s.
    T : float
        Time constant the first gains are designed from, s.
    """

    theta: Any
    cov: Any
    K: float
    T: float


def run_once(start: AdaptiveStart, seed: int, cfg: ControlConfig, *, adapt: bool, ship=None, q_std=None,
             controller: str = "cgsa") -> dict[str, Any]:
    """One run (module docstring) from ``start`` on wave ``seed``; fixed gains, and no identifier,
    when ``adapt`` is False.

    ``ship``: the plant (default the nonlinear KCS, slowed by its propeller cut); any object with
    ``reset()``, ``step(cmd, dt, disturbance_deg)`` giving v (m/s), r (deg/s), psi (deg), delta (deg)
    and ``slow_down(share)``.  ``q_std``: process noise of v (m/s), r (deg/s), psi (deg) per step for
    the identifier (the identify stage's, estimated from the data); None: the paper's.
    """
    dt, n = cfg.dt, int(round(cfg.adaptive_duration / cfg.dt)) + 1
    t = np.arange(n) * dt
    ref = course_schedule(t, cfg)
    wave = wave_sequence(n, dt, seed, num=cfg.wave_num, den=cfg.wave_den) if cfg.wave else np.zeros(n)
    wind = wind_from_config(cfg)
    tank = TankConfig()
    noise_sd = np.array([tank.noise_v, tank.noise_r, tank.noise_psi])
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, seed, 5]))
    if ship is None:
        ship = make_kcs_ship(cfg.rudder_max, cfg.rudder_rate, dead_time=cfg.dead_time,
                                 servo_time_constant=cfg.servo_time_constant)
        slow = _slow_down
    else:
        def slow(s, share):
            s.slow_down(share)
    st = ship.reset()
    fcfg = replace(FilterConfig(), r_std=tuple(noise_sd))
    if q_std is not None:
        fcfg = replace(fcfg, q_std=(*(float(q) for q in q_std), *fcfg.q_std[3:]))
    K0, T0 = start.K, start.T
    x0 = np.concatenate([[st["v"], st["r"], st["psi"]], np.asarray(start.theta, float)])
    P0 = np.zeros((9, 9))
    P0[:3, :3] = np.diag(noise_sd ** 2)
    P0[3:, 3:] = np.asarray(start.cov, float)
    ident = StreamingIdentifier(x0, P0, dt, fcfg)
    if controller == "pid":
        design = pid_design(K0, T0, cfg)
        ctl = PIDController(design, dt, cfg.rudder_max)
        k_cur, t_cur = float(K0), float(T0)
    else:
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
    bias_win = max(1, int(round(cfg.adaptive_bias_cycles * 4 * cfg.adaptive_step_every / dt)))
    first_hold = max(1, int(round(cfg.adaptive_step_every / dt)))
    offset = np.zeros(n)
    k_est = np.full(n, np.nan)
    for k in range(n):
        if not slowed and t[k] >= cfg.adaptive_change_s:
            slow(ship, cfg.adaptive_speed_share)
            slowed = True
        meas = np.array([st["v"], st["r"], st["psi"]]) + rng.normal(0.0, noise_sd)
        if adapt and k > 0:
            t0 = _time.perf_counter()
            if cfg.adaptive_remove_rudder_offset:
                offset[k] = rudder_offset(delta, k, bias_win, first_hold)
            nis[k] = ident.update({"delta": prev_delta - offset[k], "v": meas[0], "r": meas[1],
                                   "psi": meas[2]})["nis"]
            id_secs += _time.perf_counter() - t0
        if adapt and k > 0 and k % every == 0 and k >= win:
            why = None
            rud_sd = float(np.std(delta[k - win:k]))
            nis_w = float(np.nanmean(nis[k - win:k]))
            idx = ident.estimate()["indices"]
            k_est[k] = idx["K"] if idx is not None else np.nan
            if rud_sd < cfg.adaptive_min_rudder_std:
                why = f"excitation: rudder sd {rud_sd:.2f} deg"
            elif not nis_w < cfg.adaptive_max_nis_ratio * 3:
                why = f"filter over-confident: window mean NIS {nis_w:.3g}"
            elif idx is None or not (idx["K"] > 0 and idx["T"] > 0):
                why = "no positive K, T in the estimate"
            if why is None and controller == "pid":
                # the PID's model K, T each move by at most the gain-change share; the integral term
                # Ki z is carried over unchanged (bumpless): z scaled by Ki_old / Ki_new
                k_cur = limited(idx["K"], k_cur, cfg.adaptive_max_gain_change)
                t_cur = limited(idx["T"], t_cur, cfg.adaptive_max_gain_change)
                new = pid_design(k_cur, t_cur, cfg)
                ctl.z *= ctl.design.Ki / new.Ki if new.Ki > 0 else 1.0
                ctl.design = new
                ctl.ref.r_max = new.r_max
                kp, kd = new.Kp, new.Kd
            elif why is None:
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
            "final": ident.estimate(), "rudder_offset": offset, "K_estimate": k_est}


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


def k_tracking(t: np.ndarray, k_est: np.ndarray, cfg: ControlConfig) -> dict[str, float]:
    """Mean identified K (1/s) over the last ``adaptive_step_every`` s before the speed change and over
    the last 2 x ``adaptive_step_every`` s of the run, and their ratio (a Nomoto K in 1/s scales with
    the speed at a constant K' = K L/U, so the ratio should follow ``adaptive_speed_share``)."""
    before = np.isfinite(k_est) & (t < cfg.adaptive_change_s) & (t >= cfg.adaptive_change_s
                                                                  - cfg.adaptive_step_every)
    end = np.isfinite(k_est) & (t >= t[-1] - 2 * cfg.adaptive_step_every)
    kb = float(np.mean(k_est[before])) if before.any() else float("nan")
    ke = float(np.mean(k_est[end])) if end.any() else float("nan")
    return {"K_before_change": kb, "K_end": ke, "ratio": ke / kb if kb else float("nan")}


def _paired(start: AdaptiveStart, seeds: list[int], cfg: ControlConfig, *, q_std,
            controller: str) -> tuple[dict[str, Any], float]:
    """Fixed and adaptive runs of one controller on the same seeds: rows, statistics, differences."""
    rows = {"adaptive": [], "fixed": []}
    gains, finals, id_secs, tracking = [], [], 0.0, []
    for seed in seeds:
        for name in ("fixed", "adaptive"):
            r = run_once(start, seed, cfg, adapt=name == "adaptive", q_std=q_std, controller=controller)
            m = after_change_metrics(r["t"], r["ref"], r["psi"], r["delta"], cfg)
            rows[name].append({"seed": seed, **m})
            if name == "adaptive":
                gains.append([{"t_s": g[0], "Kp": g[1], "Kd": g[2], "event": g[3]} for g in r["gains"]])
                finals.append(r["final"]["indices"])
                tracking.append({"seed": seed, **k_tracking(r["t"], r["K_estimate"], cfg)})
                id_secs += r["id_seconds"]
    keys = [k for k in rows["fixed"][0] if k != "seed"]
    summary = {}
    for name, rs in rows.items():
        summary[name] = {k: {"mean": float(np.nanmean([x[k] for x in rs])),
                             "std": float(np.nanstd([x[k] for x in rs], ddof=1)) if len(rs) > 1 else 0.0}
                         for k in keys}
    pairs = list(zip(rows["adaptive"], rows["fixed"], strict=True))
    diff = {k: float(np.nanmean([a[k] - b[k] for a, b in pairs])) for k in keys}
    return {"start": {"K": start.K, "T": start.T}, "seeds": seeds, "per_seed": rows, "stats": summary,
            "difference": {"what": "adaptive minus fixed, mean over the paired seeds", "metrics": diff},
            "gains_first_seed": gains[0] if gains else [], "final_indices": finals,
            "K_tracking": tracking}, id_secs


def adaptive_block(theta0, cov0, K0: float, T0: float, seeds: list[int], cfg: ControlConfig, *, q_std=None,
                   pid_start: tuple[float, float] | None = None) -> tuple[dict[str, Any], float]:
    """The ``adaptive`` block of control/metrics.json (adaptive against fixed gains on the same seeds)
    and the seconds spent in the streaming identifier's updates of the adaptive CGSA runs (for the
    terminal and the benchmark, never in the document: same inputs, same bytes).

    The CGSA (the paper's adaptive design) starts from K0 (1/s), T0 (s); with ``pid_start`` (K, T of
    the operating-point model) the project's PID runs the same scenario as ``pid`` (its model's K, T
    move at most ``adaptive_max_gain_change`` per re-design, its integral term carried over)."""
    start = AdaptiveStart(theta0, cov0, K0, T0)
    cg, id_secs = _paired(start, seeds, cfg, q_std=q_std, controller="cgsa")
    out = _cgsa_document(cg, cfg, K0, T0, seeds, q_std)
    if pid_start is not None:
        pid, _ = _paired(replace(start, K=pid_start[0], T=pid_start[1]), seeds, cfg, q_std=q_std,
                         controller="pid")
        out["pid"] = {k: v for k, v in pid.items() if k != "seeds"}
        out["pid"]["design"] = f"PID autopilot, Tw = {cfg.tw:g} s, re-designed from the moving K, T"
    return out, id_secs


def _cgsa_document(cg: dict[str, Any], cfg: ControlConfig, K0: float, T0: float, seeds: list[int],
                   q_std) -> dict[str, Any]:
    """The CGSA part of the block, with the scenario, the rule and the identifier's settings."""
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
        "seeds": seeds, "per_seed": cg["per_seed"], "stats": cg["stats"], "difference": cg["difference"],
        "gains_first_seed": cg["gains_first_seed"], "final_indices": cg["final_indices"],
        "rudder_offset": {"removed": cfg.adaptive_remove_rudder_offset,
                          "method": f"mean rudder over the last {cfg.adaptive_bias_cycles:g} course-change "
                                    "cycle(s) (before that, over the course held before the first change), "
                                    "subtracted from the rudder the identifier is fed"},
        "identifier_q_std": None if q_std is None else [float(q) for q in q_std],
        "K_tracking": {"what": "mean identified K (1/s) before the speed change and at the end, and their "
                               "ratio; a Nomoto K in 1/s scales with speed, so the ratio should follow "
                               "the speed share", "speed_share": cfg.adaptive_speed_share,
                       "per_seed": cg["K_tracking"]},
    }
