"""Nomoto indices with one-sigma bounds propagated from the parameter covariance.

The indices are those of paper Eq. 6 (:func:`pipeline.model.nomoto_indices`), computed at the
estimate.  Their standard deviations come from the 6x6 covariance of (a11, a12, a21, a22, b11, b21)
by one of two methods:

``unscented`` (default)
    Symmetric sigma points theta +- h s_j, j = 1..6, with s_j the columns of a square root of the
    covariance (eigen-decomposition, so singular covariances such as fixed parameters are fine) and
    h = sqrt(3) (Julier's kappa = 3 - n, matching the Gaussian kurtosis).  The covariance of the
    indices is taken about the transformed centre point, sum_j (y(+j) - y0)^2 + (y(-j) - y0)^2 over
    2 h^2, which is exact for a linear map and always positive semi-definite.
``linear``
    First-order propagation J P J^T with a central-difference Jacobian.

If a sigma point falls where the model has no real positive time constants, the unscented method
falls back to the linear one (the method actually used is returned by :func:`propagate`).
Units: the model's (docs/contract.md#the-identification-model): K in 1/s (deg/s per deg), T1, T2, T3, T in s.
"""

from __future__ import annotations

import itertools
from decimal import Decimal

import numpy as np

from pipeline.errors import ModelError
from pipeline.model import INDEX_NAMES, PARAM_NAMES, as_theta, nomoto_indices

SPREAD = float(np.sqrt(3.0))


def _vec(theta) -> np.ndarray:
    d = nomoto_indices(theta)
    return np.array([d[n] for n in INDEX_NAMES])


