"""Is the filter consistent with the run?  Time-average NIS and innovation whiteness.

A Kalman filter whose model and noise settings describe the data produces innovations nu(k) that
are zero-mean, white, with covariance S(k) (Bar-Shalom, Li & Kirubarajan, *Estimation with
Applications to Tracking and Navigation*, 2001, sec. 5.4).  Two tests of that, both two-sided at
``FilterConfig.consistency_level`` (95 %: the conventional 5 % false-alarm rate of each check):

**Time-average NIS.**  eps(k) = nu' S^-1 nu is chi-square with m degrees of freedom (m measured
channels), so over N independent steps N eps_bar is chi-square with m N: the band of eps_bar is
[chi2(a/2; m N), chi2(1 - a/2; m N)] / N.  Consecutive NIS values are not independent when the
innovations are correlated (a low-passed, resampled logger; an unmodelled slow effect), and the
white band is then far too narrow.  The variance of a mean of a correlated sequence is that of
N_eff = N / (1 + 2 sum_k rho_k) independent values (rho_k: autocorrelation of eps at lag k), so the
band is taken with N_eff in place of N (the chi-square with m N_eff degrees of freedom over N_eff has
the mean m and the variance 2 m / N_eff of eps_bar).  The sum is Geyer's initial positive sequence
estimator (Geyer 1992, Statistical Science 7: 473): pairs rho_2j + rho_2j+1 are summed while they
stay positive (starting from 1 + rho_1), which truncates the noisy tail without a tuning constant.
N_eff is kept within [1, N]: a negatively correlated NIS sequence would make the band narrower than
the white one, and the white band is the strictest one the data can support.

**Whiteness.**  For each measured channel the lag-1 sample autocorrelation of the innovation; under
the white hypothesis it is N(0, 1/N) for large N (Bar-Shalom sec. 5.4.2).  The band is
+- z(1 - a/(2 m)) / sqrt(N) (Bonferroni over the m channels, so the check as a whole keeps the 5 %
false-alarm rate).  Lag 1 is where a wrong gain shows first: a filter told its measurements are more
precise than they are follows the noise and leaves negatively correlated innovations; a filter whose
model lags the ship leaves positively correlated ones.

A filter that fails either check has a parameter covariance that does not describe the estimate's
error, so every bound derived from it is not to be trusted (the flags say so).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def autocorrelation(x: np.ndarray, max_lag: int | None = None) -> np.ndarray:
    """Sample autocorrelation rho_0..rho_max_lag (biased estimator, rho_0 = 1) of a 1-D series."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n < 2:
        return np.ones(1)
    d = x - x.mean()
    var = float(d @ d)
    if var == 0.0:
        return np.concatenate([[1.0], np.zeros(min(max_lag or n - 1, n - 1))])
    nfft = 1 << (2 * n - 1).bit_length()
    f = np.fft.rfft(d, nfft)
    ac = np.fft.irfft(f * np.conj(f), nfft)[:n] / var
    return ac[: (max_lag or n - 1) + 1]


