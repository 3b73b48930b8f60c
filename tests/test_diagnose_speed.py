"""The diagnosis's speed devices change no number: the finite-difference Jacobian evaluated in one
batched call, and fits memoised within one diagnosis, give the bits of the plain fit."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest

from pipeline.diagnose import TruthConfig, zigzag_truth
from pipeline.diagnose.core import _context
from pipeline.diagnose.fit import fit_structure, memoised, series_from_run, structure_of


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


def test_batched_jacobian_gives_the_column_by_column_fit(data, monkeypatch):
    """With SciPy's own column-by-column finite differences (no ``workers``) the fit (a prediction-
    error start, a dead time profiled over its grid, the output-error polish) is the same bits."""
    import pipeline.diagnose.fit as fit

    series, ctx = data
    st = structure_of("rudder_offset", "rudder_delay")
    fast = fit_structure(series, st, ctx)
    assert fit._HAS_WORKERS  # SciPy >= 1.16: the batched path was the one measured
    monkeypatch.setattr(fit, "_HAS_WORKERS", False)
    plain = fit_structure(series, st, ctx)
    _same(fast, plain)
    assert abs(fast.values["rudder_delay"]["delay_s"] - 0.5) < 0.15  # and it is a real fit


def test_memo_returns_the_fit_it_would_make(data):
    series, ctx = data
    base = fit_structure(series, (), ctx)
    st = structure_of("rudder_offset")

    @memoised
    def twice():
        a = fit_structure(series, st, ctx, start=base)
        b = fit_structure(series, st, ctx, start=base)
        other_start = fit_structure(series, st, ctx)  # another start: a fit of its own
        return a, b, other_start

    a, b, c = twice()
    assert a is b and c is not a
    _same(a, fit_structure(series, st, ctx, start=base))  # outside a diagnosis: no memo, same bits
