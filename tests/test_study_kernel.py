"""One machine first: the SR-UKF step is allocation-free.  (The batch identification on
every core giving each run's serial numbers is tested in tests/test_identify.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.identify import fast, synthetic
from pipeline.identify.fuzzy import RULES
from pipeline.identify.srukf import ut_weights

H = 0.08


@pytest.fixture
def nrt_stats():
    """numba's own allocation counters (NRT_STATS; numba's tests read them the same way), switched on
    for the test only.  Counted at run time, so the check holds for code loaded from numba's cache
    too (no fresh compile)."""
    from numba.core.runtime import _nrt_python, rtsys

    was = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    yield lambda: rtsys.get_allocation_stats().alloc
    if not was:
        _nrt_python.memsys_disable_stats()


def test_filter_step_makes_no_heap_allocation(nrt_stats):
    """The kernel over 5 and over 400 steps makes the same number of allocations (those of passing the
    arrays in): none per step.  The counter does see allocations (the workspace's)."""
    _, d, _, y = synthetic.zigzag(n=401, seed=3)
    w = ut_weights(9, 1.0, 2.0, 0.0)
    sq_q, sq_r = np.diag([0.02, 0.02, 0.01, 0, 0, 0, 0, 0, 0]), np.diag([0.02, 0.02, 0.01])
    fz = np.array([-0.5, 0.5, -0.5, 0.5, 0.95, 1.0])
    q_cols, r_cols, idx = fast.nonzero_columns(sq_q), fast.nonzero_columns(sq_r), np.array([0, 1, 2])
    ws = fast.workspace(3)

    def allocations(n):
        x, S = np.r_[y[0], 0.1, 0.1, 0.1, -1.0, 0.0, -0.1], np.eye(9) * 0.1
        outs = (np.empty((n, 9)), np.empty((n, 9)), np.empty((n, 9)), np.empty((n, 3)), np.empty(n),
                np.empty(n))
        Y, dp = np.ascontiguousarray(y[1:n + 1]), np.ascontiguousarray(d[:n])
        before = nrt_stats()
        p = (H, sq_q, q_cols, sq_r, r_cols, idx, w.wm, w.wc, w.gamma, True, 1, fz, RULES)
        st, k = fast.srukf_steps(x, S, (Y, dp), p, ws, outs)
        used = nrt_stats() - before
        assert st == 0 and k == n and np.all(np.isfinite(outs[1]))
        assert np.any(outs[5] < 1.0)                 # the fuzzy factor path did run
        return used

    allocations(5)                                   # compiled or loaded before counting
    assert allocations(400) == allocations(5)
    before = nrt_stats()
    fast.workspace(3)
    assert nrt_stats() - before >= 19                # the counter sees the workspace's arrays
