"""The fit's analytic Jacobian (the sensitivities of the discrete RK4 solution, computed in the numba
kernel beside the simulation: pipeline.diagnose.extended._run_sens, fit.jacobian) is the derivative of
the output-error residuals: held here to central finite differences of the residual kernel, for every
form of every effect of the catalogue, all effects together, a run without sway, the training runs'
fitted starts (fit._JointStarts) and a lag both dropped and sub-stepped; and so is the prediction-error
start's (extended._pe_jac: pieces of one ship time scale from the measured states)."""

from __future__ import annotations

import dataclasses as dc
import json
import os
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from pipeline.diagnose import TruthConfig, zigzag_truth
from pipeline.diagnose.core import _context
from pipeline.diagnose.effects import CATALOGUE, REFERENCE, TRIAL
from pipeline.diagnose.fit import (
    Layout,
    _JointStarts,
    _kernel_map,
    _pe_residuals,
    _scales,
    jacobian,
    oe_batch,
    reference_speed,
    series_from_run,
    structure_of,
    with_initial_states,
)
from pipeline.model import PAPER_TABLE4


def _rng(layout) -> np.random.Generator:
    """The draws of one structure's test points, seeded by the structure itself: the same points
    whichever tests ran before in the same worker (a module-wide generator made them depend on the
    order the workers were handed the tests)."""
    return np.random.default_rng([42, zlib.crc32(repr(layout.structure).encode())])
#: central-difference step, relative to max(1, |p|): its truncation error (h^2 times the third
#: derivative; measured 1e-8 of a column at 1e-5 on the cross terms, falling as h^2) and its rounding
#: error (1e-16 / h of the residuals) both fall near 1e-10 of a column
REL_STEP = 1e-6
#: largest relative difference (column norm) allowed between the analytic and the central-difference
#: column.  Where a parameter's column comes by forward difference itself (a time input) or a feature
#: has a kink (|v|, |r|, the sign of the rudder angle), a sample crossing it within +-h moves a column
#: by about h / (the run's samples) relative: 1e-5 / 1000; 1e-5 leaves room for both and would still
#: catch a wrong partial derivative, which is off by the order of the column itself
TOL = 1e-5


@pytest.fixture(scope="module")
def setting():
    cfg = TruthConfig(seed=11, rudder_offset=1.0, speed_loss_k=0.2)
    runs = [zigzag_truth(a, a, side, 30.0, dc.replace(cfg, seed=11 + j))
            for j, (a, side) in enumerate([(20, "starboard"), (10, "port")])]
    series = [series_from_run(r) for r in runs]
    series[1] = dc.replace(series[1], v=None)
    series = with_initial_states(series, 2.0, box_sigma=2.0)
    ctx = _context(series)
    return series, ctx, _scales(series), reference_speed(series)


def _points(layout, batch, n=3):
    """Parameter vectors near the paper's ship with every effect present at a moderate size, inside the
    bounds, whose free runs follow the runs (every residual below 1, i.e. within a spread of the
    measured channel): a diverging trial model is so nonlinear in its parameters that the central
    differences themselves are off (measured: 7e-4 of a column at the step that gives 5e-9 elsewhere)."""
    lo, hi = layout.bounds()
    theta = np.array(list(PAPER_TABLE4.values()))
    rng = _rng(layout)
    out = []
    for _ in range(200):
        extra = []
        for a, b, name in zip(lo[6:], hi[6:], layout.names[6:], strict=True):
            span = 0.02 if not name.endswith("_s") else 0.5        # coefficients small, times in s
            extra.append(rng.uniform(max(a, -span), min(b, span)) if a < b else a)
        p = np.concatenate([theta * rng.uniform(0.8, 1.2, 6), extra])
        if np.max(np.abs(batch(p)[0])) < 1.0:
            out.append(p)
        if len(out) == n:
            return out
    raise AssertionError("no following trial model found")


