"""Course-keeping metrics (docs/contract.md#metrics) on a simulated or measured course change.

Definitions (all angles deg, times s; the course step goes from psi(0) to the set course):

* ``rise_time``: the first time the heading is within ``band`` (default 5 %) of the step size of the
  set course, i.e. |psi - psi_set| <= band |psi_set - psi(0)|  ("time to first reach 95 %").
* ``rise_time_10_90``: time from first reaching 10 % to first reaching 90 % of the step.
* ``reach_time``: the first time the heading reaches the set course (covers 100 % of the step);
  NaN when it never does (e.g. a steady offset on the near side).
* ``max_deviation``: max |psi - psi_set| after the set course is first reached (from ``reach_time``,
  or from ``rise_time`` when the course is never reached): overshoot and course-keeping error.
* ``steady_mae``: mean |psi - psi_set| over the steady window t >= ``steady_start``.
* ``max_rudder``: max |delta| over the whole run (actual rudder).
* ``steady_rudder_min`` / ``steady_rudder_max``: range of delta over the steady window;
  ``mean_rudder``: mean of delta over the steady window.
* ``rudder_energy``: integral of delta^2 dt over the steady window (deg^2 s);
  ``rudder_rms``: sqrt(mean delta^2) there;
  ``rudder_reversals``: number of reversals of the rudder's direction of motion in the steady window,
  counting only swings of at least ``threshold`` deg (hysteresis, so round-off does not count).
"""

from __future__ import annotations

import numpy as np

from pipeline.config import ControlConfig
from pipeline.errors import InputError

#: How "worse" reads for each metric over seeds: 'max' (larger is worse), 'min', or 'absmax'.
WORST = {
    "rise_time": "max", "rise_time_10_90": "max", "reach_time": "max", "max_deviation": "max",
    "steady_mae": "max",
    "max_rudder": "max", "steady_rudder_min": "min", "steady_rudder_max": "max",
    "mean_rudder": "absmax", "rudder_energy": "max", "rudder_rms": "max", "rudder_reversals": "max",
}


def _arrays(*arrays):
    out = [np.asarray(a, dtype=float).reshape(-1) for a in arrays]
    n = out[0].size
    if any(a.size != n for a in out):
        raise InputError("time series of different lengths")
    if n < 2:
        raise InputError("too few samples for course metrics (need at least 2)")
    if not all(np.all(np.isfinite(a)) for a in out):
        raise InputError("NaN or infinite value in a course time series")
    return out


def first_time_within(t, psi, target: float, tol: float) -> float:
    """First time |psi - target| <= tol (NaN if never)."""
    t, psi = _arrays(t, psi)
    idx = np.flatnonzero(np.abs(psi - target) <= tol)
    return float(t[idx[0]]) if idx.size else float("nan")


def first_time_fraction(t, psi, start: float, target: float, fraction: float) -> float:
    """First time the heading has covered ``fraction`` of the step start -> target (NaN if never)."""
    t, psi = _arrays(t, psi)
    step = target - start
    if step == 0:
        return float("nan")
    prog = (psi - start) / step
    idx = np.flatnonzero(prog >= fraction)
    return float(t[idx[0]]) if idx.size else float("nan")


def rudder_reversals(delta, threshold: float = ControlConfig.reversal_threshold) -> int:
    """Number of reversals of the direction of rudder motion, each swing at least ``threshold`` deg.

    Hysteresis count: a direction is established once the rudder has moved ``threshold`` from its
    running extreme; a reversal is counted when it then moves back by ``threshold`` from the new extreme.
    """
    (d,) = _arrays(delta)
    if not threshold > 0:
        raise InputError(f"reversal threshold = {threshold} must be > 0 deg")
    count, direction = 0, 0
    lo = hi = ext = d[0]
    for x in d[1:]:
        if direction == 0:
            lo, hi = min(lo, x), max(hi, x)
            if x - lo >= threshold:
                direction, ext = 1, x
            elif hi - x >= threshold:
                direction, ext = -1, x
        elif direction == 1:
            if x > ext:
                ext = x
            elif ext - x >= threshold:
                count, direction, ext = count + 1, -1, x
        else:
            if x < ext:
                ext = x
            elif x - ext >= threshold:
                count, direction, ext = count + 1, 1, x
    return int(count)


