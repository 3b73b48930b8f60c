"""A process disturbance for the test truths: what measured runs carry and no candidate effect describes.

An external yaw moment (wind gusts in a sea trial, a tank's residual circulation) as a stationary
Ornstein-Uhlenbeck process: exact at the logging step, drawn afresh in every run from a random stream
of its own (``[seed, 1]``), so a truth's sensor noise is the same with and without it.  Each truth
scales it to its own yaw moment (tests/truths/mariner.py, tests/truths/kvlcc2.py).
"""

from __future__ import annotations

import math

import numpy as np


def ornstein_uhlenbeck(n: int, dt: float, tau: float, seed: int) -> np.ndarray:
    """``n`` samples, ``dt`` s apart, of a stationary Ornstein-Uhlenbeck process of unit standard
    deviation and correlation time ``tau`` s (x_k = a x_{k-1} + sqrt(1 - a^2) w_k, a = exp(-dt/tau),
    x_0 from the stationary law), drawn from the stream ``[seed, 1]``."""
    g = np.random.default_rng([seed, 1]).normal(0.0, 1.0, n)
    a = math.exp(-dt / tau)
    out = np.empty(n)
    out[0] = g[0]
    for i in range(1, n):
        out[i] = a * out[i - 1] + math.sqrt(1.0 - a * a) * g[i]
    return out
