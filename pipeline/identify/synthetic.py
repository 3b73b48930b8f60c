"""Synthetic zigzag runs simulated from the identification model itself (for tests and benchmarks).

The truth is :func:`pipeline.model.step` with given parameters; the rudder follows the zigzag logic
(execute to +rudder, counter-rudder when the heading passes +-heading) with a rate limit; Gaussian
noise of the given one-sigma is added to the logged v, r, psi (seeded).  ``process_noise`` (one-sigma
per step of v, r, psi, as the filter's Q) makes the truth what the filter assumes, for consistency
tests; it is drawn from its own seeded stream, so runs without it are unchanged.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from pipeline.config import FilterConfig, TankConfig
from pipeline.io import Run
from pipeline.model import PAPER_TABLE4, as_theta


def zigzag(theta=None, *, rudder: float = 20.0, heading: float = 20.0, n: int = 1200,
           h: float = FilterConfig.dt, rate: float = TankConfig.rudder_rate, noise=FilterConfig.r_std,
           seed: int = 0, first: int = 1, process_noise=None):
    """Simulate a zigzag.  Returns (time s, delta deg, clean (n, 3), noisy (n, 3)) of v m/s, r deg/s,
    psi deg.  ``first`` = +1 starts with positive rudder (positive delta makes r positive).  The
    step ``h`` (s) and the logger noise (one-sigma of v m/s, r deg/s, psi deg) default to the filter's
    step and measurement noise (:class:`pipeline.config.FilterConfig`), the paper's setting."""
    th = as_theta(PAPER_TABLE4 if theta is None else theta)
    a11, a12, a21, a22, b11, b21 = th
    rng = np.random.default_rng(seed)
    rng_q = np.random.default_rng([seed, 1])
    q = None if process_noise is None else np.asarray(process_noise, float)
    x = np.zeros(3)
    target = first * rudder
    d = 0.0
    delta = np.empty(n)
    clean = np.empty((n, 3))
    for k in range(n):
        if target > 0 and x[2] >= heading:
            target = -rudder
        elif target < 0 and x[2] <= -heading:
            target = rudder
        d += float(np.clip(target - d, -rate * h, rate * h))
        delta[k] = d
        clean[k] = x
        v, r, psi = x
        x = np.array([v + h * (a11 * v + a12 * r + b11 * d), r + h * (a21 * v + a22 * r + b21 * d),
                      psi + h * r])
        if q is not None:
            x = x + rng_q.standard_normal(3) * q
    noisy = clean + rng.standard_normal((n, 3)) * np.asarray(noise, float)
    return np.arange(n) * h, delta, clean, noisy


def zigzag_run(run_id: str, theta=None, *, rudder: float = 20.0, heading: float = 20.0, n: int = 1200,
               h: float = FilterConfig.dt, seed: int = 0, noise=FilterConfig.r_std, with_v: bool = True,
               process_noise=None) -> Run:
    """A processed :class:`~pipeline.io.Run` of a simulated zigzag (provenance 'virtual')."""
    t, d, _, y = zigzag(theta, rudder=rudder, heading=heading, n=n, h=h, seed=seed, noise=noise,
                          process_noise=process_noise)
    frame = pd.DataFrame({"time": t, "psi": y[:, 2], "u": np.full(n, 1.0), "r": y[:, 1], "delta": d})
    if with_v:
        frame.insert(3, "v", y[:, 0])
    name = f"zigzag {rudder:g}/{heading:g} starboard"
    meta = {"run_id": run_id, "test_name": name, "provenance": "virtual", "kind": "zigzag",
            "rudder_deg": rudder, "heading_deg": heading, "first_side": "starboard", "dt": h,
            "source_file": f"synthetic:{run_id}", "samples": n}
    return Run(frame=frame, meta=meta)