def course_metrics(t, psi, delta, setpoint: float, *, band: float = ControlConfig.settle_band,
                   steady_start: float = ControlConfig.steady_start,
                   reversal_threshold: float = ControlConfig.reversal_threshold) -> dict:
    """All course and rudder metrics of one run (definitions in the module docstring).

    Parameters
    ----------
    t : ndarray
        Time, s.
    psi : ndarray
        Heading, deg.
    delta : ndarray
        Actual rudder angle, deg.
    setpoint : float
        The set course, deg.
    band : float
        The rise-time band, a fraction of the step (0.05: within 5 %).
    steady_start : float
        Start of the steady window, s.
    reversal_threshold : float
        Least rudder swing counted as a reversal, deg.

    Returns
    -------
    dict
        The metrics of the module docstring by name (times s, angles deg, ``rudder_energy`` deg^2 s,
        ``rudder_reversals`` a count).

    Raises
    ------
    InputError
        A steady window of fewer than 2 samples.
    """
    t, psi, delta = _arrays(t, psi, delta)
    start = psi[0]
    step = abs(setpoint - start)
    t_rise = first_time_within(t, psi, setpoint, band * step) if step > 0 else float(t[0])
    t10 = first_time_fraction(t, psi, start, setpoint, 0.1)
    t90 = first_time_fraction(t, psi, start, setpoint, 0.9)
    t_reach = first_time_fraction(t, psi, start, setpoint, 1.0)
    t_from = t_reach if np.isfinite(t_reach) else t_rise
    after = t >= t_from if np.isfinite(t_from) else np.zeros_like(t, dtype=bool)
    steady = t >= steady_start
    if steady.sum() < 2:
        raise InputError(f"steady window t >= {steady_start} s holds fewer than 2 samples")
    dt = np.diff(t)
    d_s = delta[steady]
    dt_s = np.append(dt, dt[-1])[steady]
    return {
        "rise_time": t_rise,
        "rise_time_10_90": t90 - t10,
        "reach_time": t_reach,
        "max_deviation": float(np.max(np.abs(psi[after] - setpoint))) if after.any() else float("nan"),
        "steady_mae": float(np.mean(np.abs(psi[steady] - setpoint))),
        "max_rudder": float(np.max(np.abs(delta))),
        "steady_rudder_min": float(np.min(d_s)),
        "steady_rudder_max": float(np.max(d_s)),
        "mean_rudder": float(np.mean(d_s)),
        "rudder_energy": float(np.sum(d_s ** 2 * dt_s)),
        "rudder_rms": float(np.sqrt(np.mean(d_s ** 2))),
        "rudder_reversals": rudder_reversals(d_s, reversal_threshold),
    }


def seed_statistics(rows: list[dict]) -> dict:
    """Mean, standard deviation and worst value of each metric over seeds.

    Parameters
    ----------
    rows : list of dict
        One :func:`course_metrics` result per seed.

    Returns
    -------
    dict
        {metric: {"mean", "std" (ddof 1; 0 for one row), "worst" (see :data:`WORST`), "n" (finite
        values)}}, in the metric's own unit; NaN where no value is finite.

    Raises
    ------
    InputError
        No rows.
    """
    if not rows:
        raise InputError("no runs to summarise")
    out = {}
    for name in rows[0]:
        x = np.array([float(r[name]) for r in rows])
        how = WORST.get(name, "max")
        good = x[np.isfinite(x)]
        if good.size == 0:
            out[name] = {"mean": float("nan"), "std": float("nan"), "worst": float("nan"), "n": 0}
            continue
        worst = {"max": np.max(good), "min": np.min(good), "absmax": good[np.argmax(np.abs(good))]}[how]
        std = float(np.std(good, ddof=1)) if good.size > 1 else 0.0
        out[name] = {"mean": float(np.mean(good)), "std": std, "worst": float(worst), "n": int(good.size)}
    return out
