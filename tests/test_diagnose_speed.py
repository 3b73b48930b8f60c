"""The diagnosis's speed devices change no model: the analytic Jacobian (the kernel's sensitivities)
reaches the optimum of SciPy's finite differences within the optimiser's tolerance, and fits memoised
within one diagnosis are the bits of the fit they stand for."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest

from pipeline.diagnose import TruthConfig, zigzag_truth
from pipeline.diagnose.core import _context
from pipeline.diagnose.fit import FitMemo, fit_structure, series_from_run, structure_of


@pytest.fixture(scope="module")
def data():
    cfg = TruthConfig(seed=21, rudder_offset=1.5, rudder_delay=0.5)
    runs = [
        zigzag_truth(a, a, side, 40.0, dc.replace(cfg, seed=21 + j))
        for j, (a, side) in enumerate([(20, "starboard"), (10, "port")])
    ]
    series = [series_from_run(r) for r in runs]
    return series, _context(series)


def _same(a, b):
    assert np.array_equal(a.p, b.p)
    assert a.cost == b.cost
    assert a.std == b.std


@pytest.mark.parametrize("boxed", [False, True], ids=["from the estimate", "starts fitted in their box"])
def test_analytic_jacobian_reaches_the_finite_difference_fit(data, boxed):
    """The fit (a prediction-error start, a dead time profiled over its grid with its column by
    difference, the output-error polish, with and without the training runs' starts fitted) with the
    kernel's sensitivities and with SciPy's forward differences from Python (a plain fit): the same
    optimum.  Thresholds: the training cost within the least-squares stopping tolerance ftol = 1e-6
    (fit._TOL; measured 1e-12 apart), every parameter within 1e-3 of its own standard error (measured
    6e-5): another Jacobian takes other steps, not to another model."""
    from pipeline.diagnose.fit import _TOL, with_initial_states

    series, ctx = data
    if boxed:
        series = with_initial_states(series, 0.25 * ctx.t_ship, box_sigma=2.0)
    for st in [(), structure_of("rudder_offset"), structure_of("rudder_offset", "rudder_delay")]:
        fast = fit_structure(series, st, ctx)
        plain = fit_structure(series, st, ctx, plain=True)
        assert plain.plain and not fast.plain
        assert abs(fast.cost - plain.cost) <= _TOL["ftol"] * plain.cost, st
        for i, n in enumerate(fast.names):
            assert abs(fast.p[i] - plain.p[i]) <= 1e-3 * max(plain.std[n], 1e-12), (st, n)
        assert fast.start_z.size == (2 if boxed else 0)
    assert abs(fast.values["rudder_delay"]["delay_s"] - 0.5) < 0.15  # and it is a real fit


def test_memo_returns_the_fit_it_would_make(data):
    series, ctx = data
    base = fit_structure(series, (), ctx)
    st = structure_of("rudder_offset")

    memo = FitMemo()
    a = fit_structure(series, st, ctx, start=base, memo=memo)
    b = fit_structure(series, st, ctx, start=base, memo=memo)
    c = fit_structure(series, st, ctx, memo=memo)  # another start: a fit of its own
    assert a is b and c is not a and len(memo) == 2
    _same(a, fit_structure(series, st, ctx, start=base))  # no memo: fitted anew, same bits
