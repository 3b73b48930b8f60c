"""Small statistics for study summaries: binomial intervals and the magnitude detected at a level."""

from __future__ import annotations

import hashlib
import math
from typing import Any

import numpy as np
from scipy.optimize import minimize
from scipy.stats import beta


def clopper_pearson(k: int, n: int, *, confidence: float = 0.95) -> tuple[float, float]:
    """Exact (Clopper-Pearson) two-sided interval of a binomial proportion k / n."""
    if n <= 0:
        return (0.0, 1.0)
    a = 1.0 - confidence
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return (lo, hi)


def rng_for(study_seed: int, label: str) -> np.random.Generator:
    """A generator seeded from the study seed and a label (e.g. effect and plant): deterministic."""
    key = int(hashlib.sha256(label.encode()).hexdigest()[:15], 16)
    return np.random.default_rng(np.random.SeedSequence(int(study_seed), spawn_key=(key,)))


#: Ridge on the logistic slope and intercept: keeps the fit finite when the cases separate perfectly
#: (every case above some magnitude detected, none below), where the maximum-likelihood slope is
#: infinite; 1e-3 is negligible against the log-likelihood of a few dozen cases otherwise.
RIDGE = 1e-3


def _fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Logistic regression P(detect) = 1 / (1 + exp(-(a + b x))) by penalised maximum likelihood."""
    def nll(p):
        z = p[0] + p[1] * x
        return float(np.sum(np.logaddexp(0.0, z) - y * z) + RIDGE * (p[0] ** 2 + p[1] ** 2))

    def grad(p):
        z = p[0] + p[1] * x
        r = 1.0 / (1.0 + np.exp(-z)) - y
        return np.array([r.sum() + 2 * RIDGE * p[0], (r * x).sum() + 2 * RIDGE * p[1]])

    res = minimize(nll, np.zeros(2), jac=grad, method="BFGS")
    return float(res.x[0]), float(res.x[1])


def _level_x(a: float, b: float, level: float) -> float | None:
    if not b > 0:
        return None
    return (math.log(level / (1 - level)) - a) / b


def logistic_level(mag: np.ndarray, detected: np.ndarray, level: float, confidence: float, n_boot: int,
                   seed) -> dict[str, Any]:
    """Magnitude detected with probability ``level`` from a logistic fit on log magnitude.

    Interval: percentile bootstrap, cases resampled within each magnitude (the design is kept).
    ``value`` is null (with a note) when the fitted curve does not rise or reaches the level outside
    the magnitudes tried by more than a factor 2 (an extrapolation, not a measurement).
    """
    mag = np.asarray(mag, float)
    y = np.asarray(detected, float)
    x = np.log(mag)
    lo_m, hi_m = float(mag.min()), float(mag.max())
    out: dict[str, Any] = {"value": None, "interval": [None, None], "level": level,
                           "method": f"logistic fit on log magnitude; {confidence:.0%} percentile "
                                     f"bootstrap ({n_boot} resamples)",
                           "intercept": None, "slope": None, "note": None,
                           "tried": [lo_m, hi_m], "n": int(mag.size)}
    if y.min() == y.max():
        out["note"] = (f"every case detected: below the smallest magnitude tried ({lo_m:g})" if y[0] == 1
                       else f"no case detected: above the largest magnitude tried ({hi_m:g})")
        out["interval"] = [None, lo_m] if y[0] == 1 else [hi_m, None]
        return out
    levels = np.unique(mag)
    rate = np.array([y[mag == m].mean() for m in levels])
    if np.all((rate == 0) | (rate == 1)) and np.all(np.diff(rate) >= 0):
        # a step: no case between "never" and "always"; the point lies between the two magnitudes and
        # neither the fit nor a bootstrap of these cases can place it closer (every resample is the same)
        lo_s, hi_s = float(levels[rate == 0].max()), float(levels[rate == 1].min())
        out["interval"] = [lo_s, hi_s]
        out["note"] = (f"detection jumps from none at {lo_s:g} to every case at {hi_s:g}: the {level:.0%} "
                       "point lies between them (add magnitudes in between to place it)")
        return out
    a, b = _fit(x, y)
    out["intercept"], out["slope"] = a, b
    xv = _level_x(a, b, level)
    if xv is None:
        out["note"] = "detection does not rise with magnitude in the cases tried"
        return out
    val = math.exp(xv)
    if not (lo_m / 2 <= val <= hi_m * 2):
        out["note"] = (f"the fitted {level:.0%} point {val:.3g} lies outside the magnitudes tried "
                       f"[{lo_m:g}, {hi_m:g}] by more than a factor 2: not reported")
        return out
    out["value"] = val
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    groups = [np.flatnonzero(mag == m) for m in np.unique(mag)]
    boots = []
    for _ in range(n_boot):
        idx = np.concatenate([rng.choice(g, size=g.size, replace=True) for g in groups])
        yb = y[idx]
        if yb.min() == yb.max():
            boots.append(lo_m if yb[0] == 1 else np.inf)
            continue
        ab, bb = _fit(x[idx], yb)
        xb = _level_x(ab, bb, level)
        boots.append(math.exp(min(xb, 50.0)) if xb is not None else np.inf)
    boots = np.array(boots)
    q = (1 - confidence) / 2
    lo_b, hi_b = np.quantile(boots, [q, 1 - q])
    out["interval"] = [float(lo_b), float(hi_b) if np.isfinite(hi_b) else None]
    if not np.isfinite(hi_b):
        out["note"] = "upper bound not reached in the bootstrap (some resamples never reach the level)"
    return out
