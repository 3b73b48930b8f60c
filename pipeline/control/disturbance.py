"""Wind and wave disturbances, each as an equivalent rudder angle in deg added to the actual rudder.

Wave (paper; docs/control.md): G(s) = 0.2386 s / (s^2 + 0.3593 s + 0.8067) = Kw s/(s^2 + 2 lambda w0 s
+ w0^2), w0 = 0.898 rad/s, lambda = 0.20, sigma = 0.664, driven by unit-intensity continuous white noise
w (E[w(t) w(t+tau)] = delta(tau)).  In discrete time with step dt the noise is a sequence of
independent N(0, 1/dt) samples held over each step, and G is discretised exactly for that held input
(zero-order hold, python-control ``c2d``).  The output's variance then tends, as dt -> 0, to the
continuous one, int |G(j w)|^2 dw / (2 pi) = b^2/(2 a1) for G = b s/(s^2 + a1 s + a0)
(0.0792 deg^2, sigma 0.281 deg for the paper's numbers; the output is read in deg of rudder).

Wind (paper Eq. 14, printed garbled): here delta_wind = Kw (Vw/U)^2 sin(theta_w) deg, with Kw in
[0.5, 1], Vw/U the wind-to-ship speed ratio and theta_w the windward angle.  The square of the speed
ratio is our reconstruction (wind force and rudder force both scale with speed squared).  The
paper itself then uses a constant 2 deg, which is the default (``wind_model='constant'``).
"""

from __future__ import annotations

import control as ct
import numpy as np

from pipeline.config import ControlConfig
from pipeline.errors import ModelError
from pipeline.units import deg2rad


def wind_equivalent_rudder(kw: float, speed_ratio: float, angle_deg: float) -> float:
    """Wind as equivalent rudder (the paper's Eq. 14 form): Kw (Vw/U)^2 sin(theta_w).

    Parameters
    ----------
    kw : float
        Wind coefficient Kw, deg, in [0.5, 1].
    speed_ratio : float
        Wind to ship speed Vw/U (>= 0).
    angle_deg : float
        Relative wind angle theta_w, deg.

    Returns
    -------
    float
        Equivalent rudder, deg.

    Raises
    ------
    ModelError
        Kw outside [0.5, 1] or a negative speed ratio.
    """
    if not 0.5 <= float(kw) <= 1.0:
        raise ModelError(f"wind coefficient Kw = {kw} must lie in [0.5, 1]")
    if not float(speed_ratio) >= 0:
        raise ModelError(f"wind/ship speed ratio = {speed_ratio} must be >= 0")
    return float(kw) * float(speed_ratio) ** 2 * float(np.sin(deg2rad(float(angle_deg))))


def wind_from_config(cfg) -> float:
    """Constant equivalent wind rudder (deg) from a :class:`pipeline.config.ControlConfig`."""
    if cfg.wind_model == "constant":
        return float(cfg.wind_rudder)
    if cfg.wind_model == "eq14":
        return wind_equivalent_rudder(cfg.wind_kw, cfg.wind_speed_ratio, cfg.wind_angle)
    raise ModelError(f"unknown wind_model {cfg.wind_model!r} (use 'constant' or 'eq14')")


def wave_filter(num, den, dt: float) -> ct.StateSpace:
    """Exact ZOH discretisation of the wave shaping filter G(s) = num(s)/den(s) at step dt (s)."""
    num = np.asarray(num, dtype=float)
    den = np.asarray(den, dtype=float)
    if den.size < 1 or den[0] == 0 or num.size > den.size:
        raise ModelError("wave filter must be proper with a non-zero leading denominator coefficient")
    if not np.all(np.real(np.roots(den)) < 0):
        raise ModelError(f"wave filter denominator {den.tolist()} is not stable")
    if not dt > 0:
        raise ModelError(f"time step dt = {dt} must be > 0")
    return ct.c2d(ct.ss(ct.tf(num, den)), dt, method="zoh")


def wave_sequence(n: int, dt: float, seed: int, *, num=ControlConfig.wave_num,
                  den=ControlConfig.wave_den) -> np.ndarray:
    """Wave disturbance in deg of equivalent rudder.

    Unit continuous white noise (N(0, 1/dt) samples from ``numpy.random.default_rng(seed)``, held
    over each step) through G discretised exactly; the filter starts at rest.

    Parameters
    ----------
    n : int
        Samples.
    dt : float
        Sample step, s.
    seed : int
        The noise's seed (same seed, same sequence).
    num, den : tuple of float
        Numerator and denominator of the wave filter G(s) (s in rad/s), highest power first.

    Returns
    -------
    ndarray, shape (n,)
        The disturbance, deg of equivalent rudder.
    """
    sysd = wave_filter(num, den, dt)
    a, b, c, d = (np.asarray(m, dtype=float) for m in (sysd.A, sysd.B, sysd.C, sysd.D))
    w = np.random.default_rng(seed).normal(0.0, 1.0 / np.sqrt(dt), size=int(n))
    x = np.zeros(a.shape[0])
    out = np.empty(int(n))
    b = b[:, 0]
    c = c[0]
    d0 = float(d[0, 0])
    for k in range(int(n)):
        out[k] = c @ x + d0 * w[k]
        x = a @ x + b * w[k]
    return out


def wave_variance_theory(*, num=ControlConfig.wave_num, den=ControlConfig.wave_den) -> float:
    """Continuous-time output variance for unit white noise, int |G(jw)|^2 dw/(2 pi), via Lyapunov."""
    sys = ct.ss(ct.tf(np.asarray(num, float), np.asarray(den, float)))
    if np.any(np.abs(np.asarray(sys.D)) > 0):
        raise ModelError("wave filter must be strictly proper for a finite output variance")
    p = ct.lyap(np.asarray(sys.A), np.asarray(sys.B) @ np.asarray(sys.B).T)
    return float((np.asarray(sys.C) @ p @ np.asarray(sys.C).T)[0, 0])


def wave_variance_discrete(dt: float, *, num=ControlConfig.wave_num, den=ControlConfig.wave_den) -> float:
    """Exact stationary variance of :func:`wave_sequence` output (discrete Lyapunov, input var 1/dt)."""
    sysd = wave_filter(num, den, dt)
    a, b, c, d = (np.asarray(m, dtype=float) for m in (sysd.A, sysd.B, sysd.C, sysd.D))
    p = ct.dlyap(a, (b @ b.T) / dt)
    return float((c @ p @ c.T)[0, 0] + d[0, 0] ** 2 / dt)
