"""Rudder executes and heading extrema read from logged signals (noise- and rate-limit-robust).

An *execute* is the instant the rudder starts moving to a new angle (ITTC 7.5-04-02-01).  With a
rate-limited servo the logged rudder ramps; the execute is found by fitting a straight line to the
ramp between ``ramp_band`` fractions of the transition and extrapolating it back to the previous
level, kept within the two samples between which the rudder first leaves the previous level by
more than max(4 sigma, 0.2 % of the jump) (sigma: plateau noise, robust; the thresholds are
:class:`pipeline.config.ManoeuvreConfig`); the bracket catches a
servo that accelerates before reaching its rate (the HSVA runs), for which the line alone is late.
A step that completes between two samples is placed at their midpoint (error at most half a step).
Transitions are found with hysteresis at +-``level_fraction`` of the rudder amplitude, so
measurement noise much smaller than the amplitude cannot create false executes.  Either side may
come first.  All angles in degrees, times in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.config import ManoeuvreConfig
from pipeline.errors import InputError


@dataclass
class Executes:
    times: np.ndarray          # s, execute instants
    sides: np.ndarray          # +1 rudder to starboard (positive delta), -1 to port
    levels: np.ndarray         # deg, rudder plateau reached after each execute (median)
    amplitude: float           # deg, rudder amplitude (robust)
    neutral: float             # deg, rudder before the first execute


def rudder_amplitude(delta: np.ndarray, neutral: float = 0.0, *,
                     config: ManoeuvreConfig | None = None) -> float:
    """Robust rudder amplitude: median |delta - neutral| over the samples above a share of the top.

    Parameters
    ----------
    delta : array
        Logged rudder angle, deg.
    neutral : float
        Neutral rudder angle, deg.
    config : ManoeuvreConfig, optional
        ``amplitude_percentile`` (the top) and ``amplitude_share``.

    Returns
    -------
    float
        The amplitude, deg (positive).
    """
    c = config or ManoeuvreConfig()
    d = np.abs(np.asarray(delta, float) - neutral)
    top = np.percentile(d, c.amplitude_percentile)
    if not top > 0:
        raise InputError("the rudder never moves: no execute to analyse", column="delta")
    return float(np.median(d[d > c.amplitude_share * top]))


def _crossing_time(t, y, level, i0, i1) -> float | None:
    """First time in samples i0..i1 where y crosses ``level`` (linear interpolation)."""
    seg = y[i0:i1 + 1] - level
    idx = np.nonzero(np.sign(seg[:-1]) != np.sign(seg[1:]))[0]
    if idx.size == 0:
        return None
    k = i0 + idx[0]
    y0, y1 = y[k] - level, y[k + 1] - level
    return float(t[k] + (t[k + 1] - t[k]) * (y0 / (y0 - y1) if y0 != y1 else 0.0))


def find_executes(time, delta, *, level_fraction: float = 0.5, ramp_band=(0.2, 0.8),
                  config: ManoeuvreConfig | None = None) -> Executes:
    """Rudder executes of a zigzag or turning run.

    Parameters
    ----------
    time : array
        Sample times, s, increasing.
    delta : array
        Logged rudder angle, deg (positive = starboard turn).
    level_fraction : float
        Hysteresis level, share of the rudder amplitude, at which a transition is counted.
    ramp_band : (float, float)
        Shares of each transition between which the ramp's straight line is fitted.
    config : ManoeuvreConfig, optional
        The neutral-rudder, plateau-noise and start-of-move thresholds.

    Returns
    -------
    Executes
        Execute times (s), sides (+1 starboard), plateau levels (deg), amplitude and neutral (deg).
    """
    c = config or ManoeuvreConfig()
    t = np.asarray(time, float)
    d = np.asarray(delta, float)
    if t.size < 10:
        raise InputError("too few samples to find rudder executes", column="delta")
    # Neutral rudder: median of the first samples if they are quiet, else 0.
    amp0 = rudder_amplitude(d, 0.0, config=c)
    head = d[: max(3, int(np.searchsorted(t, t[0] + c.neutral_head_s)))]
    quiet = np.all(np.abs(head - np.median(head)) < c.neutral_share * amp0) \
        and abs(np.median(head)) < c.neutral_share * amp0
    neutral = float(np.median(head)) if quiet else 0.0
    amp = rudder_amplitude(d, neutral, config=c)
    x = d - neutral
    thr = level_fraction * amp
    state = 0
    flips: list[tuple[int, int]] = []           # (sample index of threshold crossing, new side)
    for k, xv in enumerate(x):
        if xv > thr and state != 1:
            state = 1
            flips.append((k, 1))
        elif xv < -thr and state != -1:
            state = -1
            flips.append((k, -1))
    if not flips:
        raise InputError("no rudder execute found", column="delta")
    times, levels = [], []
    prev_level = 0.0
    for n, (k, side) in enumerate(flips):
        k_next = flips[n + 1][0] if n + 1 < len(flips) else x.size
        # plateau after this execute: samples beyond the threshold until the next flip
        seg = x[k:k_next]
        plateau = seg[side * seg > thr]
        new_level = float(np.median(plateau[plateau.size // 3:])) if plateau.size else side * amp
        jump = new_level - prev_level
        k_prev = flips[n - 1][0] if n > 0 else 0
        lo = prev_level + ramp_band[0] * jump
        hi = prev_level + ramp_band[1] * jump
        # walk back from the threshold crossing to the start of the ramp band
        i = k
        while i > k_prev and (x[i] - lo) * np.sign(jump) > 0:
            i -= 1
        j = k
        while j < k_next - 1 and (x[j] - hi) * np.sign(jump) < 0:
            j += 1
        idx = np.arange(i + 1, j)           # samples strictly inside the band
        if idx.size >= 2:                   # ramp resolved
            slope, icpt = np.polyfit(t[idx], x[idx], 1)
            te = (prev_level - icpt) / slope if slope != 0 else t[k]
            # departure from the previous plateau: the last sample within tol of it (walking back
            # from the ramp) and the next one bracket the start of the movement; the line's
            # extrapolation is kept inside that bracket (a servo that accelerates before reaching
            # its rate limit makes the line alone late)
            lo_i = k_prev if n else 0
            plat = x[lo_i:i + 1]
            plat = plat[np.abs(plat - prev_level) < c.plateau_share * abs(jump)]
            sig = 1.4826 * np.median(np.abs(np.diff(plat) - np.median(np.diff(plat)))) / np.sqrt(2) \
                if plat.size > 5 else 0.0
            tol = max(c.execute_sigmas * sig, c.execute_min_share * abs(jump))
            q = i
            while q > lo_i and abs(x[q] - prev_level) > tol:
                q -= 1
            if abs(x[q] - prev_level) <= tol < abs(x[q + 1] - prev_level):
                te = float(np.clip(te, t[q], t[q + 1]))
        else:                               # (nearly) a step between two samples: take the midpoint
            te = 0.5 * (t[max(i, 0)] + t[min(j, x.size - 1)])
        te = float(np.clip(te, t[k_prev] if n else t[0], t[k]))
        times.append(te)
        levels.append(new_level + neutral)
        prev_level = new_level
    return Executes(times=np.array(times), sides=np.array([s for _, s in flips]),
                    levels=np.array(levels), amplitude=amp, neutral=neutral)


def heading_at(time, psi, t_at: float, window: float) -> float:
    """Heading at ``t_at`` from a straight line fitted to psi over [t_at - window, t_at].

    Parameters
    ----------
    time : array
        Sample times, s.
    psi : array
        Heading, deg.
    t_at : float
        The instant, s.
    window : float
        Length of the fit before ``t_at``, s (fewer than three samples in it: linear interpolation).

    Returns
    -------
    float
        The heading at ``t_at``, deg.
    """
    t = np.asarray(time, float)
    p = np.asarray(psi, float)
    m = (t >= t_at - window) & (t <= t_at + 1e-9)
    if m.sum() < 3:
        return float(np.interp(t_at, t, p))
    c = np.polyfit(t[m] - t_at, p[m], 1)
    return float(c[1])


def slope_at(time, y, t_at: float, window: float) -> float:
    """Local straight-line slope of y around ``t_at`` (+-window s).

    Parameters
    ----------
    time : array
        Sample times, s.
    y : array
        The signal (e.g. heading, deg).
    t_at : float
        The instant, s.
    window : float
        Half-width of the fit, s (fewer than three samples in it: the slope of the bracketing pair).

    Returns
    -------
    float
        dy/dt at ``t_at``, y's unit per s (deg/s for a heading).
    """
    t = np.asarray(time, float)
    m = np.abs(t - t_at) <= window + 1e-9
    if m.sum() < 3:
        k = int(np.clip(np.searchsorted(t, t_at), 1, t.size - 1))
        return float((y[k] - y[k - 1]) / (t[k] - t[k - 1]))
    return float(np.polyfit(t[m] - t_at, np.asarray(y, float)[m], 1)[0])


def extremum(time, psi, i0: int, i1: int, sign: int, window: float) -> tuple[float, float, bool]:
    """Extremum of sign*psi over samples i0..i1 (inclusive), refined by a local cubic fit.

    Parameters
    ----------
    time : array
        Sample times, s.
    psi : array
        Heading, deg.
    i0, i1 : int
        First and last sample of the interval searched.
    sign : int
        +1 for a maximum of psi, -1 for a minimum.
    window : float
        Half-width of the cubic fit around the raw extremum, s.

    Returns
    -------
    tuple of (float, float, bool)
        Time of the extremum (s), psi there (deg), and ``complete``: False when the raw extremum sits
        at the end of the interval (the heading had not yet turned back).
    """
    t = np.asarray(time, float)
    p = np.asarray(psi, float)
    seg = sign * p[i0:i1 + 1]
    k = i0 + int(np.argmax(seg))
    complete = k < i1 - 1 and k > i0
    m = (np.abs(t - t[k]) <= window) & (np.arange(t.size) >= i0) & (np.arange(t.size) <= i1)
    if m.sum() >= 7 and complete:
        tc = t[k]
        c = np.polyfit(t[m] - tc, p[m], 3)       # a cubic follows the asymmetric turn-back
        d1 = np.polyder(c)
        roots = [float(z.real) for z in np.roots(d1) if abs(z.imag) < 1e-12 and abs(z.real) <= window]
        roots = [z for z in roots if sign * np.polyval(np.polyder(d1), z) < 0]   # a maximum of sign*psi
        if roots:
            tv = min(roots, key=abs)
            return float(tc + tv), float(np.polyval(c, tv)), True
    return float(t[k]), float(p[k]), complete