def _sqrt_cov(cov) -> np.ndarray:
    """A square root S (S S^T = cov) of a symmetric positive semi-definite 6x6 matrix."""
    c = np.asarray(cov, dtype=float)
    if c.shape != (6, 6):
        raise ModelError(f"parameter covariance must be 6 x 6 (a11 a12 a21 a22 b11 b21), got {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ModelError("parameter covariance has NaN or infinite entries")
    scale = max(float(np.max(np.abs(c))), 1e-300)
    if np.max(np.abs(c - c.T)) > 1e-8 * scale:
        raise ModelError("parameter covariance is not symmetric")
    c = 0.5 * (c + c.T)
    w, v = np.linalg.eigh(c)
    if w.min() < -1e-9 * max(w.max(), 1e-300):
        raise ModelError(f"parameter covariance is not positive semi-definite (eigenvalue {w.min():.3g})")
    return v * np.sqrt(np.clip(w, 0.0, None))


def jacobian(params, *, rel_step: float = 1e-6) -> np.ndarray:
    """Central-difference Jacobian of the indices with respect to the parameters.

    Parameters
    ----------
    params : mapping or sequence
        a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model), by name or in
        PARAM_NAMES order.
    rel_step : float
        Step relative to each parameter's size (at least 1e-3 of a unit), dimensionless.

    Returns
    -------
    numpy.ndarray
        5 x 6: d(K, T1, T2, T3, T) / d(a11 ... b21), in the indices' units per the parameters'.
    """
    theta = as_theta(params)
    jac = np.empty((len(INDEX_NAMES), 6))
    for j in range(6):
        h = rel_step * max(abs(theta[j]), 1e-3)
        tp, tm = theta.copy(), theta.copy()
        tp[j] += h
        tm[j] -= h
        jac[:, j] = (_vec(tp) - _vec(tm)) / (2 * h)
    return jac


def propagate(params, cov, *, method: str = "unscented") -> tuple[dict[str, dict[str, float]], str]:
    """Indices with one-sigma bounds, and the method actually used.

    Parameters
    ----------
    params : the six parameters (mapping by name or sequence in PARAM_NAMES order), the model's units.
    cov : their 6x6 covariance (same order), or None (stds are then None).
    method : 'unscented' or 'linear'.

    Returns
    -------
    ({"K": {"value", "std"}, "T1": ..., "T2": ..., "T3": ..., "T": ...}, method_used)

    Raises ModelError when the estimate itself has no real, positive time constants, or the
    covariance is not a symmetric positive semi-definite 6x6 matrix.
    """
    if method not in ("unscented", "linear"):
        raise ModelError(f"unknown uncertainty method {method!r} (use 'unscented' or 'linear')")
    theta = as_theta(params)
    y0 = _vec(theta)
    if cov is None:
        return {n: {"value": float(y0[i]), "std": None} for i, n in enumerate(INDEX_NAMES)}, "none"
    s = _sqrt_cov(cov)
    used = method
    var = None
    if method == "unscented":
        try:
            acc = np.zeros_like(y0)
            for j in range(6):
                for sign in (1.0, -1.0):
                    acc += (_vec(theta + sign * SPREAD * s[:, j]) - y0) ** 2
            var = acc / (2.0 * SPREAD**2)
        except ModelError:
            used = "linear (unscented sigma point outside the model's valid region)"
    if var is None:
        js = jacobian(theta) @ s
        var = np.sum(js**2, axis=1)
    out = {n: {"value": float(y0[i]), "std": float(np.sqrt(var[i]))} for i, n in enumerate(INDEX_NAMES)}
    return out, used


def indices_with_uncertainty(params, cov, *, method: str = "unscented") -> dict[str, dict[str, float]]:
    """The indices with one-sigma bounds (:func:`propagate` without the method used).

    Parameters
    ----------
    params : mapping or sequence
        a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model), by name or in
        PARAM_NAMES order.
    cov : array or None
        Their 6 x 6 covariance in the same order (None: stds are None).
    method : str
        'unscented' or 'linear'.

    Returns
    -------
    dict
        {"K": {"value", "std"}, "T1", "T2", "T3", "T"}: K in 1/s, the time constants in s.
    """
    return propagate(params, cov, method=method)[0]


def monte_carlo(params, cov, *, samples: int = 20000, seed: int = 0) -> dict[str, dict[str, float]]:
    """Reference propagation: the indices of ``samples`` seeded Gaussian draws N(params, cov).

    Draws with no real positive time constants are dropped (their share is returned as
    ``"rejected"``).  When the covariance is wide the indices (ratios of parameters) are heavy-tailed
    and skewed: the percentiles then describe the spread better than "std".

    Parameters
    ----------
    params : mapping or sequence
        a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model), by name or in
        PARAM_NAMES order.
    cov : array
        Their 6 x 6 covariance.
    samples : int
        Number of draws.
    seed : int
        Seed of the draws.

    Returns
    -------
    dict
        {name: {"mean", "std", "p16", "p50", "p84"}} for K (1/s), T1 T2 T3 T (s), and "rejected"
        (share of draws dropped, 0-1).
    """
    theta = as_theta(params)
    rng = np.random.default_rng(seed)
    draws = theta + rng.standard_normal((samples, 6)) @ _sqrt_cov(cov).T
    ys = []
    for d in draws:
        try:
            ys.append(_vec(d))
        except ModelError:
            pass
    if not ys:
        raise ModelError("no Monte Carlo draw gives real positive time constants")
    y = np.array(ys)
    pc = np.percentile(y, [16, 50, 84], axis=0)
    out = {n: {"mean": float(y[:, i].mean()), "std": float(y[:, i].std(ddof=1)),
               "p16": float(pc[0, i]), "p50": float(pc[1, i]), "p84": float(pc[2, i])}
           for i, n in enumerate(INDEX_NAMES)}
    out["rejected"] = 1.0 - len(ys) / samples
    return out


def draw_validity(params, cov, *, samples: int = 20000, seed: int = 0) -> dict[str, float]:
    """Which Gaussian draws N(params, cov) give a usable model, for the first- and second-order indices.

    The same seeded draws as :func:`monte_carlo`.  With D = a11 a22 - a12 a21, num = a21 b11 - a11 b21:

    * second order (T1, T2, T3 of Eq. 6) needs real positive T1, T2: D > 0, T1 + T2 = -(a11 + a22)/D
      > 0 and (T1 + T2)^2 >= 4 T1 T2.  ``invalid_fraction`` is the share of draws without them, with
      its causes: ``D <= 0`` (one negative time constant: a course-unstable model), ``unstable``
      (T1 + T2 <= 0), ``complex`` (a stable but oscillatory yaw mode).
    * first order (K, T of the Nomoto K/(1 + T s), what the first-order CGSA uses) needs only
      K = num/D > 0 and T = T1 + T2 - T3 = -(a11 + a22)/D - b21/num > 0, which are real for complex
      T1, T2 as well.  ``invalid_fraction_first_order`` is the share of draws with K <= 0 or T <= 0
      (a reversed rudder response or an unstable first-order ship).

    A zigzag fixes K and K/T well but hardly the spiral stability D: the a11-a12 and a21-a22 pairs are
    nearly collinear (sway follows yaw), so the covariance is a long ridge along which D crosses zero
    while K and T stay put.  Checking K and T against the second-order condition would flag them for
    the uncertainty of T1, T2, T3.

    Parameters
    ----------
    params : mapping or sequence
        a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model), by name or in
        PARAM_NAMES order.
    cov : array
        Their 6 x 6 covariance.
    samples : int
        Number of draws.
    seed : int
        Seed of the draws (the same as :func:`monte_carlo`'s gives the same draws).

    Returns
    -------
    dict
        {"invalid_fraction", "invalid_fraction_first_order", "invalid_causes": {"D <= 0",
        "unstable", "complex"}}: shares of the draws, 0-1.
    """
    theta = as_theta(params)
    rng = np.random.default_rng(seed)
    d = theta + rng.standard_normal((samples, 6)) @ _sqrt_cov(cov).T
    a11, a12, a21, a22, b11, b21 = d.T
    det = a11 * a22 - a12 * a21
    num = a21 * b11 - a11 * b21
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -(a11 + a22) / det
        k = num / det
        t = s - b21 / num
        disc = s * s - 4.0 / det
    det_bad = ~(det > 0)
    unstable = ~det_bad & ~(s > 0)
    cplx = ~det_bad & ~unstable & (disc < 0)
    second_bad = det_bad | unstable | cplx | ~(np.abs(k) > 0)
    first_bad = ~(np.isfinite(k) & np.isfinite(t) & (k > 0) & (t > 0))
    return {"invalid_fraction": float(second_bad.mean()),
            "invalid_fraction_first_order": float(first_bad.mean()),
            "invalid_causes": {"D <= 0": float(det_bad.mean()), "unstable": float(unstable.mean()),
                               "complex": float(cplx.mean())}}


def rounding_half_widths(printed: dict[str, str]) -> dict[str, float]:
    """Half a unit of the last printed digit of each value, e.g. '0.0099' -> 5e-5.

    Parameters
    ----------
    printed : dict
        Name -> the value as printed (string: the digits matter).

    Returns
    -------
    dict
        Name -> half-width, in the value's unit.
    """
    return {k: 0.5 * float(Decimal(1).scaleb(Decimal(str(v).strip()).as_tuple().exponent))
            for k, v in printed.items()}


def index_range_over_box(params, half_widths: dict[str, float], *, interior: int = 2000,
                         seed: int = 0) -> dict[str, tuple[float, float]]:
    """Range (min, max) of each index for parameters anywhere in params +- half_widths.

    Evaluated on the 64 corners of the box plus ``interior`` seeded uniform points (over such small
    boxes the indices are monotone, so the corners carry the extremes; the interior points guard
    against the exception).  Used to ask whether a published table of indices is consistent with a
    published, rounded table of parameters.

    Parameters
    ----------
    params : mapping or sequence
        a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model).
    half_widths : dict
        Parameter name -> half-width of the box, the parameter's unit.
    interior : int
        Number of seeded interior points.
    seed : int
        Their seed.

    Returns
    -------
    dict
        Index name -> (min, max): K in 1/s, T1 T2 T3 T in s.
    """
    theta = as_theta(params)
    hw = np.array([float(half_widths.get(n, 0.0)) for n in PARAM_NAMES])
    pts = [theta + hw * np.array(c) for c in itertools.product((-1.0, 1.0), repeat=6)]
    rng = np.random.default_rng(seed)
    pts += list(theta + hw * rng.uniform(-1, 1, (interior, 6)))
    y = np.array([_vec(p) for p in pts])
    return {n: (float(y[:, i].min()), float(y[:, i].max())) for i, n in enumerate(INDEX_NAMES)}
