"""The streaming identifier equals the batch kernel sample for sample (docs/control.md)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.config import FilterConfig
from pipeline.errors import InputError
from pipeline.identify import synthetic
from pipeline.identify.core import _arrays, initial_state, measured_indices, run_filter
from pipeline.identify.stream import StreamingIdentifier


@pytest.mark.parametrize("drop_v", [False, True])
def test_streaming_equals_the_batch_kernel_sample_for_sample(drop_v):
    run = synthetic.zigzag_run("s", n=400, seed=3, noise=(0.005, 0.05, 0.05))
    if drop_v:
        run.frame["v"] = np.nan
    _, d, Y3 = _arrays(run)
    meas = measured_indices(Y3[:, 0])
    cfg = FilterConfig()
    x0, P0 = initial_state(Y3[0], meas, cfg)
    batch = run_filter("srukf-ffm", x0, P0, Y3[1:], d[:-1], h=run.dt, cfg=cfg, meas_idx=meas)
    s = StreamingIdentifier(x0, P0, run.dt, cfg, meas)
    for k in range(1, len(d)):
        sample = {"delta": d[k - 1], "r": Y3[k, 1], "psi": Y3[k, 2]}
        if not drop_v:
            sample["v"] = Y3[k, 0]
        got = s.update(sample)
        np.testing.assert_array_equal(s.x, batch.x[k - 1])
        assert got["nis"] == batch.nis[k - 1] and got["f"] == batch.f[k - 1]
    est = s.estimate()
    np.testing.assert_array_equal(list(est["parameters"].values()), batch.x_final[3:])
    np.testing.assert_allclose(est["covariance"], batch.P_final[3:, 3:], rtol=1e-12, atol=0)
    assert est["steps"] == len(d) - 1
    # the fuzzy forgetting really acted (f < 1 somewhere), so its carried memory was tested
    assert np.min(batch.f) < 1.0


def test_streaming_refuses_bad_samples():
    cfg = FilterConfig()
    x0, P0 = initial_state(np.zeros(3), [0, 1, 2], cfg)
    s = StreamingIdentifier(x0, P0, 0.08, cfg)
    with pytest.raises(InputError, match="sample 0"):
        s.update({"delta": 1.0, "v": 0.0, "r": 0.1})
    with pytest.raises(InputError, match="NaN"):
        s.update({"delta": 1.0, "v": 0.0, "r": np.nan, "psi": 0.0})
    with pytest.raises(InputError):
        StreamingIdentifier(x0, P0, 0.0, cfg)
