"""Run a manoeuvre in the virtual tank and log it as a canonical run (docs/contract.md).

Measurement noise: each logged signal gets seeded white noise of the one-sigma sizes in
:class:`pipeline.config.TankConfig`.  The run's noise seed is derived deterministically from
``cfg.seed`` and the run's test name (SHA-256, so it does not depend on Python's hash salt); the
zigzag logic counter-rudders on the MEASURED (noisy) heading, as a real tank's would.

Effect injection (TankConfig): the logged rudder is the servo angle; the forces see
``servo(t - rudder_delay) + rudder_offset``; ``extra_yaw_damping`` is added to N'_rrr;
``hold_speed`` keeps u at the approach speed.
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.config import TankConfig
from pipeline.errors import InputError
from pipeline.io import CANONICAL_COLUMNS, Run, atomic_path
from pipeline.runinfo import parse_test_name
from pipeline.tank.kcs import (
    DEFAULT_TANK,
    Command,
    Grid,
    KCSCoefficients,
    Servo,
    _run,
    initial_state,
    param_vector,
    trim_rps,
)
from pipeline.tank.manoeuvres import Manoeuvre
from pipeline.units import deg2rad, rad2deg

NOTE = "virtual tank (MMG model of the KCS, SIMMAN 2020 model scale); not measured data"
EFFECT_FIELDS = ("rudder_offset", "rudder_delay", "extra_yaw_damping", "hold_speed")
#: the servo and sensor effects of the detection-power study, in the metadata only when set (a clean
#: run's metadata names none of them)
SERVO_FIELDS = ("rudder_lag", "rudder_asymmetry", "rudder_stall_deg", "heading_misalignment")
#: Column formats of the CSV (decimals well below the noise sizes).
CSV_FORMATS = {"time": "%.3f", "x0": "%.4f", "y0": "%.4f", "psi": "%.4f", "u": "%.5f", "v": "%.5f",
               "r": "%.4f", "delta": "%.4f", "rpm": "%.2f"}


def noise_seed(seed: int, test_name: str) -> int:
    """The run's noise seed, independent of Python's hash salt.

    Parameters
    ----------
    seed : int
        ``TankConfig.seed``.
    test_name : str
        The manoeuvre's test name.

    Returns
    -------
    int
        A 63-bit integer from SHA-256 of ``'<seed>:<test_name>'``.
    """
    digest = hashlib.sha256(f"{int(seed)}:{test_name}".encode()).digest()
    return int.from_bytes(digest[:8], "little") >> 1


def _steps(cfg: TankConfig) -> tuple[int, float]:
    if not (cfg.log_dt > 0 and cfg.sim_dt > 0):
        raise InputError(f"tank: log_dt and sim_dt must be positive (got {cfg.log_dt}, {cfg.sim_dt})")
    for name in ("rudder_rate", "rudder_max", "approach_speed", "lpp", "scale"):
        if not getattr(cfg, name) > 0:
            raise InputError(f"tank: TankConfig.{name} must be positive, got {getattr(cfg, name)}")
    if not cfg.rudder_delay >= 0:
        raise InputError(f"tank: TankConfig.rudder_delay must be >= 0 s, got {cfg.rudder_delay}")
    if not cfg.rudder_lag >= 0:
        raise InputError(f"tank: TankConfig.rudder_lag must be >= 0 s, got {cfg.rudder_lag}")
    if not abs(cfg.rudder_asymmetry) < 1:
        raise InputError(f"tank: TankConfig.rudder_asymmetry must be in (-1, 1), got {cfg.rudder_asymmetry}")
    if not cfg.rudder_stall_deg >= 0:
        raise InputError(f"tank: TankConfig.rudder_stall_deg must be >= 0 deg, got {cfg.rudder_stall_deg}")
    sub = max(1, int(round(cfg.log_dt / cfg.sim_dt)))
    return sub, cfg.log_dt / sub


def simulate(manoeuvre: Manoeuvre, cfg: TankConfig = DEFAULT_TANK,
             coeffs: KCSCoefficients | None = None) -> Run:
    """Simulate ``manoeuvre`` in the virtual tank.

    Parameters
    ----------
    manoeuvre : Manoeuvre
        What to run (:mod:`pipeline.tank.manoeuvres`).
    cfg : TankConfig
        The tank (scale, approach speed, effects).
    coeffs : KCSCoefficients, optional
        The KCS coefficient set (default: the SIMMAN 2020 one; tests use a port/starboard-symmetric one).

    Returns
    -------
    Run
        The canonical columns time (s), x0, y0 (m), psi (deg), u, v (m/s), r (deg/s), delta (deg,
        the logged servo angle), rpm (1/min) at ``cfg.log_dt``, the first execute at t = 0 from a
        steady straight approach, and provenance metadata.

    Examples
    --------
    A 10/10 zigzag of the virtual KCS, 30 s, without logging noise:

    >>> from pipeline.config import TankConfig
    >>> from pipeline.tank import zigzag
    >>> run = simulate(zigzag(10.0, 10.0, duration=30.0), TankConfig(noise=False))
    >>> run.meta["provenance"], run.meta["test_name"], run.dt, len(run.frame)
    ('virtual', 'zigzag 10/10 starboard', 0.08, 376)
    >>> round(float(run.frame["u"].iloc[0]), 3)          # the approach speed, m/s (Fn 0.26)
    2.006
    >>> round(float(run.frame["delta"].iloc[1]), 3)      # the servo's 14.28 deg/s over one 0.08 s step
    1.142
    """
    coeffs = coeffs or KCSCoefficients()
    sub, h = _steps(cfg)
    n_log = int(round(manoeuvre.duration / cfg.log_dt)) + 1
    name = manoeuvre.test_name
    nseed = noise_seed(cfg.seed, name)
    rng = np.random.default_rng(nseed)
    sizes = {"psi": cfg.noise_psi, "r": cfg.noise_r, "u": cfg.noise_u, "v": cfg.noise_v,
             "x0": cfg.noise_xy, "y0": cfg.noise_xy, "delta": cfg.noise_delta}
    noise = {k: rng.standard_normal(n_log) * (s if cfg.noise else 0.0) for k, s in sizes.items()}
    rps = trim_rps(cfg, coeffs)
    p = param_vector(cfg, coeffs, rps)
    release = int(round(manoeuvre.pull_out_s / cfg.log_dt)) if manoeuvre.pull_out_s is not None else -1
    command = Command(manoeuvre.kind == "zigzag", deg2rad(manoeuvre.rudder_deg),
                      deg2rad(manoeuvre.heading_deg or 0.0), manoeuvre.sign, release)
    servo = Servo(deg2rad(cfg.rudder_rate), deg2rad(cfg.rudder_max), int(round(cfg.rudder_delay / h)),
                  deg2rad(cfg.rudder_offset), float(cfg.rudder_lag), float(cfg.rudder_asymmetry),
                  deg2rad(cfg.rudder_stall_deg))
    out = _run(p, initial_state(cfg), Grid(n_log, sub, h), command, servo, deg2rad(noise["psi"]))
    time = np.arange(n_log) * cfg.log_dt
    eps = deg2rad(cfg.heading_misalignment)     # 0: the readings are the ship's, bit for bit
    u_read, v_read = read_through_heading(out[:, 0], out[:, 1], eps)
    frame = pd.DataFrame({
        "time": time,
        "x0": out[:, 3] + noise["x0"],
        "y0": out[:, 4] + noise["y0"],
        "psi": rad2deg(out[:, 5] + eps) + noise["psi"],
        "u": u_read + noise["u"],
        "v": v_read + noise["v"],
        "r": rad2deg(out[:, 2]) + noise["r"],
        "delta": rad2deg(out[:, 6]) + noise["delta"],
        "rpm": np.full(n_log, 60.0 * rps),
    })
    meta = {
        "run_id": manoeuvre.file_stem,
        "provenance": "virtual",
        "test_name": name,
        **parse_test_name(name),
        "ship": "KCS",
        "lpp": cfg.lpp,
        "model_scale": cfg.scale,
        "dt": cfg.log_dt,
        "sim_dt": h,
        "seed": cfg.seed,
        "noise_seed": nseed,
        "noise": cfg.noise,
        "noise_std": sizes,
        "approach_speed": cfg.approach_speed,
        "rpm": 60.0 * rps,
        "rudder_rate": cfg.rudder_rate,
        "rudder_max": cfg.rudder_max,
        **({"pull_out_s": manoeuvre.pull_out_s} if manoeuvre.pull_out_s is not None else {}),
        "effects": {k: getattr(cfg, k) for k in EFFECT_FIELDS}
        | {k: getattr(cfg, k) for k in SERVO_FIELDS if getattr(cfg, k)},
        "model": "3-DOF MMG (Yasukawa & Yoshimura 2015), Yoshimura's KCS coefficients",
        "coefficients": asdict(coeffs),
        "note": NOTE,
    }
    meta.update(meta["effects"])
    return Run(frame=frame, meta=meta)


def read_through_heading(u, v, eps_rad: float):
    """(u, v) as read through a heading that reads ``eps_rad`` more than the centreline.

    The ship's velocity resolved in axes turned by eps, u cos eps + v sin eps and v cos eps - u sin eps
    (a tank that forms body velocities from its earth-fixed track and heading).

    Parameters
    ----------
    u, v : array
        Body-fixed velocities, m/s.
    eps_rad : float
        Heading misalignment, rad (0: (u, v) as given).

    Returns
    -------
    tuple of array
        The read (u, v), m/s.
    """
    if eps_rad == 0.0:
        return u, v
    c, s = np.cos(eps_rad), np.sin(eps_rad)
    return u * c + v * s, v * c - u * s


def _note(meta: dict) -> str:
    note = str(meta.get("note", NOTE))
    eff = meta.get("effects") or {}
    on = [f"{k}={v}" for k, v in eff.items() if v not in (0, 0.0, False, None)]
    if on:
        note += "; injected effects: " + ", ".join(on)
    if meta.get("noise") is False:
        note += "; noise-free"
    return note


def write_csv(path: str | Path, run: Run) -> Path:
    """Write ``run`` as the canonical CSV (docs/contract.md#raw-formats), atomically.

    Layout: ``# key: value`` lines (ship, provenance, test, lpp, scale, dt, seed, note), then the
    header ``time,x0,y0,psi,u,v,r,delta,rpm`` and one comma-separated row per sample.

    Parameters
    ----------
    path : str or Path
        The file to write.
    run : Run
        A run in the canonical columns and units.

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    m = run.meta
    lines = [
        f"# ship: {m.get('ship', 'KCS')}",
        f"# provenance: {m.get('provenance', 'virtual')}",
        f"# test: {m['test_name']}",
        f"# lpp: {m.get('lpp', TankConfig.lpp):g}",
        f"# scale: {m.get('model_scale', TankConfig.scale):g}",
        f"# dt: {m.get('dt', run.dt):g}",
        f"# seed: {m.get('seed', '')}",
        f"# note: {_note(m)}",
        ",".join(CANONICAL_COLUMNS),
    ]
    cols = [c for c in CANONICAL_COLUMNS if c not in run.frame.columns]
    if cols:
        raise InputError("run lacks canonical columns for the CSV", file=path, column=cols[0])
    data = run.frame[list(CANONICAL_COLUMNS)].to_numpy(dtype=float)
    fmt = [CSV_FORMATS[c] for c in CANONICAL_COLUMNS]
    with atomic_path(path, suffix=".csv") as tmp:
        with open(tmp, "w", newline="\n") as fh:
            fh.write("\n".join(lines) + "\n")
            np.savetxt(fh, data, fmt=fmt, delimiter=",")
    return path