def _central(f, p, lo, hi):
    cols = []
    for i in range(p.size):
        h = REL_STEP * max(1.0, abs(p[i]))
        a, b = max(p[i] - h, lo[i]), min(p[i] + h, hi[i])
        qa, qb = p.copy(), p.copy()
        qa[i], qb[i] = a, b
        cols.append((f(qb) - f(qa)) / (b - a))
    return np.column_stack(cols)


#: the same for a column the analytic Jacobian itself makes by a forward difference (a time input:
#: dead time, servo lag, speed exponent; fit.jacobian): its own truncation error, measured up to 2.0e-5
#: of the column at a following trial model of the all-effects structure (the speed exponent), where
#: a wrong partial derivative is off by the order of the column (0.1 % is caught:
#: test_a_wrong_partial_derivative_is_caught)
TOL_FD = 1e-4


def _check(ja, jn, names, fd=(), fine=None):
    """Every column of ``ja`` within TOL of the central differences ``jn`` (TOL_FD for the forward-
    difference columns ``fd``).  ``fine``: a callable giving the central differences at a tenth of the
    step, asked for a column that misses: a sample crossing a kink (|v|, |r|, the rudder's sign) within
    +-h moves the reference itself (measured: the rudder cubic's column 1.8e-5 off at h = 1e-6 of its
    value, 9e-12 at h/10), so the reference must have converged before it judges."""
    finer = None
    for i, n in enumerate(names):
        tol = TOL_FD if i in fd else TOL
        scale = max(np.linalg.norm(jn[:, i]), 1e-12)
        err = np.linalg.norm(ja[:, i] - jn[:, i]) / scale
        if not err < tol and fine is not None:
            finer = fine() if finer is None else finer
            err = np.linalg.norm(ja[:, i] - finer[:, i]) / max(np.linalg.norm(finer[:, i]), 1e-12)
        assert err < tol, (n, err)


def _central_fine(f, p, lo, hi):
    """:func:`_central` at a tenth of its step."""
    global REL_STEP
    saved, REL_STEP = REL_STEP, REL_STEP / 10.0
    try:
        return _central(f, p, lo, hi)
    finally:
        REL_STEP = saved


#: every form of every effect (the trial ones too), all the catalogue's effects together, and the
#: reference structure (the mixed hull terms with the rudder and speed effects)
STRUCTURES = [structure_of((e.name, f.name)) for e in CATALOGUE + TRIAL for f in e.forms] + [
    structure_of(*[(e.name, e.forms[-1].name) for e in CATALOGUE]), structure_of(*REFERENCE)
]


@pytest.mark.parametrize("st", STRUCTURES, ids=lambda st: "+".join(f"{e}:{f}" for e, f in st))
def test_analytic_jacobian_is_the_derivative_of_the_residuals(setting, st):
    series, ctx, sc, u_ref = setting
    layout = Layout(st, ctx)
    lo, hi = layout.bounds()
    batch = oe_batch(series, sc, layout, u_ref)
    for p in _points(layout, batch):
        res, jp = jacobian(batch, p, lo, hi)
        assert np.array_equal(res, batch(p)[0])          # the same residuals, bit for bit
        _check(jp, _central(lambda q: batch(q)[0], p, lo, hi), layout.names, _kernel_map(batch, p, lo, hi)[2],
               lambda p=p: _central_fine(lambda q: batch(q)[0], p, lo, hi))


def test_the_starts_columns_are_the_derivative_too(setting):
    """The polish's joint fit of each training run's start (r0 within its box): its z columns."""
    series, ctx, sc, u_ref = setting
    st = structure_of("rudder_offset", "nonlinear_yaw_damping", "heading_misalignment")
    layout = Layout(st, ctx)
    lo, hi = layout.bounds()
    batch = oe_batch(series, sc, layout, u_ref)
    joint = _JointStarts(series, len(layout.names), layout, sc, u_ref, batch, (lo, hi))
    assert len(joint.free) == 2                        # r0 of both runs
    jlo, jhi = joint.bounds(lo, hi)
    for p in _points(layout, batch, 2):
        pz = joint.extend(p, _rng(layout).uniform(-0.5, 0.5, len(joint.free)))
        names = layout.names + [f"z{k}" for k in range(len(joint.free))]
        _check(joint.fun_jac(pz)[1], _central(joint, pz, jlo, jhi), names)


