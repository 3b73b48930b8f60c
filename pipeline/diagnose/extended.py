"""The extended sway-yaw model: SPEC section 5's linear model plus the candidate effects of section 7.

Units as SPEC section 5: v m/s, r deg/s, psi deg, delta deg, step h s, u m/s.  With all effect
parameters at their null values the simulator is exactly :func:`pipeline.model.simulate`.

    d_eff(k) = delta(t_k - (tau - h)) + delta0                   rudder_delay tau s, rudder_offset delta0 deg
    s(k)     = (u(k) / U_ref) ** n                               speed_loss: exponent n (n = 1 is the
                                                                 physics: dimensional a_ij ~ U/L, b ~ U^2)
    v(k+1)   = v + h (s a11 v + s a12 r + s^2 b11 d_eff)
    r(k+1)   = r + h (s a21 v + s a22 r + s^2 b21 d_eff + n_rrr r^3)   nonlinear_yaw_damping (Norrbin)
    psi(k+1) = psi + h r

``n_rrr`` is in s/deg^2 (r in deg/s, r^3 n_rrr in deg/s^2); negative means more damping.
The delayed rudder is linearly interpolated on the logged time grid (the rudder before the run
start is taken as its first value).

Dead time and the Euler step: SPEC's discrete model responds about one step h later than the
continuous ship whose samples it fits (the rudder is held over the step, half a step; psi follows
r by the rectangle rule, half a step).  Measured on the linear truth model (:mod:`.truth`), a free
delay fitted to clean data settles at -0.06 to -0.09 s with h = 0.08 s, and injected dead times come
out low by the same amount.  So ``delay_s`` is the *physical* dead time and the logged rudder is
shifted by (delay_s - h).  ``delay_s=None`` means no delay effect: no shift at all, exactly the SPEC
model; the delay model nests the baseline at delay_s = h.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from pipeline.errors import ModelError
from pipeline.model import as_theta

EFFECTS = ("rudder_offset", "nonlinear_yaw_damping", "rudder_delay", "speed_loss")
#: the effect's own parameter (the one tested against zero) and its null value
EFFECT_PARAM = {
    "rudder_offset": "offset_deg",
    "nonlinear_yaw_damping": "n_rrr_s_per_deg2",
    "rudder_delay": "delay_s",
    "speed_loss": "speed_exponent",
}
NULL = {"offset_deg": 0.0, "n_rrr_s_per_deg2": 0.0, "delay_s": None, "speed_exponent": 0.0}
_CLIP_R = 200.0  # deg/s: a diverging trial model is clipped here so residuals stay finite
_CLIP_V = 50.0  # m/s


@njit(cache=True)
def _sim_kernel(theta, n_rrr, s, d, x0, h):  # pragma: no cover - compiled
    a11, a12, a21, a22, b11, b21 = theta[0], theta[1], theta[2], theta[3], theta[4], theta[5]
    n = d.shape[0]
    out = np.empty((n, 3))
    v, r, psi = x0[0], x0[1], x0[2]
    for k in range(n):
        out[k, 0] = v
        out[k, 1] = r
        out[k, 2] = psi
        sk = s[k]
        sb = sk * sk
        vn = v + h * (sk * a11 * v + sk * a12 * r + sb * b11 * d[k])
        rn = r + h * (sk * a21 * v + sk * a22 * r + sb * b21 * d[k] + n_rrr * r * r * r)
        psi = psi + h * r
        if vn > _CLIP_V:
            vn = _CLIP_V
        elif vn < -_CLIP_V:
            vn = -_CLIP_V
        if rn > _CLIP_R:
            rn = _CLIP_R
        elif rn < -_CLIP_R:
            rn = -_CLIP_R
        v, r = vn, rn
    return out


def effective_rudder(
    t: np.ndarray, delta: np.ndarray, offset_deg: float = 0.0, delay_s: float | None = None
) -> np.ndarray:
    """Rudder the model is driven with (deg): logged rudder plus ``offset_deg``; with a physical dead
    time ``delay_s`` (s) the logged rudder is shifted by (delay_s - h) (see module docstring)."""
    d = np.asarray(delta, dtype=float)
    t = np.asarray(t, dtype=float)
    if delay_s is not None:
        shift = float(delay_s) - float(t[1] - t[0])
        if shift != 0.0:
            d = np.interp(t - shift, t, d, left=d[0], right=d[-1])
    return d + offset_deg


def speed_factor(u_ratio: np.ndarray | None, n: int, exponent: float) -> np.ndarray:
    """Coefficient scale (u/U_ref)^exponent (ones when there is no speed ratio or exponent is 0)."""
    if u_ratio is None or exponent == 0.0:
        return np.ones(n)
    return np.power(np.clip(u_ratio, 0.05, None), exponent)


def simulate_extended(
    theta,
    x0,
    delta,
    h: float,
    *,
    t=None,
    offset_deg: float = 0.0,
    n_rrr_s_per_deg2: float = 0.0,
    delay_s: float | None = None,
    u_ratio=None,
    speed_exponent: float = 0.0,
) -> np.ndarray:
    """Free-run simulation of the extended model (see module docstring).

    Parameters
    ----------
    theta : the six linear parameters (SPEC section 5 units).
    x0 : initial (v m/s, r deg/s, psi deg).
    delta : logged rudder, deg, length N.
    h : step, s.
    t : time, s (defaults to k h).
    delay_s : physical rudder dead time, s, or None for no delay effect.
    u_ratio : u / U_ref per sample (needed only with speed_loss).

    Returns (N, 3) array of (v, r, psi); row 0 is ``x0``.
    """
    th = as_theta(theta)
    d = np.asarray(delta, dtype=float)
    if d.ndim != 1 or d.size < 2:
        raise ModelError("rudder series must be one-dimensional with at least 2 samples")
    if t is None:
        t = np.arange(d.size) * h
    de = effective_rudder(t, d, offset_deg, delay_s)
    s = speed_factor(None if u_ratio is None else np.asarray(u_ratio, dtype=float), d.size, speed_exponent)
    return _sim_kernel(th, float(n_rrr_s_per_deg2), s, de, np.asarray(x0, dtype=float).reshape(3), float(h))
