"""The equations of motion are defined once (pipeline.model.rhs); every copy is held to it here."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import cont2discrete

from pipeline.model import PAPER_TABLE4, rhs, simulate, simulate_zoh, state_matrices, step

RNG = np.random.default_rng(2024)


def _random_params(n):
    base = np.array(list(PAPER_TABLE4.values()))
    return base * RNG.uniform(0.5, 1.5, (n, 6))


def test_step_is_the_euler_step_of_rhs():
    for theta in _random_params(20):
        x = RNG.normal(0, [0.1, 2.0, 30.0])
        d = RNG.uniform(-35, 35)
        np.testing.assert_allclose(step(x, d, theta, 0.08), x + 0.08 * rhs(x, d, theta), rtol=0, atol=1e-14)


def test_simulate_is_repeated_step():
    theta = _random_params(1)[0]
    d = RNG.uniform(-20, 20, 200)
    sim = simulate(theta, (0.01, -0.5, 3.0), d, 0.08)
    x = np.array([0.01, -0.5, 3.0])
    for k in range(199):
        x = step(x, d[k], theta, 0.08)
        np.testing.assert_allclose(sim[k + 1], x, rtol=1e-12, atol=1e-12)


def test_zoh_matches_scipy_cont2discrete():
    theta = _random_params(1)[0]
    A, B = state_matrices(theta)
    Ad, Bd, *_ = cont2discrete((A, B[:, None], np.eye(3), np.zeros((3, 1))), 0.08, method="zoh")
    d = RNG.uniform(-20, 20, 300)
    sim = simulate_zoh(theta, (0.0, 0.0, 0.0), d, 0.08)
    x = np.zeros(3)
    for k in range(299):
        x = Ad @ x + Bd[:, 0] * d[k]
    np.testing.assert_allclose(sim[-1], x, rtol=1e-10, atol=1e-10)


def test_diagnosis_kernel_copy_is_rhs_with_null_effects():
    from pipeline.diagnose.effects import Terms
    from pipeline.diagnose.extended import deriv

    for theta in _random_params(20):
        x = RNG.normal(0, [0.1, 2.0, 30.0])
        d = RNG.uniform(-35, 35)
        got = deriv(x, 0.0, d, 1.0, theta, Terms())[:3]
        np.testing.assert_allclose(got, rhs(x, d, theta), rtol=1e-13, atol=1e-13)


def test_diagnosis_rk4_matches_exact_first_order_hold():
    """The diagnosis integrates with RK4 and the rudder linearly interpolated: against the exact
    first-order-hold solution of rhs (scipy cont2discrete 'foh'), its error is below 1e-4 of the
    response, far under any effect (or sensor noise) the diagnosis judges."""
    from pipeline.diagnose.extended import simulate_extended

    theta = np.array(list(PAPER_TABLE4.values()))
    t = np.arange(1500) * 0.08
    d = np.clip(20 * np.sin(t / 4.0) * 3, -20, 20)
    sim = simulate_extended(theta, (0.0, 0.0, 0.0), d, 0.08)
    A, B = state_matrices(theta)
    Ad, Bd, C, D, _ = cont2discrete((A, B[:, None], np.eye(3), np.zeros((3, 1))), 0.08, method="foh")
    # foh state-space form: xi(k+1) = Ad xi + Bd u(k), y = C xi + D u
    xi = np.zeros(3) - D[:, 0] * d[0]
    ys = []
    for k in range(t.size):
        ys.append(C @ xi + D[:, 0] * d[k])
        xi = Ad @ xi + Bd[:, 0] * d[k]
    ys = np.array(ys)
    scale = np.abs(ys).max(axis=0)
    assert np.max(np.abs(sim - ys) / scale) < 1e-4


def test_identify_numba_transition_is_model_step():
    """pipeline.identify.fast._fx (numba, sigma points with the parameters in the state) is the
    model's step."""
    from pipeline.identify.fast import _fx

    X = np.empty((9, 7))
    X[:3] = RNG.normal(0, [[0.1], [2.0], [30.0]], (3, 7))
    X[3:] = _random_params(7).T
    out = np.empty_like(X)
    _fx(X, 7, 12.5, 0.08, out)
    for i in range(7):
        np.testing.assert_allclose(out[:3, i], step(X[:3, i], 12.5, X[3:, i], 0.08), rtol=1e-13, atol=1e-13)
        np.testing.assert_array_equal(out[3:, i], X[3:, i])