@pytest.mark.parametrize("lag_s", [0.001, 0.03, 0.6])
def test_a_servo_lag_dropped_or_substepped(setting, lag_s):
    """A lag below h/20 is taken as none, one below h/2 needs RK4 sub-steps: the sensitivities run the
    same sub-steps (the lag's own column is a forward difference).  0.03 s, not 0.02: at h/(2 lag) = 2
    exactly the sub-step count changes, and the residuals jump with it."""
    series, ctx, sc, u_ref = setting
    layout = Layout(structure_of("rudder_lag", "rudder_offset"), ctx)
    lo, hi = layout.bounds()
    batch = oe_batch(series, sc, layout, u_ref)
    p = _points(layout, batch, 1)[0]
    p[layout.names.index("lag_s")] = lag_s
    _, jp = jacobian(batch, p, lo, hi)
    _check(jp, _central(lambda q: batch(q)[0], p, lo, hi), layout.names)


def test_a_wrong_partial_derivative_is_caught(setting, monkeypatch):
    """The check can fail: the offset's column scaled by 1.001 is refused."""
    import pipeline.diagnose.fit as fit

    series, ctx, sc, u_ref = setting
    layout = Layout(structure_of("rudder_offset"), ctx)
    lo, hi = layout.bounds()
    batch = oe_batch(series, sc, layout, u_ref)
    p = _points(layout, batch, 1)[0]
    _, jp = fit.jacobian(batch, p, lo, hi)
    jp[:, layout.names.index("offset_deg")] *= 1.001
    with pytest.raises(AssertionError, match="offset_deg"):
        _check(jp, _central(lambda q: batch(q)[0], p, lo, hi), layout.names)


@pytest.mark.parametrize("run", [0, 1], ids=["with sway", "without sway"])
def test_the_held_out_start_jacobian_is_the_derivative_too(setting, run):
    """boxed_initial_state's problem (its residuals in blocks psi, r, v, along the free start states):
    the residuals are the free run's minus the measured, times 1/spread, and the Jacobian from the
    kernel's sensitivities their derivative, for a fitted extended model, with and without a sway
    channel."""
    from pipeline.diagnose.fit import _start_problem, fit_structure, simulate_terms

    series, ctx, *_ = setting
    fit = fit_structure(series, structure_of("rudder_offset", "nonlinear_yaw_damping"), ctx, max_nfev=20)
    s = series[run]
    x = np.array(s.x0, dtype=float)
    free = [0, 1] if s.v is not None else [1]
    w = np.array([1.0 / np.std(s.v) if s.v is not None else 0.0, 1.0 / np.std(s.r), 1.0 / np.std(s.psi)])
    ur = None if fit.u_ref is None else s.u_smooth() / fit.u_ref

    def resid(z):
        q = x.copy()
        q[free] = z
        sim = simulate_terms(fit.theta, fit.terms, q, s.t, s.delta, ur)
        out = [(sim[:, 2] - s.psi) * w[2], (sim[:, 1] - s.r) * w[1]]
        return np.concatenate(out + ([(sim[:, 0] - s.v) * w[0]] if s.v is not None else []))

    z = x[free] + 0.01
    big = np.full(len(free), np.inf)
    res, jac = _start_problem(fit, s, x, free, w)(z)
    assert np.allclose(res, resid(z), rtol=1e-12, atol=1e-12)
    _check(jac, _central(resid, z, -big, big), [f"x{i}" for i in free])


def _exp_fit(x, *, bad_jacobian=False, bad_residuals=False, huge_jacobian=False):
    """Residuals exp(a t) - exp(2 t) + c on t in [0, 1] (zero at a = 2, c = 0) and their Jacobian,
    either made non-finite on demand."""
    t = np.linspace(0.0, 1.0, 50)
    f = np.exp(x[0] * t) - np.exp(2.0 * t) + x[1]
    jx = np.stack([t * np.exp(x[0] * t), np.ones_like(t)], axis=1)
    if huge_jacobian:                       # finite, but its squares overflow
        jx = jx * 1e200
    return (f * np.nan if bad_residuals else f), (jx * np.nan if bad_jacobian else jx)