def effective_sample_size(x: np.ndarray) -> tuple[float, float]:
    """(N_eff, sum_k rho_k) of a series for the variance of its mean (module docstring).

    N_eff = N / (1 + 2 sum rho_k), the sum by Geyer's initial positive sequence, clipped to [1, N].
    """
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n < 3:
        return float(n), 0.0
    rho = autocorrelation(x)
    # Geyer: tau = -1 + 2 sum_j Gamma_j, Gamma_j = rho_2j + rho_2j+1 while positive; Gamma_0 = 1 + rho_1.
    s = float(rho[1]) if 1.0 + rho[1] > 0.0 else 0.0
    for j in range(1, len(rho) // 2):
        pair = rho[2 * j] + rho[2 * j + 1]
        if pair <= 0.0:
            break
        s += pair
    n_eff = n / (1.0 + 2.0 * s)
    return float(min(max(n_eff, 1.0), n)), float(s)


def _chi2_ppf(q: float, dof: float) -> float:
    """Chi-square quantile (scipy.special directly: the scipy.stats wrapper costs 0.2 ms a call, a
    quarter of an identification in a batch study)."""
    from scipy.special import gammaincinv

    return 2.0 * float(gammaincinv(dof / 2.0, q))


def nis_band(m: int, n_eff: float, *, level: float = 0.95) -> list[float]:
    """Two-sided ``level`` band of the mean NIS of m channels over n_eff independent steps."""
    a = 1.0 - level
    dof = m * n_eff
    return [_chi2_ppf(a / 2, dof) / n_eff, _chi2_ppf(1 - a / 2, dof) / n_eff]


def whiteness(innov: np.ndarray, names: list[str], *, level: float = 0.95) -> dict[str, Any]:
    """Lag-1 autocorrelation of each channel's innovations against +- z(1 - a/(2m))/sqrt(N)."""
    from scipy.special import ndtri

    innov = np.asarray(innov, dtype=float)
    m = innov.shape[1]
    out: dict[str, Any] = {}
    for j, name in enumerate(names):
        col = innov[:, j]
        col = col[np.isfinite(col)]
        n = len(col)
        half = float(ndtri(1 - (1 - level) / (2 * m)) / math.sqrt(max(n, 1)))
        d = col - col.mean()
        var = float(d @ d)
        rho1 = (float(d[:-1] @ d[1:]) / var if var > 0 else 0.0) if n > 2 else float("nan")
        out[name] = {"lag1": rho1, "band": [-half, half], "white": bool(abs(rho1) <= half),
                     "steps": n}
    return out


def consistency(nis: np.ndarray, innov: np.ndarray, names: list[str], *,
                level: float = 0.95) -> dict[str, Any]:
    """The numbers the identify stage records about the filter's consistency (module docstring).

    nis (N,) normalised innovation squared per step; innov (N, m) innovations of the m measured
    channels ``names`` (in their data units).
    """
    nis = np.asarray(nis, dtype=float)
    nis = nis[np.isfinite(nis)]
    m = len(names)
    n = len(nis)
    n_eff, rho_sum = effective_sample_size(nis)
    return {
        "nis_mean": float(np.mean(nis)), "nis_expected": float(m), "nis_steps": n,
        "nis_autocorrelation_sum": rho_sum, "nis_n_eff": n_eff,
        "nis_95_band": nis_band(m, n_eff, level=level),
        "nis_95_band_white": nis_band(m, n, level=level),
        "nis_fraction_above_chi2_95": float(np.mean(nis > _chi2_ppf(0.95, m))) if n else None,
        "whiteness": whiteness(innov, names, level=level),
        "level": level,
    }


def flags(cons: dict[str, Any]) -> list[dict[str, Any]]:
    """``nis_mean`` and ``innovation_whiteness`` flags of a :func:`consistency` result."""
    out: list[dict[str, Any]] = []
    nis, (lo, hi) = cons.get("nis_mean"), cons["nis_95_band"]
    m, n_eff = cons["nis_expected"], cons["nis_n_eff"]
    if nis is None or not np.isfinite(nis) or not lo <= nis <= hi:
        high = nis is None or not np.isfinite(nis) or nis > hi
        if high:
            side = ("the innovations are larger than the filter's noise settings say (measurement noise R "
                    "or process noise Q too small, or model mismatch): the filter is over-confident; "
                    "estimates and their uncertainties are not to be trusted")
        else:
            side = ("the innovations are smaller than the filter's noise settings say (R or Q too large, or "
                    "the fading memory inflating P, as it does by design): the filter over-states its "
                    "uncertainty, so its bounds are conservative; this alone does not make the estimates "
                    "wrong (whether the model predicts is judged on held-out runs)")
        out.append({"check": "nis_mean", "value": nis, "band": [lo, hi],
                    "reading": "over-confident" if high else "over-stated uncertainty",
                    "reason": f"mean NIS {nis:.3g} where {m:g} is expected, outside its "
                              f"{cons['level']:.0%} chi-square band [{lo:.3g}, {hi:.3g}] over "
                              f"{n_eff:.0f} effectively independent steps: {side}"})
    bad = {k: w for k, w in cons.get("whiteness", {}).items() if not w["white"]}
    if bad:
        what = ", ".join(f"{k} {w['lag1']:+.2f}" for k, w in bad.items())
        half = next(iter(bad.values()))["band"][1]
        neg = [k for k, w in bad.items() if w["lag1"] < 0]
        pos = [k for k, w in bad.items() if w["lag1"] > 0]
        parts = []
        if neg:
            parts.append(f"negative in {', '.join(neg)}: the filter's gain is too high and it follows the "
                         "measurement noise (R too small or Q too large for the data)")
        if pos:
            parts.append(f"positive in {', '.join(pos)}: the filter's errors persist from step to step "
                         "(model mismatch, unmodelled slow effects, Q too small, or correlated logger noise)")
        why = "; ".join(parts)
        out.append({"check": "innovation_whiteness", "value": {k: w["lag1"] for k, w in bad.items()},
                    "band": [-half, half],
                    "reason": f"innovations not white: lag-1 autocorrelation {what} outside +-{half:.2g} "
                              f"({why}); the parameter covariance does not describe the estimate's error"})
    return out
