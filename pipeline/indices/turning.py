"""Turning circle analysis (ITTC 7.5-04-02-01) of a run in the units of docs/contract.md#run-data.

From the execute (start of the rudder ramp, as for zigzags), with the position and heading there as
origin: advance = distance along the original heading when the heading has changed by 90 deg;
transfer = distance across it (to the side of the turn) at 90 deg; tactical diameter = distance
across at 180 deg; steady turning diameter = diameter of the circle fitted (algebraic least squares,
Kasa) to the track over the steady part: rudder still held (a pull-out phase, the rudder returned
after the turn, is excluded), heading change from ``steady_from`` deg (180 deg for short runs),
and yaw rate settled (:func:`_steady_mask`); steady speed ratio = mean sqrt(u^2 + v^2) there
over the approach speed (mean over the 3 s before the execute; speed from the track when u is
absent).  Lengths also in ship lengths with
``run.meta["lpp"]``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pipeline.config import IndicesConfig, ManoeuvreConfig
from pipeline.errors import InputError
from pipeline.indices.executes import find_executes, heading_at
from pipeline.indices.zigzag import SIDE_NAME, _signals
from pipeline.io import Run


def _speed(run: Run, t, x, y) -> np.ndarray:
    if "u" in run.frame.columns:
        u = run.col("u")
        v = run.col("v") if "v" in run.frame.columns else np.zeros_like(u)
        return np.hypot(u, v)
    return np.hypot(np.gradient(x, t), np.gradient(y, t))


def fit_circle(x, y) -> tuple[float, float, float]:
    """Least-squares circle through points (Kasa's algebraic fit).

    Parameters
    ----------
    x, y : array
        Track coordinates, m.

    Returns
    -------
    tuple of float
        Centre x (m), centre y (m), radius (m).
    """
    a = np.column_stack([x, y, np.ones_like(x)])
    b = x * x + y * y
    (c1, c2, c3), *_ = np.linalg.lstsq(a, b, rcond=None)
    xc, yc = c1 / 2, c2 / 2
    return float(xc), float(yc), float(np.sqrt(c3 + xc * xc + yc * yc))


def _held_end(delta: np.ndarray, i_e: int, level: float, c: ManoeuvreConfig) -> int:
    """Last sample of the held-rudder phase: before the rudder leaves its plateau (pull-out)."""
    off = np.flatnonzero(np.abs(delta[i_e:] - level) > c.held_off_share * abs(level))
    # the ramp up after the execute is below the plateau too: look only after the plateau is reached
    reached = np.flatnonzero(np.abs(delta[i_e:] - level) <= c.held_reached_share * abs(level))
    if reached.size == 0:
        return delta.size - 1
    first = int(reached[0])
    off = off[off > first]
    return i_e + int(off[0]) - 1 if off.size else delta.size - 1


def _steady_mask(t, change, r, *, i_e: int, held_end: int, total_held: float, cfg: IndicesConfig):
    """Samples of the steady turn (ITTC 7.5-04-02-01), or (None, start) when there are too few.

    Steady: the rudder still held (pull-out excluded), the heading changed by at least ``start``
    (``cfg.steady_from``, 270 deg, or 180 deg for shorter runs), and the yaw rate settled: within
    ``steady_r_band`` (5 %, :class:`pipeline.config.ManoeuvreConfig`) of its median over the last
    third of the held phase, or within three
    times its sample-to-sample noise for a slow turn (a turning ship's yaw rate settles within a few
    per cent once the speed loss is over).  At least ``cfg.steady_min_span`` deg of it is needed.
    """
    c = cfg.manoeuvre
    start = cfg.steady_from if total_held >= cfg.steady_from + cfg.steady_min_span else c.steady_from_short
    idx = np.arange(t.size)
    held = (idx >= i_e) & (idx <= held_end)
    steady = held & (change >= start)
    if r is not None and steady.sum() >= c.steady_min_samples:
        tail = np.flatnonzero(held)
        tail = tail[int(2 * tail.size / 3):]
        r_ref = float(np.median(r[tail]))
        noise = float(np.median(np.abs(np.diff(r[tail])))) * 1.4826 / np.sqrt(2) if tail.size > 2 else 0.0
        band = max(c.steady_r_band * abs(r_ref), c.steady_noise_sigmas * noise)
        settled = np.abs(r - r_ref) <= band
        # steady from the first sample after which r stays settled to the end of the held phase
        bad = np.flatnonzero(steady & ~settled)
        if bad.size:
            steady &= idx > bad[-1]
    if steady.sum() < c.steady_min_samples:
        return None, start
    span = float(change[steady].max() - change[steady].min())
    if span < cfg.steady_min_span:
        return None, start
    return steady, start



def turning_metrics(run: Run, *, config: IndicesConfig | None = None) -> dict[str, Any]:
    """Turning-circle metrics (module docstring for the definitions).

    Parameters
    ----------
    run : Run
        A turning circle with columns time s, psi deg, delta deg, x0 y0 m (and r deg/s, u v m/s
        when logged); ``run.meta["lpp"]`` (m) for the lengths in ship lengths.
    config : IndicesConfig, optional
        Steady-turn and execute settings.

    Returns
    -------
    dict
        {"side", "rudder_deg", "t_execute_s", "advance_m", "transfer_m", "tactical_diameter_m",
        "steady_diameter_m", the same divided by lpp as "*_L", "steady_speed_ratio",
        "steady_yaw_rate_deg_s", "approach_speed_m_s", "heading_change_deg", "lpp_m"}; quantities the
        run does not reach (e.g. 180 deg) are None.
    """
    cfg = config or IndicesConfig()
    t, psi, delta = _signals(run)
    x, y = run.col("x0"), run.col("y0")
    ex = find_executes(t, delta, level_fraction=cfg.level_fraction, ramp_band=cfg.ramp_band,
                       config=cfg.manoeuvre)
    te = float(ex.times[0])
    side = int(ex.sides[0])
    i_e = int(np.searchsorted(t, te))
    psi_e = heading_at(t, psi, te, cfg.heading_window)
    xe, ye = float(np.interp(te, t, x)), float(np.interp(te, t, y))
    ang = np.deg2rad(psi_e)
    along = (x - xe) * np.cos(ang) + (y - ye) * np.sin(ang)
    across = side * (-(x - xe) * np.sin(ang) + (y - ye) * np.cos(ang))
    change = side * (psi - psi_e)
    speed = _speed(run, t, x, y)
    pre = (t >= te - cfg.manoeuvre.approach_s) & (t < te)
    u0 = run.meta.get("approach_speed")
    u0 = float(u0) if u0 else float(np.mean(speed[pre] if pre.sum() >= 2 else speed[: max(i_e, 2)]))

    def at(level, arr):
        k = np.nonzero(change[i_e:] >= level)[0]
        if k.size == 0:
            return None
        j = i_e + int(k[0])
        if j == 0:
            return float(arr[0])
        f = (level - change[j - 1]) / (change[j] - change[j - 1])
        return float(arr[j - 1] + f * (arr[j] - arr[j - 1]))

    held_end = _held_end(delta, i_e, float(ex.levels[0]), cfg.manoeuvre)
    total = float(np.max(change[i_e:]))
    total_held = float(np.max(change[i_e:held_end + 1]))
    steady, start = _steady_mask(t, change, run.col("r") if "r" in run.frame.columns else None,
                                 i_e=i_e, held_end=held_end, total_held=total_held, cfg=cfg)
    d_steady = ratio = r_steady = None
    if steady is not None:
        _, _, rad = fit_circle(x[steady], y[steady])
        d_steady = 2.0 * rad
        ratio = float(np.mean(speed[steady]) / u0) if u0 > 0 else None
        r_steady = float(np.mean(run.col("r")[steady])) if "r" in run.frame.columns else None
    lpp = run.meta.get("lpp")
    lpp = float(lpp) if lpp else None
    out = {"side": SIDE_NAME[side], "rudder_deg": float(ex.levels[0]), "t_execute_s": te,
           "approach_speed_m_s": u0, "heading_change_deg": total, "lpp_m": lpp,
           "advance_m": at(90.0, along), "transfer_m": at(90.0, across),
           "tactical_diameter_m": at(180.0, across), "steady_diameter_m": d_steady,
           "steady_speed_ratio": ratio, "steady_yaw_rate_deg_s": r_steady,
           "steady_from_deg": start, "steady_samples": int(steady.sum()) if steady is not None else 0,
           "pull_out_s": float(t[held_end + 1]) if held_end + 1 < t.size else None}
    for key in ("advance", "transfer", "tactical_diameter", "steady_diameter"):
        v = out[f"{key}_m"]
        out[f"{key}_L"] = v / lpp if (v is not None and lpp) else None
    if out["advance_m"] is None:
        raise InputError("the heading never changes by 90 deg after the execute: not a turning circle",
                         file=run.name, column="psi")
    return out
