"""One machine first (issue 12): the SR-UKF step is allocation-free, and the batch identification on
every core gives each run's serial numbers."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.config import FilterConfig
from pipeline.identify import fast, identify_arrays, identify_batch, synthetic
from pipeline.identify.fuzzy import RULES, fuzzy_factor_ws
from pipeline.identify.srukf import ut_weights

H = 0.08
ROOT = Path(__file__).resolve().parents[1]


FRESH = "PIPELINE_FRESH_NUMBA_CHECK"


def _compiled_ir(fn) -> str:
    assert fn.signatures, f"{fn.__name__} not compiled"
    return "\n".join(fn.inspect_llvm(sig) for sig in fn.signatures)


@pytest.mark.skipif(os.environ.get(FRESH) != "1",
                    reason="runs inside test_per_step_code_makes_no_heap_allocation "
                    "(numba cannot show the code it loads from its cache)")
def test_fresh_compile_has_no_allocation_in_the_step():
    x = np.zeros(9)
    S = np.eye(9)
    Y = np.zeros((5, 3))
    w = ut_weights(9, 1.0, 2.0, 0.0)
    sq_q, sq_r = np.diag([0.02, 0.02, 0.01, 0, 0, 0, 0, 0, 0]), np.diag([0.02, 0.02, 0.01])
    fz = np.array([-0.5, 0.5, -0.5, 0.5, 0.95, 1.0])
    outs = (np.empty((5, 9)), np.empty((5, 9)), np.empty((5, 9)), np.empty((5, 3)), np.empty(5), np.empty(5))
    st, _ = fast.srukf_steps(x, S, Y, np.zeros(5), H, sq_q, fast.nonzero_columns(sq_q), sq_r,
                             fast.nonzero_columns(sq_r), np.array([0, 1, 2]), w.wm, w.wc, w.gamma, True, 1,
                             fz, RULES, fast.workspace(3), *outs)
    assert st == 0
    for fn in (fast.srukf_steps, fast._factor, fast._tria_t, fast._cholupdate, fast._fx, fuzzy_factor_ws):
        ir = _compiled_ir(fn)
        assert "NRT_MemInfo_alloc" not in ir and "NRT_Allocate" not in ir, fn.__name__
    assert "NRT_MemInfo_alloc" in _compiled_ir(fast.workspace)     # the check does see an allocation


@pytest.mark.slow
def test_per_step_code_makes_no_heap_allocation(tmp_path):
    env = {**os.environ, FRESH: "1", "NUMBA_CACHE_DIR": str(tmp_path),
           "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    res = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          f"{__file__}::test_fresh_compile_has_no_allocation_in_the_step"],
                         env=env, capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert res.returncode == 0 and "1 passed" in res.stdout, res.stdout[-3000:]


def test_parallel_batch_equals_serial_batch_and_single_runs():
    Ys, ds = [], []
    for seed in range(9):
        _, d, _, y = synthetic.zigzag(n=150, seed=seed, rudder=12 + seed)
        Ys.append(y)
        ds.append(d)
    Ys, ds = np.stack(Ys), np.stack(ds)
    th_s, P_s, st_s, _ = identify_batch(Ys, ds, H)
    th_p, P_p, st_p, _ = identify_batch(Ys, ds, H, parallel=True)
    assert np.all(st_s == 0) and np.array_equal(st_s, st_p)
    assert np.array_equal(th_s, th_p) and np.array_equal(P_s, P_p)       # same code per run: same bits
    t = np.arange(150) * H
    one = identify_arrays(t, ds[4], Ys[4], FilterConfig(), samples=150)
    assert np.allclose(th_p[4], list(one.parameters.values()), rtol=1e-10)
