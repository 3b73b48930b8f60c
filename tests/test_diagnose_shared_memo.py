"""The fit memo shared by the diagnosis's processes (pipeline.diagnose.fit.SharedFitMemo,
docs/performance.md): a fit made in one process is the same bits in another, a fit another process is
making is waited for (not made twice), a claim whose process has died or whose fit failed is given up,
and the kernel's layout and start columns asked for change no number of the Jacobian."""

from __future__ import annotations

import dataclasses as dc
import multiprocessing
import os
import pickle

import numpy as np
import pytest

from pipeline.diagnose import TruthConfig, zigzag_truth
from pipeline.diagnose.core import _context
from pipeline.diagnose.fit import (
    FitMemo,
    SharedFitMemo,
    fit_memo,
    fit_structure,
    oe_batch,
    series_from_run,
    structure_of,
)

fork = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="no fork here")


@pytest.fixture(scope="module")
def data():
    cfg = TruthConfig(seed=31, rudder_offset=1.0)
    runs = [zigzag_truth(a, a, side, 30.0, dc.replace(cfg, seed=31 + j))
            for j, (a, side) in enumerate([(20, "starboard"), (10, "port")])]
    series = [series_from_run(r) for r in runs]
    return series, _context(series)


@fork
def test_claims_waits_and_release():
    """On a plain dictionary as the store: the first asker claims (None: make it), a put is seen by a
    second memo (another process's view), a released claim is claimed again, and a claim left by a
    process that no longer exists is taken over instead of waited for."""
    store: dict = {}
    a, b = SharedFitMemo(store), SharedFitMemo(store)
    assert a.get("k") is None                      # claimed by a
    a.put("k", "fit")
    assert b.get("k") == "fit"
    assert b.get("j") is None
    b.release("j")
    assert a.get("j") is None                      # claimable again after the release
    # a claim by a process that has died (a pid that exists no more: a reaped child's)
    p = multiprocessing.get_context("fork").Process(target=os._exit, args=(0,))
    p.start()
    p.join()
    store[SharedFitMemo._key("dead")] = ("claim", p.pid, 1)
    assert a.get("dead") is None                   # taken over, not waited for forever


def test_pickled_memo_keeps_only_the_store():
    m = SharedFitMemo({})
    m.put("k", "fit")
    m2 = pickle.loads(pickle.dumps(m))
    assert len(m2) == 0 and m2.get("k") == "fit"


def _fit_in_child(series, ctx, start, memo, out):
    fit = fit_structure(series, structure_of("rudder_offset"), ctx, start=start, memo=memo)
    out.put(fit.p.tobytes())


@fork
def test_a_fit_made_in_another_process_is_the_same_bits(data):
    """Through a real manager: the child makes the fit, the parent gets those bits from the store
    without fitting (its own fit, made without a memo, is the same bits)."""
    series, ctx = data
    base = fit_structure(series, (), ctx)
    with fit_memo(2) as memo:
        assert isinstance(memo, SharedFitMemo)
        mp = multiprocessing.get_context("fork")
        q = mp.Queue()
        p = mp.Process(target=_fit_in_child, args=(series, ctx, base, memo, q))
        p.start()
        child = q.get(timeout=120)
        p.join()
        assert p.exitcode == 0
        assert len(memo._store) == 1
        got = fit_structure(series, structure_of("rudder_offset"), ctx, start=base, memo=memo)
        assert got.p.tobytes() == child
    own = fit_structure(series, structure_of("rudder_offset"), ctx, start=base)
    assert own.p.tobytes() == child and own.cost == got.cost and own.std == got.std
    with fit_memo(1) as one:
        assert type(one) is FitMemo


def test_layout_and_start_columns_change_no_number(data):
    """The Jacobian in Fortran layout is the row-layout one, element for element; asking for the
    sensitivity of one start state gives the same bits in every column as asking for all three."""
    from pipeline.diagnose.fit import Layout, _scales, jacobian, reference_speed

    series, ctx = data
    layout = Layout(structure_of("rudder_offset", "nonlinear_yaw_damping"), ctx)
    lo, hi = layout.bounds()
    batch = oe_batch(series, _scales(series), layout, reference_speed(series))
    fit = fit_structure(series, layout.structure, ctx)
    p = fit.p
    every = [(k, i, 0.5 + i) for k in range(len(series)) for i in range(3)]
    some = [x for x in every if x[1] == 1]
    fc, jc = jacobian(batch, p, lo, hi, None, every)
    ff, jf = jacobian(batch, p, lo, hi, None, every, order="F")
    assert jf.flags.f_contiguous and np.array_equal(fc, ff) and np.array_equal(jc, jf)
    fs, js = jacobian(batch, p, lo, hi, None, some)
    assert np.array_equal(fs, fc)
    n = p.size
    assert np.array_equal(js[:, :n], jc[:, :n])
    for c, x in enumerate(some):
        assert np.array_equal(js[:, n + c], jc[:, n + every.index(x)])
    assert np.any(js[:, n:] != 0)
