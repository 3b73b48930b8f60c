"""Identification: recovery of simulated truths, baseline agreement, batch mode, CLI and bad input."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.config import FilterConfig
from pipeline.identify import identify_arrays, identify_batch, identify_run, synthetic
from pipeline.identify.baseline import CountingCholesky
from pipeline.io import write_run
from pipeline.model import PAPER_TABLE4, PARAM_NAMES, as_theta, nomoto_indices, simulate

H = 0.08
TRUTH = nomoto_indices(PAPER_TABLE4)
SPEC_KEYS = {"algorithm", "samples", "parameters", "covariance", "indices", "timing"}


def _zigzag_like_rudder(n, amp=20.0, half_period=8.0, rate=14.28):
    """Open-loop square wave +-amp (half period s) through a rate limit: a zigzag-like rudder."""
    t = np.arange(n) * H
    target = np.where((t // half_period) % 2 == 0, amp, -amp)
    d = np.zeros(n)
    for k in range(1, n):
        d[k] = d[k - 1] + np.clip(target[k] - d[k - 1], -rate * H, rate * H)
    return t, d


def _consistent_zigzag(seed, n=585):
    """Truth with process noise of the size of Q and measurement noise of the size of R."""
    rng = np.random.default_rng(seed)
    t, d = _zigzag_like_rudder(n)
    th = as_theta(PAPER_TABLE4)
    x = np.zeros(3)
    clean = np.empty((n, 3))
    for k in range(n):
        clean[k] = x
        x = np.array([x[0] + H * (th[0] * x[0] + th[1] * x[1] + th[4] * d[k]),
                      x[1] + H * (th[2] * x[0] + th[3] * x[1] + th[5] * d[k]), x[2] + H * x[1]])
        x = x + rng.standard_normal(3) * np.array([0.02, 0.02, 0.01])
    return t, d, clean + rng.standard_normal((n, 3)) * np.array([0.02, 0.02, 0.01])


def _rel(ind):
    return abs(ind["K"] / TRUTH["K"] - 1), abs(ind["T"] / TRUTH["T"] - 1)


def test_recovers_table4_from_model_simulate_with_measurement_noise():
    # the truth has no process noise, so the filter's state process noise is set to match (small)
    n = 585
    t, d = _zigzag_like_rudder(n)
    clean = simulate(PAPER_TABLE4, (0, 0, 0), d, H)
    y = clean + np.random.default_rng(FilterConfig().samples).standard_normal((n, 3)) * [0.02, 0.02, 0.01]
    cfg = dataclasses.replace(FilterConfig(), q_std=(0.002, 0.002, 0.001) + (0.0,) * 6)
    res = identify_arrays(t, d, y, cfg)
    assert res.samples == 585
    eK, eT = _rel(res.indices)
    assert eK < 0.05 and eT < 0.05, res.indices
    # every parameter within 4 of the filter's own one-sigma of the truth
    std = np.sqrt(np.diag(res.covariance))
    z = (np.array(list(res.parameters.values())) - as_theta(PAPER_TABLE4)) / std
    assert np.all(np.abs(z) < 4), dict(zip(PARAM_NAMES, z, strict=True))
    tr = res.trace
    assert tr["f"].between(0.95, 1.0).all() and tr["f"].min() < 1.0
    assert 1.0 < res.consistency["nis_mean"] < 5.0


@pytest.mark.parametrize("with_v", [True, False])
def test_recovers_indices_with_paper_q_on_consistent_data(with_v):
    # data made with the noise the filter assumes (Q and R of the paper); mean of 4 seeded runs
    errs = []
    for seed in range(4):
        t, d, y = _consistent_zigzag(100 + seed)
        if not with_v:
            y[:, 0] = np.nan
        res = identify_arrays(t, d, y, FilterConfig())
        assert res.measured == (["v", "r", "psi"] if with_v else ["r", "psi"])
        errs.append([res.indices["K"] / TRUTH["K"] - 1, res.indices["T"] / TRUTH["T"] - 1])
    mean = np.abs(np.mean(errs, axis=0))
    # without v the hidden sway makes the indices less well determined (a known limitation, the
    # filter must stay stable and in the right neighbourhood); with v: within 5 %
    assert np.all(mean < (0.05 if with_v else 0.25)), errs


def test_baseline_agrees_with_srukf_and_counts_no_failures():
    t, d, _, y = synthetic.zigzag(n=300, seed=4)
    a = identify_arrays(t, d, y, FilterConfig(), algorithm="srukf-ffm")
    b = identify_arrays(t, d, y, FilterConfig(), algorithm="ffm-ukf")
    assert np.allclose(list(a.parameters.values()), list(b.parameters.values()), rtol=1e-7)
    assert np.allclose(a.covariance, b.covariance, rtol=1e-6, atol=1e-14)
    assert b.filterpy_failures == 0 and "chol_failures" in b.trace
    assert a.filterpy_failures is None


def test_counting_cholesky_counts_and_repairs():
    chol = CountingCholesky()
    A = np.diag([1.0, 1e-3, -1e-12])              # not positive definite
    U = chol(A)
    assert chol.failures == 1
    assert np.allclose(U.T @ U, np.diag([1.0, 1e-3, 0.0]), atol=1e-9)
    chol(np.eye(3))
    assert chol.failures == 1


def test_batch_serial_and_parallel_equal_single_runs():
    """The batch kernel gives each run's single-run numbers; on every core (numba threads over blocks
    of runs, 9 runs in 8 blocks on 2 threads) the same bits as serially."""
    Ys, ds = [], []
    for seed in range(9):
        t, d, _, y = synthetic.zigzag(n=200, seed=seed, rudder=12 + seed)
        Ys.append(y)
        ds.append(d)
    theta, P, status, secs = identify_batch(np.stack(Ys), np.stack(ds), H)
    assert np.all(status == 0) and secs > 0
    th_p, P_p, st_p, _ = identify_batch(np.stack(Ys), np.stack(ds), H, parallel=True)
    assert np.array_equal(status, st_p)
    assert np.array_equal(theta, th_p) and np.array_equal(P, P_p)      # same code per run: same bits
    for k in range(9):
        single = identify_arrays(t, ds[k], Ys[k], FilterConfig(), samples=200)
        assert np.allclose(theta[k], list(single.parameters.values()), rtol=1e-10)
        assert np.allclose(P[k], single.covariance, rtol=1e-8, atol=1e-16)


def test_cli_single_run_writes_spec_estimates(tmp_path, capsys):
    run = synthetic.zigzag_run("zz", n=700, seed=3)
    write_run(tmp_path / "zz.parquet", run)
    out = tmp_path / "out"
    assert main(["identify", str(tmp_path / "zz.parquet"), "--out", str(out), "--samples", "400"]) == 0
    est = json.loads((out / "estimates.json").read_text())
    assert SPEC_KEYS <= set(est)
    assert est["algorithm"] == "srukf-ffm" and est["samples"] == 400
    assert list(est["parameters"]) == list(PARAM_NAMES)
    assert np.array(est["covariance"]).shape == (6, 6)
    assert set(est["indices"]) == {"K", "T1", "T2", "T3", "T"}
    # the loop's seconds are beside the result (timing.json), never in it: same bytes on a rerun
    assert est["timing"] == {"file": "timing.json"}
    timing = json.loads((out / est["timing"]["file"]).read_text())
    assert 0 < timing["seconds_per_step"] < timing["seconds_total"]
    assert est["run_id"] == "zz" and est["provenance"] == "virtual"
    direct = identify_run(run, FilterConfig(), samples=400)
    assert np.allclose(list(est["parameters"].values()), list(direct.parameters.values()))
    assert (out / "trace.parquet").exists()
    assert main(["identify", str(tmp_path / "zz.parquet"), "--out", str(out), "--algorithm", "ffm-ukf",
                 "--samples", "50"]) == 0
    assert json.loads((out / "estimates.json").read_text())["filterpy_failures"] == 0


def test_cli_refuses_bad_run_without_partial_output(tmp_path, capsys):
    run = synthetic.zigzag_run("bad", n=300, seed=3)
    run.frame.loc[120, "r"] = np.nan
    write_run(tmp_path / "bad.parquet", run)
    out = tmp_path / "out"
    assert main(["identify", str(tmp_path / "bad.parquet"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "row 121" in err and "'r'" in err
    assert not out.exists() or not any(out.iterdir())
    assert main(["identify", str(tmp_path / "missing.parquet"), "--out", str(out)]) == 2
    assert "not found" in capsys.readouterr().err
