"""First-order Nomoto K and T (T r' + r = K delta) from a zigzag, two ways.

Units: psi, delta deg; r deg/s; t s; so K is in 1/s (deg/s of yaw rate per deg of rudder), T in s.
Both methods integrate rather than differentiate the noisy heading, and use the logged rudder as it
is (a rate-limited, non-ideal rudder is therefore no error source).

``graphical_kt`` (Nomoto's standard test method, evaluated numerically instead of on a chart)
    Integrating the model between two heading extrema t_a, t_b (r = 0 there) gives
    psi_b - psi_a = K * int_a^b delta dt, so K = sum s_i dpsi_i / sum s_i I_i over successive
    extrema (s_i the sign of the swing; alternating swings cancel a neutral-rudder offset to first
    order).  Between an extremum t_a and the next counter-rudder execute t_e:
    T r(t_e) = K int_a^e delta dt - (psi_e - psi_a), with r(t_e) the tangent of the heading curve at
    the execute (local straight line over +-tangent_window s, the chart method's tangent), so
    T = sum r_e (K I_e - dpsi_e) / sum r_e^2.
``integral_kt`` (least squares, docs/indices.md#k-and-t-from-the-zigzag)
    Twice integrated from the first sample (psi_s, unknown r_s):
    int (psi - psi_s) = K intint delta - T (psi - psi_s) + c0 + c1 t [+ c2 t^2],
    c1 = T r_s absorbs the initial yaw rate, c0 an error of psi_s, c2 = K delta_0 / 2 a constant
    rudder offset delta_0 (column used when ``offset`` is True).  Ordinary least squares; the
    reported standard errors assume white residuals and are indicative only.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.integrate import cumulative_trapezoid

from pipeline.config import IndicesConfig
from pipeline.errors import InputError
from pipeline.indices.executes import slope_at
from pipeline.indices.zigzag import _signals, zigzag_metrics
from pipeline.io import Run


def _cum(t, y) -> np.ndarray:
    return cumulative_trapezoid(y, t, initial=0.0)


def graphical_kt(run: Run, *, config: IndicesConfig | None = None,
                 zigzag: dict[str, Any] | None = None) -> dict[str, Any]:
    """K and T by the standard (graphical) method; see the module docstring.

    Parameters
    ----------
    run : Run
        A zigzag: time s, psi deg, delta deg (docs/contract.md#run-data).
    config : IndicesConfig, optional
        The heading, tangent and peak windows and the execute thresholds.
    zigzag : dict, optional
        The run's :func:`pipeline.indices.zigzag.zigzag_metrics` when already computed.

    Returns
    -------
    dict
        {"method": "standard", "K" (1/s), "T" (s), "K_swings" (per pair of extrema), "T_points" (per
        execute), "extrema", "executes_used", "rudder_deg", "heading_deg"}.

    Raises
    ------
    InputError
        When the run has fewer than two heading extrema (K) or no counter-rudder after one (T).
    """
    cfg = config or IndicesConfig()
    t, psi, delta = _signals(run)
    zz = zigzag if zigzag is not None else zigzag_metrics(run, config=cfg)
    ext = [(o["t_peak_s"], o["peak_dev_deg"] + zz["psi0_deg"]) for o in zz["overshoots"]]
    if len(ext) < 2:
        raise InputError("fewer than two heading extrema: the standard method needs a longer zigzag",
                         file=run.name, column="psi")
    cd = _cum(t, delta)
    ci = np.interp([e[0] for e in ext], t, cd)
    dpsi = np.diff([e[1] for e in ext])
    dint = np.diff(ci)
    s = np.sign(dpsi)
    k = float(np.sum(s * dpsi) / np.sum(s * dint))
    pts = []
    for e in zz["executes"]:
        te = e["time_s"]
        before = [x for x in ext if x[0] < te]
        if not before:
            continue
        ta, pa = before[-1]
        r_e = slope_at(t, psi, te, cfg.tangent_window)
        psi_e = float(np.polyval(np.polyfit(t[np.abs(t - te) <= cfg.tangent_window + 1e-9] - te,
                                            psi[np.abs(t - te) <= cfg.tangent_window + 1e-9], 1), 0.0))
        i_e = float(np.interp(te, t, cd) - np.interp(ta, t, cd))
        pts.append({"t_execute_s": te, "t_extremum_s": ta, "r_deg_s": r_e,
                    "T_s": (k * i_e - (psi_e - pa)) / r_e if r_e else None,
                    "_r": r_e, "_rhs": k * i_e - (psi_e - pa)})
    if not pts:
        raise InputError("no counter-rudder execute after a heading extremum: T cannot be read",
                         file=run.name, column="delta")
    r = np.array([p.pop("_r") for p in pts])
    rhs = np.array([p.pop("_rhs") for p in pts])
    tt = float(np.sum(r * rhs) / np.sum(r * r))
    return {"method": "standard", "K": k, "T": tt,
            "K_swings": (dpsi / dint).tolist(), "T_points": pts,
            "extrema": [{"t_s": a, "psi_deg": b} for a, b in ext],
            "rudder_deg": zz["rudder_deg"], "heading_deg": zz["heading_deg"]}


def integral_kt(run: Run, *, offset: bool = True, t_start: float | None = None,
                t_end: float | None = None, config: IndicesConfig | None = None) -> dict[str, Any]:
    """K and T by least squares on the twice-integrated first-order model (module docstring).

    Parameters
    ----------
    run : Run
        The zigzag (any manoeuvre with enough rudder activity works): time s, psi deg, delta deg.
    offset : bool
        Estimate a constant rudder offset too (t^2 column).
    t_start, t_end : float, optional
        Window in s (default: the whole run).
    config : IndicesConfig, optional
        ``manoeuvre.integral_min_samples``: the fewest samples the window may hold.

    Returns
    -------
    dict
        {"method": "integral", "K" (1/s), "T" (s), "K_std", "T_std" (one sigma, same units),
        "rudder_offset_deg" (deg, or None), "rms_residual_deg_s", "samples"}.
    """
    min_samples = (config or IndicesConfig()).manoeuvre.integral_min_samples
    t, psi, delta = _signals(run)
    m = np.ones_like(t, bool)
    if t_start is not None:
        m &= t >= t_start
    if t_end is not None:
        m &= t <= t_end
    if m.sum() < min_samples:
        raise InputError(f"fewer than {min_samples} samples in the integral-method window", file=run.name,
                         column="time")
    t, psi, delta = t[m] - t[m][0], psi[m], delta[m]
    dpsi = psi - psi[0]
    y = _cum(t, dpsi)
    cols = [_cum(t, _cum(t, delta)), -dpsi, np.ones_like(t), t]
    if offset:
        cols.append(t * t)
    a = np.column_stack(cols)
    scale = np.max(np.abs(a), axis=0)
    scale[scale == 0] = 1.0
    coef, *_ = np.linalg.lstsq(a / scale, y, rcond=None)
    coef = coef / scale
    res = y - a @ coef
    dof = max(t.size - a.shape[1], 1)
    s2 = float(res @ res) / dof
    try:
        cov = s2 * np.linalg.inv(a.T @ a)
        std = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        std = np.full(a.shape[1], np.nan)
    k, tt = float(coef[0]), float(coef[1])
    if not (k > 0 and tt > 0):
        raise InputError(f"integral method gives K = {k:.4g}, T = {tt:.4g}: not a first-order "
                         "Nomoto response (no positive K and T)", file=run.name, column="psi")
    return {"method": "integral", "K": k, "T": tt, "K_std": float(std[0]), "T_std": float(std[1]),
            "rudder_offset_deg": float(2 * coef[4] / k) if offset else None,
            "rms_residual_deg_s": float(np.sqrt(s2)), "samples": int(t.size)}
