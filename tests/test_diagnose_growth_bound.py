"""The bounded form of an extension (DiagnoseConfig.bound_small_motion; docs/diagnosis.md, "Sound at
every amplitude"): the growth rate of the fitted linear part held at most at a bound by a penalty row
in the output-error polish (pipeline.diagnose.fit._GrowthPenalty).

Known answers: the penalty's derivative is the growth rate's (central differences, real and complex
poles); it is zero at and below the bound; and a fit of the linear truth (the paper's Table 4 hull,
course-stable) held below a bound stricter than its own growth rate lands on the bound, while the
free fit does not."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest

from pipeline.diagnose import TruthConfig, zigzag_truth
from pipeline.diagnose.core import _context
from pipeline.diagnose.fit import _GrowthPenalty, fit_structure, growth_rate, series_from_run


@pytest.mark.parametrize("a", [(-0.3, -2.0, -4.0, -0.8), (-0.3, -2.0, 4.0, -0.8), (0.2, -0.5, -15.9, 0.1)],
                         ids=["real poles", "complex poles", "unstable"])
def test_the_penalty_row_is_the_growth_rates_excess_and_its_derivative(a):
    x = np.array([*a, 0.01, -0.2, 0.5])          # a11 a12 a21 a22 b11 b21 and one more parameter
    g = growth_rate(x)
    pen = _GrowthPenalty(g - 0.05, [])           # bound below the growth rate: the row is active
    v, grad = pen._row(x, n_rows=100)
    w = np.sqrt(100) * pen.duration
    assert v == pytest.approx(w * 0.05, rel=1e-9)
    for i in range(4):
        h = 1e-7 * max(1.0, abs(x[i]))
        xp, xm = x.copy(), x.copy()
        xp[i] += h
        xm[i] -= h
        assert grad[i] == pytest.approx(w * (growth_rate(xp) - growth_rate(xm)) / (2 * h), rel=1e-5, abs=1e-9)
    assert np.all(grad[4:] == 0.0)
    v, grad = _GrowthPenalty(g + 1e-3, [])._row(x, n_rows=100)     # below the bound: no penalty
    assert v == 0.0 and np.all(grad == 0.0)
    f = _GrowthPenalty(None, [])
    assert f.fun(len) is len and f.fun_jac(len) is len             # no bound: the functions themselves


@pytest.mark.slow
def test_a_fit_held_below_its_own_growth_rate_lands_on_the_bound():
    cfg = TruthConfig(seed=21)
    runs = [series_from_run(zigzag_truth(a, a, s, 60.0, dc.replace(cfg, seed=cfg.seed + j)))
            for j, (a, s) in enumerate(((20, "starboard"), (10, "port")))]
    ctx = _context(runs)
    free = fit_structure(runs, (), ctx)
    bound = growth_rate(free.theta) - 0.05          # stricter than the data's own linear model
    held = fit_structure(runs, (), ctx, start=free, growth_bound=bound)
    assert growth_rate(free.theta) > bound + 0.04
    assert growth_rate(held.theta) <= bound + 1e-3 * abs(bound) + 1e-5, (growth_rate(held.theta), bound)
    assert growth_rate(held.theta) == pytest.approx(bound, abs=2e-3)      # on the bound, not below it
    assert held.cost >= free.cost and held.growth_bound == bound
    assert "growth rate of the linear part held" in held.message
