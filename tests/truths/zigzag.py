"""The zigzag test as a tank runs it, shared by the full-scale truths (kvlcc2, mariner, tanker).

Each truth gives its own equations of motion (``rhs``) and what it logs (``row``); this module only
drives them: the logging instants, the zigzag logic on the *measured* heading (execute at
``t_execute``, counter-rudder at a logging instant when the measured heading passes
+-``heading_deg``) and classical RK4 at ``h`` s between logging instants, the rudder command and any
external disturbance held over the sub-steps.  No pipeline code.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import pandas as pd

RAD = math.pi / 180.0


def rk4(rhs: Callable, x: list, h: float, *args) -> list:
    """One classical Runge-Kutta step of x' = rhs(x, *args) over ``h``."""
    k1 = rhs(x, *args)
    k2 = rhs([a + 0.5 * h * b for a, b in zip(x, k1, strict=True)], *args)
    k3 = rhs([a + 0.5 * h * b for a, b in zip(x, k2, strict=True)], *args)
    k4 = rhs([a + h * b for a, b in zip(x, k3, strict=True)], *args)
    return [a + h / 6.0 * (b1 + 2 * b2 + 2 * b3 + b4)
            for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4, strict=True)]


def run(
    rhs: Callable,
    x0: Sequence[float],
    row: Callable[[float, list], Sequence[float]],
    psi_deg: Callable[[list], float],
    rudder_deg: float,
    heading_deg: float,
    first_side: str,
    n: int,
    dt_log: float,
    h: float,
    t_execute: float,
    psi_noise: np.ndarray,
    dist: np.ndarray | None = None,
    command: Callable[[float], float] = lambda c: c,
) -> np.ndarray:
    """The logged rows (``row(t, state)`` at each of ``n`` instants ``dt_log`` apart) of a zigzag.

    ``rhs(x, command, n_ext)``: the truth's state derivative under the (truth-signed) rudder command
    rad and an external disturbance (its units); ``command`` maps the contract-signed command (rad,
    positive turning to starboard) to the truth's sign; ``psi_deg(x)``: the true heading, deg, to
    which ``psi_noise[i]`` is added for the zigzag logic; ``dist[i]``: the disturbance held from
    instant i to i + 1 (none: 0)."""
    sub = int(round(dt_log / h))
    sign = 1.0 if first_side == "starboard" else -1.0
    x = list(x0)
    out = None
    cmd, executed = 0.0, False          # contract-signed command, rad
    for i in range(n):
        t = i * dt_log
        r = row(t, x)
        if out is None:
            out = np.zeros((n, len(r)))
        out[i] = r
        psi_meas = psi_deg(x) + psi_noise[i]
        if not executed and t >= t_execute - 1e-9:
            cmd, executed = sign * rudder_deg * RAD, True
        elif executed:
            if cmd > 0 and psi_meas >= heading_deg:
                cmd = -rudder_deg * RAD
            elif cmd < 0 and psi_meas <= -heading_deg:
                cmd = rudder_deg * RAD
        if i == n - 1:
            break
        ne = 0.0 if dist is None else float(dist[i])
        c = command(cmd)
        for _ in range(sub):
            x = rk4(rhs, x, h, c, ne)
    return out


def sensor_noise(n: int, scale: float, seed: int, noise: bool = True, extra: dict | None = None) -> dict:
    """White sensor noise of the full-scale truths' logged channels (``n`` samples each), from
    model-scale figures Froude-scaled at 1:``scale``: psi 0.05 deg, r 0.05 deg/s, u and v 0.005 m/s,
    delta 0.05 deg, then ``extra`` (channel: full-scale std), drawn in that order from
    ``default_rng(seed)``; zeros when ``noise`` is False."""
    rng = np.random.default_rng(seed)
    sq = math.sqrt(scale)
    sig = {"psi": 0.05, "r": 0.05 / sq, "u": 0.005 * sq, "v": 0.005 * sq, "delta": 0.05, **(extra or {})}
    return {k: (rng.normal(0.0, v, n) if noise else np.zeros(n)) for k, v in sig.items()}


def logged(rows: np.ndarray, columns: list[str], noise: dict) -> pd.DataFrame:
    """The logged frame: the rows as measured (each channel of ``noise`` added), the true series in
    ``attrs["true"]``."""
    f = pd.DataFrame(rows, columns=columns)
    f.attrs["true"] = f.copy()
    for k, e in noise.items():
        f[k] = f[k] + e
    return f