def test_compressed_least_squares_survives_an_overflowed_jacobian_and_refuses_a_bad_start():
    """Sensitivities that overflow where the residuals are finite (a nearly diverging free run) fall
    back to a forward difference (as do finite ones whose squares overflow), so the fit reaches the
    same optimum; a start whose residuals are
    not finite gets SciPy's own error, not a lookup failure."""
    from pipeline.diagnose.fit import _compressed_lsq

    lo, hi, x0 = np.array([-5.0, -5.0]), np.array([5.0, 5.0]), np.zeros(2)
    exact = _compressed_lsq(_exp_fit, x0, lo, hi, 200)
    fallback = _compressed_lsq(lambda x: _exp_fit(x, bad_jacobian=True), x0, lo, hi, 200)
    assert exact.x == pytest.approx([2.0, 0.0], abs=1e-6)
    assert fallback.x == pytest.approx(exact.x, abs=1e-6)
    huge = _compressed_lsq(lambda x: _exp_fit(x, huge_jacobian=True), x0, lo, hi, 200)
    assert huge.x == pytest.approx(exact.x, abs=1e-6)
    assert np.all(np.isfinite(huge.jac)) and np.abs(huge.jac).max() < 1e3
    with pytest.raises(ValueError, match="not finite in the initial point"):
        _compressed_lsq(lambda x: _exp_fit(x, bad_residuals=True), x0, lo, hi, 200)


@pytest.fixture(scope="module")
def sway_setting(setting):
    """The setting's runs with sway measured in both (the prediction-error pieces' Jacobian is made only
    where every run has it: fit._fit_from) and the fit's horizon, one ship time scale in samples."""
    cfg = TruthConfig(seed=11, rudder_offset=1.0, speed_loss_k=0.2)
    runs = [zigzag_truth(a, a, side, 30.0, dc.replace(cfg, seed=11 + j))
            for j, (a, side) in enumerate([(20, "starboard"), (10, "port")])]
    series = with_initial_states([series_from_run(r) for r in runs], 2.0, box_sigma=2.0)
    ctx = _context(series)
    horizon = max(10, int(round(ctx.t_ship / series[0].h)))
    return series, ctx, _scales(series), reference_speed(series), horizon


def _pe(series, sc, u_ref, layout, horizon):
    def f(q):
        th, tm, _ = layout.unpack(q)
        return _pe_residuals(series, sc, th, tm, u_ref, horizon)
    return f


@pytest.mark.parametrize("st", STRUCTURES, ids=lambda st: "+".join(f"{e}:{f}" for e, f in st))
def test_prediction_error_jacobian_is_the_derivative_of_its_residuals(sway_setting, st):
    """The prediction-error start's residuals from the kernel are fit._pe_residuals's bits, and their
    Jacobian the derivative of them (pieces from measured states: no start column)."""
    series, ctx, sc, u_ref, horizon = sway_setting
    layout = Layout(st, ctx)
    lo, hi = layout.bounds()
    batch = oe_batch(series, sc, layout, u_ref)
    pieces = batch.pe_layout(horizon)
    assert pieces is not None and 0 < horizon < series[0].t.size
    f = _pe(series, sc, u_ref, layout, horizon)
    for p in _points(layout, batch, 2):
        res, jp = jacobian(batch, p, lo, hi, pieces=pieces)
        assert np.array_equal(res, f(p))
        _check(jp, _central(f, p, lo, hi), layout.names, _kernel_map(batch, p, lo, hi)[2],
               lambda p=p: _central_fine(f, p, lo, hi))


