"""A simple linear truth model with injectable effects: the clean reference for testing the diagnosis.

The truth is docs/contract.md#the-identification-model's sway-yaw model in continuous time (integrated with 8
Euler sub-steps per logged sample, so the fitted discrete model is not the generating one), run as a zigzag
with a rate-limited rudder servo and counter-rudder triggered by the *measured* heading, as a tank would.
Effects (each off by default) act as docs/diagnosis.md defines them:

- ``rudder_offset`` deg: effective rudder = logged + offset;
- ``rudder_delay`` s: effective rudder = logged(t - delay);
- ``n_rrr`` s/deg^2: r' gains n_rrr r^3 (Norrbin cubic yaw damping, negative = more damping);
- ``y_vv`` 1/m, ``n_vv`` deg/m^2: cross-flow drag, v' gains y_vv v|v| and r' gains n_vv v|v|
  (negative y_vv = more sway damping; in pure sway the drag of a fore-aft near-symmetric hull has
  little moment, so the study injects y_vv alone, as the KCS's MMG N'vvv is small beside Y'vvv);
- ``n_vvr`` s/m^2: r' gains n_vvr v^2 r (Abkowitz's sway-yaw cross term, in the yaw equation only;
  negative = more yaw damping while drifting);
- ``rudder_stall_deg`` deg: the rudder force follows stall_deg tanh(delta_eff / stall_deg) instead of
  delta_eff (a smooth lift saturation, not the catalogue's cubic form; 0 = off);
- ``speed_loss_k``: surge u' = -(u - U0)/tau_u - k U0 (r in rad/s)^2; the linear coefficients scale
  with u/U0 and the rudder terms with (u/U0)^2 (dimensional coefficients ~ U/L, rudder force ~ U^2);
- ``heading_misalignment`` deg: a sensor effect, not the ship's: the logged heading reads eps more
  than the centreline and u, v are read through it (v cos eps - u sin eps, u cos eps + v sin eps).

Without effects the data are exactly linear plus seeded white measurement noise: "clean" means that.
The logged rudder is the servo's output (what a rudder-angle sensor reads).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline.io import Run
from pipeline.model import PAPER_TABLE4, as_theta


@dataclass(frozen=True)
class TruthConfig:
    # a11 a12 a21 a22 b11 b21, in the units of docs/contract.md#run-data
    theta: tuple[float, ...] = tuple(PAPER_TABLE4.values())
    u0: float = 2.0  # m/s approach speed
    dt: float = 0.08  # s logging step
    substeps: int = 8
    rudder_rate: float = 14.0  # deg/s servo rate
    rudder_offset: float = 0.0  # deg
    rudder_delay: float = 0.0  # s
    rudder_lag: float = 0.0  # s, first-order servo lag: d(delta_eff)/dt = (delta - delta_eff) / lag
    rudder_asymmetry: float = 0.0  # 1: force ~ delta_eff (1 + a sign(delta_eff)), a > 0 stronger to starboard
    n_rrr: float = 0.0  # s/deg^2
    y_vv: float = 0.0  # 1/m, sway cross-flow drag v|v|
    n_vv: float = 0.0  # deg/m^2, its yaw moment
    n_vvr: float = 0.0  # s/m^2, yaw cross term v^2 r
    rudder_stall_deg: float = 0.0  # deg, rudder force ~ stall tanh(delta_eff / stall); 0 = linear
    speed_loss_k: float = 0.0  # non-dimensional surge loss coefficient
    heading_misalignment: float = 0.0  # deg, a sensor: psi reads this much more, u and v read through it
    tau_u: float = 12.0  # s, surge recovery time constant
    noise: bool = True
    noise_psi: float = 0.05  # deg
    noise_r: float = 0.05  # deg/s
    noise_v: float = 0.005  # m/s
    noise_u: float = 0.005  # m/s
    noise_delta: float = 0.05  # deg
    seed: int = 0


def zigzag_truth(
    rudder_deg: float,
    heading_deg: float,
    first_side: str = "starboard",
    duration: float = 100.0,
    cfg: TruthConfig = TruthConfig(),
) -> Run:
    """Simulate a rudder/heading zigzag of the truth model.

    Parameters
    ----------
    rudder_deg : float
        Rudder amplitude, deg.
    heading_deg : float
        Heading change that triggers each rudder reversal, deg.
    first_side : str
        ``"starboard"`` (positive rudder first) or ``"port"``.
    duration : float
        Length of the run, s.
    cfg : TruthConfig
        The truth model, its effects, noise and seed (same config, same bytes).

    Returns
    -------
    Run
        A processed-style run in the units of docs/contract.md#run-data (provenance "virtual").
    """
    a11, a12, a21, a22, b11, b21 = as_theta(cfg.theta)
    rng = np.random.default_rng(cfg.seed)
    h = cfg.dt / cfg.substeps
    n = int(round(duration / cfg.dt)) + 1
    nsub = (n - 1) * cfg.substeps + 1
    sign = 1.0 if first_side == "starboard" else -1.0
    lag = int(round(cfg.rudder_delay / h))
    hist = np.zeros(nsub + 1)  # servo rudder per sub-step (for the delay)
    v = r = psi = 0.0
    u = cfg.u0
    d = 0.0
    d_lagged = 0.0  # deg, the servo lag's state
    cmd = sign * rudder_deg
    out = np.zeros((n, 6))  # time psi r v u delta (true)
    noise_psi = rng.normal(0.0, cfg.noise_psi, n) if cfg.noise else np.zeros(n)
    psi_meas = 0.0
    for i in range(nsub):
        if i % cfg.substeps == 0:
            k = i // cfg.substeps
            out[k] = (k * cfg.dt, psi, r, v, u, d)
            psi_meas = psi + noise_psi[k]
            # counter-rudder when the measured heading passes the trigger on the commanded side
            if cmd > 0 and psi_meas >= heading_deg:
                cmd = -rudder_deg
            elif cmd < 0 and psi_meas <= -heading_deg:
                cmd = rudder_deg
        step = np.clip(cmd - d, -cfg.rudder_rate * h, cfg.rudder_rate * h)
        d += step
        hist[i] = d
        d_in = hist[i - lag] if i >= lag else 0.0
        if cfg.rudder_lag > 0.0:  # explicit Euler of the lag: h / lag <= 0.1 for lags >= 0.1 s
            d_in, d_lagged = d_lagged, d_lagged + h * (d_in - d_lagged) / cfg.rudder_lag
        d_eff = d_in + cfg.rudder_offset
        if cfg.rudder_asymmetry:
            d_eff *= 1.0 + cfg.rudder_asymmetry * np.sign(d_eff)
        if cfg.rudder_stall_deg > 0.0:
            d_eff = cfg.rudder_stall_deg * np.tanh(d_eff / cfg.rudder_stall_deg)
        s = u / cfg.u0
        dv = s * a11 * v + s * a12 * r + s * s * b11 * d_eff
        dr = s * a21 * v + s * a22 * r + s * s * b21 * d_eff + cfg.n_rrr * r**3
        if cfg.y_vv or cfg.n_vv or cfg.n_vvr:  # only when set: a clean truth keeps the linear bits
            dv += cfg.y_vv * v * abs(v)
            dr += cfg.n_vv * v * abs(v) + cfg.n_vvr * v * v * r
        du = -(u - cfg.u0) / cfg.tau_u - cfg.speed_loss_k * cfg.u0 * np.deg2rad(r) ** 2
        psi += h * r
        v += h * dv
        r += h * dr
        u += h * du
    frame = pd.DataFrame(
        {
            "time": out[:, 0],
            "psi": out[:, 1],
            "r": out[:, 2],
            "v": out[:, 3],
            "u": out[:, 4],
            "delta": out[:, 5],
        }
    )
    if cfg.heading_misalignment:  # read through a heading set off the centreline: axes turned by eps
        c, sn = np.cos(np.deg2rad(cfg.heading_misalignment)), np.sin(np.deg2rad(cfg.heading_misalignment))
        frame["u"], frame["v"] = out[:, 4] * c + out[:, 3] * sn, out[:, 3] * c - out[:, 4] * sn
        frame["psi"] += cfg.heading_misalignment
    if cfg.noise:
        frame["psi"] += noise_psi
        frame["r"] += rng.normal(0.0, cfg.noise_r, n)
        frame["v"] += rng.normal(0.0, cfg.noise_v, n)
        frame["u"] += rng.normal(0.0, cfg.noise_u, n)
        frame["delta"] += rng.normal(0.0, cfg.noise_delta, n)
    side = "S" if first_side == "starboard" else "P"
    name = f"truth_zigzag_{rudder_deg:g}_{heading_deg:g}_{side}"
    meta = {
        "run_id": name,
        "provenance": "virtual",
        "test_name": f"zigzag {rudder_deg:g}/{heading_deg:g} {first_side}",
        "kind": "zigzag",
        "rudder_deg": rudder_deg,
        "heading_deg": heading_deg,
        "first_side": first_side,
        "dt": cfg.dt,
        "source_format": "truth-model",
    }
    return Run(frame=frame, meta=meta)


def yaw_rate_amplitude(run: Run, skip_s: float = 10.0) -> float:
    """Largest |r| (deg/s) after ``skip_s`` seconds (the zigzag's yaw-rate amplitude)."""
    f = run.frame
    return float(np.abs(f["r"].to_numpy()[f["time"].to_numpy() >= skip_s]).max())


def lowest_speed_ratio(run: Run) -> float:
    """min(u)/u(0) over the run."""
    u = run.frame["u"].to_numpy()
    return float(u.min() / u[0])


def _bisect(fun, lo: float, hi: float, target: float, iters: int = 30) -> float:
    """Solve fun(x) = target for monotone increasing fun on [lo, hi]."""
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        if fun(mid) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _clean(cfg: TruthConfig) -> TruthConfig:
    """``cfg`` without noise and without any effect (the same ship)."""
    return dataclasses.replace(
        cfg, noise=False, n_rrr=0.0, rudder_offset=0.0, rudder_delay=0.0, speed_loss_k=0.0,
        rudder_lag=0.0, rudder_asymmetry=0.0, y_vv=0.0, n_vv=0.0, n_vvr=0.0, rudder_stall_deg=0.0,
    )


def damping_for_cut(cut: float, cfg: TruthConfig = TruthConfig(), duration: float = 60.0) -> float:
    """n_rrr (s/deg^2, negative) that cuts the yaw-rate amplitude of the truth's 20/20 zigzag by ``cut``."""
    return _coefficient_for_change("n_rrr", -1.0, cut, 0.05, cfg, duration)


def speed_loss_for(loss: float, cfg: TruthConfig = TruthConfig(), duration: float = 60.0) -> float:
    """speed_loss_k giving the lowest speed (1 - ``loss``) u0 in the truth's 20/20 zigzag."""
    clean = _clean(cfg)

    def drop(k):
        return 1.0 - lowest_speed_ratio(
            zigzag_truth(20, 20, "starboard", duration, dataclasses.replace(clean, speed_loss_k=k))
        )

    return _bisect(drop, 0.0, 20.0, loss)


def sway_velocity_amplitude(run: Run, skip_s: float = 10.0) -> float:
    """Largest |v| (m/s) after ``skip_s`` seconds (the zigzag's sway-velocity amplitude)."""
    f = run.frame
    return float(np.abs(f["v"].to_numpy()[f["time"].to_numpy() >= skip_s]).max())


def _coefficient_for_change(name: str, sign: float, change: float, hi: float, cfg: TruthConfig,
                            duration: float, amplitude=yaw_rate_amplitude) -> float:
    """Value of the truth field ``name`` (sign ``sign``) that changes ``amplitude`` (default: the peak
    yaw rate) of the truth's 20/20 zigzag by the fraction ``change`` (either way); bisection on the
    field's size in [0, ``hi``]."""
    clean = _clean(cfg)
    amp0 = amplitude(zigzag_truth(20, 20, "starboard", duration, clean))

    def rel(mag):
        run = zigzag_truth(20, 20, "starboard", duration, dataclasses.replace(clean, **{name: sign * mag}))
        return abs(1.0 - amplitude(run) / amp0)

    return sign * _bisect(rel, 0.0, hi, change)


def sway_drag_for_cut(cut: float, cfg: TruthConfig = TruthConfig(), duration: float = 60.0) -> float:
    """y_vv (1/m, negative) cutting the 20/20 peak sway velocity by the fraction ``cut`` (sway only)."""
    return _coefficient_for_change("y_vv", -1.0, cut, 50.0, cfg, duration, sway_velocity_amplitude)


def cross_term_for_change(change: float, cfg: TruthConfig = TruthConfig(), duration: float = 60.0) -> float:
    """n_vvr (s/m^2, negative) changing the 20/20 peak yaw rate by the fraction ``change``."""
    return _coefficient_for_change("n_vvr", -1.0, change, 200.0, cfg, duration)


def stall_loss(stall_deg: float, at_deg: float) -> float:
    """Fraction of the rudder force lost at ``at_deg`` (deg) under the stall law stall tanh(delta /
    stall) of ``rudder_stall_deg`` = ``stall_deg`` (deg): 1 - stall tanh(at / stall) / at."""
    return float(1.0 - stall_deg * np.tanh(at_deg / stall_deg) / at_deg)


def stall_for_loss(loss: float, max_deg: float = 20.0) -> float:
    """Stall angle (deg) whose :func:`stall_loss` at ``max_deg`` is ``loss`` (a fraction): the rudder
    force lost at ``max_deg``.  Bisection on 1/stall (the loss grows with it)."""
    if not 0.0 < loss < 1.0:
        raise ValueError(f"rudder force loss must be in (0, 1), got {loss}")
    return 1.0 / _bisect(lambda inv: stall_loss(1.0 / inv, max_deg), 1e-9, 50.0 / max_deg, loss, iters=60)
