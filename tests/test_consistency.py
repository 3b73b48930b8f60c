"""Filter-consistency checks (pipeline/identify/consistency.py): the NIS band with the effective
sample size holds its 95 % level on correlated innovations where the white band does not, and the
whiteness check has its stated false-alarm rate.  Truths are simulated sequences with a known
autocorrelation, not the filter."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.identify import consistency as cons


def _ar1(rng, n, m, rho):
    """m independent unit-variance Gaussian AR(1) channels with lag-1 correlation rho."""
    e = rng.standard_normal((n, m))
    x = np.empty((n, m))
    x[0] = e[0]
    for k in range(1, n):
        x[k] = rho * x[k - 1] + np.sqrt(1 - rho**2) * e[k]
    return x


def test_effective_sample_size_of_an_ar1_series():
    # the mean of an AR(1) series has the variance of N (1 - rho) / (1 + rho) independent values
    rng = np.random.default_rng(1)
    n, rho = 40000, 0.8
    x = _ar1(rng, n, 1, rho)[:, 0]
    n_eff, s = cons.effective_sample_size(x)
    assert n_eff == pytest.approx(n * (1 - rho) / (1 + rho), rel=0.15)
    assert s == pytest.approx(rho / (1 - rho), rel=0.15)            # sum rho^k
    w, _ = cons.effective_sample_size(rng.standard_normal(n))
    assert w == pytest.approx(n, rel=0.1) and w <= n
    assert cons.effective_sample_size(np.full(50, 2.0))[0] == 50   # no variation: no correlation to count


def _coverage(rho, runs=300, n=585, m=3, seed=2):
    rng = np.random.default_rng(seed)
    inside_eff = inside_white = 0
    for _ in range(runs):
        nu = _ar1(rng, n, m, rho)                  # innovations with S = I: NIS = |nu|^2, mean m
        c = cons.consistency((nu**2).sum(axis=1), nu, ["v", "r", "psi"])
        lo, hi = c["nis_95_band"]
        inside_eff += lo <= c["nis_mean"] <= hi
        lo, hi = c["nis_95_band_white"]
        inside_white += lo <= c["nis_mean"] <= hi
    return inside_eff / runs, inside_white / runs


def test_nis_band_keeps_its_level_on_correlated_innovations():
    # 300 runs: a binomial 95 % has a standard deviation of 1.3 %, so [0.89, 0.995] is +-4.5 sigma
    eff, white = _coverage(0.8)
    assert 0.89 <= eff <= 0.995, eff
    # the NIS of AR(1) innovations has autocorrelation rho^2k: N_eff = N / 4.56, so the white band is
    # 0.47 times too narrow and holds 2 Phi(1.96 x 0.47) - 1 = 64 % instead of 95 %
    assert white < 0.75, white
    eff, white = _coverage(0.0, seed=3)
    assert 0.89 <= eff <= 0.995 and 0.89 <= white <= 0.995, (eff, white)


def test_whiteness_false_alarm_rate_and_power():
    rng = np.random.default_rng(4)
    names = ["v", "r", "psi"]
    alarms = sum(bool(cons.flags(cons.consistency((nu**2).sum(1), nu, names)) and
                      any(not w["white"] for w in cons.whiteness(nu, names).values()))
                 for nu in (rng.standard_normal((585, 3)) for _ in range(400)))
    assert alarms / 400 < 0.09                     # 5 % by construction (Bonferroni), +-1.1 % binomial
    nu = _ar1(rng, 585, 3, 0.3)
    w = cons.whiteness(nu, names)
    assert not any(x["white"] for x in w.values())
    f = cons.flags(cons.consistency((nu**2).sum(1), nu, names))
    assert [x["check"] for x in f] == ["innovation_whiteness"]
    assert "persist from step to step" in f[0]["reason"]


def test_nis_flag_says_which_way():
    rng = np.random.default_rng(5)
    nu = rng.standard_normal((585, 3))
    for factor, word in ((3.0, "larger"), (1 / 3, "smaller")):
        c = cons.consistency(factor * (nu**2).sum(1), nu, ["v", "r", "psi"])
        (f,) = cons.flags(c)
        assert f["check"] == "nis_mean" and word in f["reason"] and f["band"] == c["nis_95_band"]