@pytest.mark.parametrize("lag_s", [0.03, 0.6])
def test_prediction_error_pieces_with_a_servo_lag(sway_setting, lag_s):
    """A lag's pieces restart from the servo's own lag state (extended._lag_history), sub-stepped below
    h/2: the residuals are fit._pe_residuals's, the Jacobian its derivative."""
    series, ctx, sc, u_ref, horizon = sway_setting
    layout = Layout(structure_of("rudder_lag", "rudder_offset"), ctx)
    lo, hi = layout.bounds()
    batch = oe_batch(series, sc, layout, u_ref)
    p = _points(layout, batch, 1)[0]
    p[layout.names.index("lag_s")] = lag_s
    f = _pe(series, sc, u_ref, layout, horizon)
    res, jp = jacobian(batch, p, lo, hi, pieces=batch.pe_layout(horizon))
    assert np.array_equal(res, f(p))
    _check(jp, _central(f, p, lo, hi), layout.names)


def test_no_prediction_error_jacobian_without_sway(setting):
    """A run without sway starts its pieces from the model's own free-run v, which the kernel's pieces do
    not: no layout, and the fit keeps finite differences there (fit._fit_from)."""
    series, ctx, sc, u_ref = setting
    layout = Layout(structure_of("rudder_offset"), ctx)
    batch = oe_batch(series, sc, layout, u_ref)
    assert series[1].v is None and batch.pe_layout(20) is None
    assert oe_batch(series[:1], sc, layout, u_ref).pe_layout(20) is not None
    with pytest.raises(ValueError, match="no x0 or starts"):
        lo, hi = layout.bounds()
        jacobian(oe_batch(series[:1], sc, layout, u_ref), _points(layout, batch, 1)[0], lo, hi,
                 x0=series[0].x0[None], pieces=np.zeros((2, 3), dtype=np.int64))


def test_each_kernel_is_compiled_for_one_signature():
    """Every way the fits call the kernels (tests/kernel_signatures.py, in a fresh interpreter: one or
    several parameter rows, given starts, a Jacobian of one column or several in either memory order,
    the prediction-error pieces with and without sensitivities, a short diagnosis; the identification's
    filter on writable and read-only arrays, serially and on numba's threads) needs one compiled
    signature per kernel: each further one is compiled apart (in a fresh tree, about 15-20 s CPU for
    _run or _run_sens alone, 30 s for the filter's batch range, in every process that meets it first;
    docs/performance.md, "Compile time").  With a warm cache the kernels called from Python are the
    ones checked; in a fresh tree (CI) those they call as well."""
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run([sys.executable, str(root / "tests" / "kernel_signatures.py")], cwd=root,
                          capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(root)},
                          timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    held = json.loads(done.stdout.strip().splitlines()[-1])
    used = {"extended._oe_batch", "extended._oe_jac", "extended._pe_jac", "extended._run",
            "fast.srukf_kernel", "fast.srukf_batch_kernel", "fast.srukf_batch_kernel_parallel"}
    assert used <= {k for k, v in held.items() if v}, held
    assert all(len(v) <= 1 for v in held.values()), {k: v for k, v in held.items() if len(v) > 1}


@pytest.mark.parametrize("m,n", [(3000, 10), (2500, 16), (7, 7), (500, 1), (4, 6)])
def test_qr_projection_is_scipys_bit_for_bit(m, n):
    """fit._qr_project (LAPACK's geqrf and ormqr called directly, the work lengths asked once per
    shape) gives scipy.linalg.qr_multiply(a, f, mode="right")'s numbers bit for bit, for columns of
    very different scales, a second call of a shape (the lengths from the cache) and a wide matrix."""
    from scipy.linalg import qr_multiply

    from pipeline.diagnose.fit import _qr_project

    rng = np.random.default_rng([m, n])
    for _ in range(2):
        a = rng.normal(size=(m, n)) * rng.uniform(0.1, 1e3, n)
        f = rng.normal(size=m)
        want = qr_multiply(np.asfortranarray(a), f, mode="right")
        got = _qr_project(np.asfortranarray(a), f)
        assert all(np.array_equal(w, g) for w, g in zip(want, got, strict=True))
        assert got[0].shape == (min(m, n),) and got[1].shape == (min(m, n), n)