@pytest.mark.parametrize("where", ["srukf", "baseline"])
def test_identify_python_transitions_are_model_step(where):
    if where == "srukf":
        from pipeline.identify.srukf import model_fx as fx

        def call(x):
            return fx(x[:, None], -7.0, 0.08)[:, 0]
    else:
        from pipeline.identify.baseline import _fx as fx

        def call(x):
            return fx(x, 0.08, -7.0)

    for theta in _random_params(10):
        x = np.concatenate([RNG.normal(0, [0.1, 2.0, 30.0]), theta])
        np.testing.assert_allclose(call(x)[:3], step(x[:3], -7.0, theta, 0.08), rtol=1e-13, atol=1e-13)


def _diag_series():
    """Two short truth runs (a 20/20 and a 10/10 zigzag, surge speed logged) as diagnosis series; the
    second without a sway channel (v None: its residual block has no v rows)."""
    import dataclasses as dc

    from pipeline.diagnose import TruthConfig, zigzag_truth
    from pipeline.diagnose.fit import series_from_run

    cfg = TruthConfig(seed=11, rudder_offset=1.0, speed_loss_k=0.2)
    runs = [zigzag_truth(a, a, side, 30.0, dc.replace(cfg, seed=11 + j)) for j, (a, side) in enumerate(
        [(20, "starboard"), (10, "port")]
    )]
    series = [series_from_run(r) for r in runs]
    series[1] = dc.replace(series[1], v=None)
    return series


@pytest.mark.parametrize("which", ["each form alone", "every effect together"])
def test_diagnosis_batch_kernel_is_the_free_run_residual_bit_for_bit(which):
    """The fit's batched residual kernel (extended._oe_batch via fit.oe_batch, one call for every
    finite-difference column) gives exactly the bits of the one-by-one free-run residuals
    (fit._oe_residuals: extended.simulate_terms, itself held to rhs above), for every effect form,
    a lag small enough to be dropped and one needing RK4 sub-steps, a run without sway."""
    from pipeline.diagnose.core import _context
    from pipeline.diagnose.effects import CATALOGUE
    from pipeline.diagnose.fit import Layout, _oe_residuals, _scales, oe_batch, reference_speed, structure_of

    series = _diag_series()
    ctx = _context(series)
    sc, u_ref = _scales(series), reference_speed(series)
    if which == "each form alone":
        structures = [structure_of((e.name, f.name)) for e in CATALOGUE for f in e.forms]
    else:
        structures = [structure_of(*[(e.name, e.forms[-1].name) for e in CATALOGUE])]
    for st in structures:
        layout = Layout(st, ctx)
        lo, hi = layout.bounds()
        theta = np.array(list(PAPER_TABLE4.values()))
        P = []
        for _ in range(4):
            extra = [RNG.uniform(max(a, -0.5), min(b, 0.5)) for a, b in zip(lo[6:], hi[6:], strict=True)]
            P.append(np.concatenate([theta * RNG.uniform(0.7, 1.3, 6), extra]))
        for i, n in enumerate(layout.names):
            if n == "lag_s":  # one below h/20 (taken as none), one needing sub-steps (< h/2)
                P[0][i], P[1][i] = 0.001, 0.02
        P = np.array(P)
        got = oe_batch(series, sc, layout, u_ref)(P)
        for p, row in zip(P, got, strict=True):
            th, terms, _ = layout.unpack(p)
            want = _oe_residuals(series, sc, th, terms, u_ref)
            assert np.array_equal(row, want), (st, np.max(np.abs(row - want)))


@pytest.mark.parametrize("lag_s", [0.0, 0.9, 0.02])
def test_diagnosis_segments_restart_the_free_run_exactly(lag_s):
    """predict_segments from a free run's own states at any sample reproduces that free run bit for bit,
    servo lag included: the lag state at a restart is the servo's own (it depends on the logged rudder
    alone), not the logged rudder.  With the rudder there, a 0.9 s lag's restarts are a rudder swing
    off (the check fails by degrees)."""
    from pipeline.diagnose.effects.base import Terms
    from pipeline.diagnose.extended import predict_segments, simulate_terms

    th = [-0.5, -0.3, -2.0, -1.0, 0.02, -0.4]
    t = np.arange(0.0, 60.0, 0.08)
    d = 10.0 * np.sign(np.sin(t / 5.0))
    terms = Terms(lag_s=lag_s, delay_s=0.3)
    x = simulate_terms(th, terms, [0.0, 0.0, 0.0], t, d)
    starts = np.arange(0, t.size - 50, 37)
    seg = predict_segments(th, terms, x, t, d, starts, 50)
    for i, k in enumerate(starts):
        assert np.array_equal(seg[i], x[k:k + 50]), (lag_s, k)
