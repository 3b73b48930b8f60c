"""The extended sway-yaw model in continuous time and its simulation without error of its own.

Right-hand side (units of docs/contract.md#the-identification-model: v m/s, r deg/s, psi deg, delta deg, t s,
u m/s):

    a(t)     = delta(t - delay_s)                          logged rudder, linearly interpolated
    e        = lag state (lag_s de/dt = a - e) if lag_s > 0, else a
    g        = (e + offset_deg) (1 + asym sign(.)) + cubic (e + offset_deg)^3     rudder force angle
    s        = (u / U_ref)^speed_exponent                  (ones without speed_loss)
    dv/dt    = s (a11 v + a12 r) + s^2 b11 g + sum_j c_j f_j(v, r, s)   over feature terms of dv/dt
    dr/dt    = s (a21 v + a22 r) + s^2 b21 g + sum_j c_j f_j(v, r, s)   over feature terms of dr/dt
    dpsi/dt  = r
    v read   = v + v_bias_m_s q,  q = u / U_ref (ones without u)   the sway velocity a run gives

The last line is a reading, not a force (a sensor effect, e.g. a heading reference set off the
centreline, through which a file's earth-fixed velocities become a sway velocity biased by
-u sin(misalignment)): the state integrated is the ship's, while every initial state given to and
every sway velocity returned by the functions here is a reading; with v_bias_m_s = 0 both are the
same numbers, bit for bit.

With every effect at its null value this is :func:`pipeline.model.rhs` (tests hold the kernel's copy
to it).  Integration: classical RK4 at the sample step (``substeps`` per step when asked), the rudder
and the speed factor taken at the step's start, middle and end from the logged series (linear
interpolation).  The baseline uses the same integrator with no effect, so that an effect never
"explains" a difference of integration: an exact zero-order-hold baseline (rudder held over the
step) would differ from this interpolating one by a half-step rudder delay, which a dead time would
then fit.  The RK4 error against the exact first-order-hold solution is held below 1e-4 of the
response by tests/test_model_definition.py.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from pipeline.diagnose.effects.base import Terms
from pipeline.errors import ModelError
from pipeline.model import as_theta

_CLIP_R = 500.0  # deg/s: a diverging trial model is clipped here so residuals stay finite
_CLIP_V = 100.0  # m/s
_CLIP_D = 1000.0  # deg, lag state

#: The rudder block: every effect on the rudder force angle, the servo and the sway reading reaches the
#: kernels as ONE float64 vector read by these indices (:func:`rudder_block` fills it from
#: :class:`~pipeline.diagnose.effects.base.Terms`; docs/performance.md, "The kernels' parameters").
#: A new rudder effect is an index here, its line in :func:`rudder_block` and its use in
#: :func:`_deriv_at` (with its partial derivatives there), never a new kernel argument.
#: B_OFFSET deg, B_ASYM dimensionless, B_CUBIC 1/deg^2, B_LAG s (the lag as integrated: 0 below h/20,
#: :func:`_lag_and_substeps`), B_VBIAS m/s (the sway reading's bias at U_ref).
B_OFFSET, B_ASYM, B_CUBIC, B_LAG, B_VBIAS = 0, 1, 2, 3, 4
BLOCK_SIZE = 5


# _feature and _feature_grad are left to LLVM to inline: numba's own inlining ("always") of them into
# the four RK4 stages of _deriv_at made _run and _run_sens take 43 s CPU to compile in a fresh tree
# against 25 s, for the same run time and the same bits (docs/performance.md, "Compile time")
@njit(cache=True)
def _feature(code, v, r, s=1.0):  # pragma: no cover - compiled; held to effects.base.feature_value
    if code == 0:
        return r * r * r
    if code == 1:
        return r * abs(r)
    if code == 2:
        return v * abs(v)
    if code == 3:
        return v * v * r
    if code == 4:
        return v * r * r
    if code == 5:
        return v * abs(r)
    if code == 6:
        return abs(v) * r
    if code == 8:
        return v * v * r / s
    if code == 9:
        return v * r * r / s
    if code == 10:
        return r * r * r / s
    return v * v * v


@njit(cache=True, inline="always")
def _deriv_at(v, r, e, a_in, s, th, codes, eqs, coefs, blk, tab, amat, i, sens):  # pragma: no cover
    """(dv/dt, dr/dt, dpsi/dt, de/dt) of the extended model (module docstring); ``blk``: the rudder
    block (B_* indices).  With ``sens``, also its partial derivatives at this state, as stage ``i``
    of an RK4 step: amat[i] = (d(dv/dt)/dv, d(dv/dt)/dr, d(dr/dt)/dv, d(dr/dt)/dr), tab[i] (2, slots)
    the direct partial derivatives of (dv/dt, dr/dt) along each kernel parameter (theta, feature
    coefficients, then :data:`S_OFFSET`... from 6 + nf; the last slot stays zero: a start's, the sway
    bias's), from the same feature values; a column's stage derivative is then dk = A S + B
    (:func:`_run_sens`).  Without ``sens`` tab and amat are not touched."""
    lag = blk[B_LAG]
    ang = (e if lag > 0.0 else a_in) + blk[B_OFFSET]
    sg = 1.0 if ang > 0.0 else (-1.0 if ang < 0.0 else 0.0)
    g = ang * (1.0 + blk[B_ASYM] * sg) + blk[B_CUBIC] * ang * ang * ang
    dv = s * (th[0] * v + th[1] * r) + s * s * th[4] * g
    dr = s * (th[2] * v + th[3] * r) + s * s * th[5] * g
    avv, avr, arv, arr = 0.0, 0.0, 0.0, 0.0
    if sens:
        avv, avr = s * th[0], s * th[1]
        arv, arr = s * th[2], s * th[3]
    for j in range(codes.shape[0]):
        fe = _feature(codes[j], v, r, s)
        f = coefs[j] * fe
        if eqs[j] == 0:
            dv += f
        else:
            dr += f
        if sens:
            fv, fr = _feature_grad(codes[j], v, r, s)
            if eqs[j] == 0:
                avv += coefs[j] * fv
                avr += coefs[j] * fr
                tab[i, 0, 6 + j] = fe
            else:
                arv += coefs[j] * fv
                arr += coefs[j] * fr
                tab[i, 1, 6 + j] = fe
    if sens:
        asym, cubic = blk[B_ASYM], blk[B_CUBIC]
        a3 = ang * ang * ang
        # g as the sensitivities have always had it: cubic * (ang^3), not (cubic * ang) * ang * ang as
        # in dv above; the two differ in the last bit, and the Jacobian keeps its own bits
        gs = ang * (1.0 + asym * sg) + cubic * a3
        tab[i, 0, 0], tab[i, 0, 1], tab[i, 1, 2], tab[i, 1, 3] = s * v, s * r, s * v, s * r
        tab[i, 0, 4], tab[i, 1, 5] = s * s * gs, s * s * gs
        o = 6 + codes.shape[0]
        gv, gr = s * s * th[4], s * s * th[5]
        dg = 1.0 + asym * sg + 3.0 * cubic * ang * ang
        tab[i, 0, o + S_OFFSET], tab[i, 1, o + S_OFFSET] = gv * dg, gr * dg
        tab[i, 0, o + S_ASYM], tab[i, 1, o + S_ASYM] = gv * ang * sg, gr * ang * sg
        tab[i, 0, o + S_CUBIC], tab[i, 1, o + S_CUBIC] = gv * a3, gr * a3
        amat[i, 0], amat[i, 1], amat[i, 2], amat[i, 3] = avv, avr, arv, arr
    de = (a_in - e) / lag if lag > 0.0 else 0.0
    return dv, dr, r, de


@njit(cache=True)
def _deriv(v, r, e, a_in, s, th, codes, eqs, coefs, blk):  # pragma: no cover
    """(dv/dt, dr/dt, dpsi/dt, de/dt) of the extended model: :func:`_deriv_at` without sensitivities."""
    return _deriv_at(v, r, e, a_in, s, th, codes, eqs, coefs, blk, np.empty((1, 2, 1)), np.empty((1, 4)), 0,
                     False)


@njit(cache=True, inline="always")
def _stage_inputs(x_half, i0, j, m):  # pragma: no cover
    """An input on the half-step grid at RK4 sub-step j of m of the step from index i0 = 2k: its values
    at the sub-step's start, middle and end, by linear interpolation (the logged midpoint when m = 1)."""
    x0 = x_half[i0] + (j / m) * (x_half[i0 + 2] - x_half[i0])
    x1 = x_half[i0 + 1] if m == 1 else x_half[i0] + ((j + 0.5) / m) * (x_half[i0 + 2] - x_half[i0])
    x2 = x_half[i0] + ((j + 1.0) / m) * (x_half[i0 + 2] - x_half[i0])
    return x0, x1, x2


@njit(cache=True, inline="always")
def _rk4_step(v, r, psi, e, a0, a1, a2, q0, q1, q2, hs, th, codes, eqs, coefs, blk, tab, amat,
              sens):  # pragma: no cover
    """One classical RK4 step of ``hs`` s of the state (v, r, psi, lag state e), the rudder ``a`` and
    speed factor ``q`` at the step's start, middle and end: (v, r, psi, e after it; the stage
    derivatives k1, k2, k3 of v, r, e that made it; whether the heading increment was clipped).  A
    diverging trial model: the RK4 stages themselves can explode (r^3 of a clipped r), so the heading
    increment and the lag state are clipped as well as v and r (residuals stay finite and large).
    With ``sens``, the four stages' partial derivatives go to tab[0..3], amat[0..3] (:func:`_deriv_at`)."""
    k1v, k1r, k1p, k1e = _deriv_at(v, r, e, a0, q0, th, codes, eqs, coefs, blk, tab, amat, 0, sens)
    k2v, k2r, k2p, k2e = _deriv_at(v + 0.5 * hs * k1v, r + 0.5 * hs * k1r, e + 0.5 * hs * k1e,
                                   a1, q1, th, codes, eqs, coefs, blk, tab, amat, 1, sens)
    k3v, k3r, k3p, k3e = _deriv_at(v + 0.5 * hs * k2v, r + 0.5 * hs * k2r, e + 0.5 * hs * k2e,
                                   a1, q1, th, codes, eqs, coefs, blk, tab, amat, 2, sens)
    k4v, k4r, k4p, k4e = _deriv_at(v + hs * k3v, r + hs * k3r, e + hs * k3e,
                                   a2, q2, th, codes, eqs, coefs, blk, tab, amat, 3, sens)
    v = v + hs / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
    r = r + hs / 6.0 * (k1r + 2.0 * k2r + 2.0 * k3r + k4r)
    dpsi = hs / 6.0 * (k1p + 2.0 * k2p + 2.0 * k3p + k4p)
    clip_psi = not (abs(dpsi) < _CLIP_R * hs)
    if clip_psi:
        dpsi = _CLIP_R * hs if dpsi > 0 else -_CLIP_R * hs
    psi = psi + dpsi
    e = e + hs / 6.0 * (k1e + 2.0 * k2e + 2.0 * k3e + k4e)
    if not (abs(e) < _CLIP_D):
        e = _CLIP_D if e > 0 else -_CLIP_D
    if not (abs(v) < _CLIP_V):
        v = _CLIP_V if v > 0 else -_CLIP_V
    if not (abs(r) < _CLIP_R):
        r = _CLIP_R if r > 0 else -_CLIP_R
    return v, r, psi, e, k1v, k1r, k1e, k2v, k2r, k2e, k3v, k3r, k3e, clip_psi


@njit(cache=True)
def _run(out, k0, k1, x0, e0, a_half, s_half, h, m, th, codes, eqs, coefs, blk):  # pragma: no cover
    """RK4 from sample k0 (state x0, lag state e0) to k1 - 1, writing samples k0 .. k1-1 to rows
    0 .. k1-k0-1 of ``out``.
    ``a_half``/``s_half``: rudder (pre-lag) and speed factor on the half-step grid (index 2k = t_k)."""
    v, r, psi, e = x0[0], x0[1], x0[2], e0
    hs = h / m
    tab, amat = np.empty((1, 2, 1)), np.empty((1, 4))      # untouched: no sensitivities here
    for k in range(k0, k1):
        out[k - k0, 0] = v
        out[k - k0, 1] = r
        out[k - k0, 2] = psi
        if k == k1 - 1:
            break
        for j in range(m):
            a0, a1, a2 = _stage_inputs(a_half, 2 * k, j, m)
            s0, s1, s2 = _stage_inputs(s_half, 2 * k, j, m)
            step = _rk4_step(v, r, psi, e, a0, a1, a2, s0, s1, s2, hs, th, codes, eqs, coefs, blk, tab, amat,
                             False)
            v, r, psi, e = step[0], step[1], step[2], step[3]


@njit(cache=True)
def _lag_history(a_half, h, m, lag):  # pragma: no cover
    """The servo's lag state e at every sample of a free run from e = a at the first sample: the same
    RK4 stages as :func:`_run` (de/dt = (a - e) / lag depends on the rudder alone, so it is exactly the
    lag state of every free run from the run's start).  Without a lag, the rudder itself."""
    n = (a_half.shape[0] + 1) // 2
    e_out = np.empty(n)
    e = a_half[0]
    hs = h / m
    for k in range(n):
        e_out[k] = e if lag > 0.0 else a_half[2 * k]
        if k == n - 1 or lag <= 0.0:
            continue
        for j in range(m):
            a0, a1, a2 = _stage_inputs(a_half, 2 * k, j, m)
            k1 = (a0 - e) / lag
            k2 = (a1 - (e + 0.5 * hs * k1)) / lag
            k3 = (a1 - (e + 0.5 * hs * k2)) / lag
            k4 = (a2 - (e + hs * k3)) / lag
            e = e + hs / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return e_out


@njit(cache=True)
def _segments(out, starts, length, xs, a_half, s_half, h, m, th, codes, eqs, coefs, blk):  # pragma: no cover
    """Prediction over ``length`` samples from each measured state xs[starts[i]] (rows of out[i]); the
    lag state at each start is the servo's own from the run's start (:func:`_lag_history`)."""
    e_hist = _lag_history(a_half, h, m, blk[B_LAG])
    for i in range(starts.shape[0]):
        k0 = starts[i]
        _run(out[i], k0, k0 + length, xs[k0], e_hist[k0], a_half, s_half, h, m, th, codes, eqs, coefs, blk)


def rudder_block(terms: Terms, lag_s: float | None = None) -> np.ndarray:
    """The rudder block (B_* indices) of ``terms``; ``lag_s``: the lag as integrated (s,
    :func:`_lag_and_substeps`), default ``terms.lag_s``."""
    blk = np.empty(BLOCK_SIZE)
    blk[B_OFFSET] = float(terms.offset_deg)
    blk[B_ASYM] = float(terms.asymmetry)
    blk[B_CUBIC] = float(terms.rudder_cubic_per_deg2)
    blk[B_LAG] = float(terms.lag_s if lag_s is None else lag_s)
    blk[B_VBIAS] = float(terms.v_bias_m_s)
    return blk


def deriv(x, e, a_in, s, theta, terms: Terms) -> np.ndarray:
    """Python entry to the kernel's right-hand side: (dv/dt, dr/dt, dpsi/dt, de/dt) at state x =
    (v m/s, r deg/s, psi deg), lag state ``e`` deg, pre-lag rudder ``a_in`` deg and speed factor ``s``
    (for tests)."""
    codes, eqs, coefs = _arrays(terms)
    return np.array(
        _deriv(float(x[0]), float(x[1]), float(e), float(a_in), float(s), as_theta(theta), codes, eqs, coefs,
               rudder_block(terms))
    )


def _lag_and_substeps(terms: Terms, h: float, substeps: int) -> tuple[float, int]:
    """The servo lag as integrated, and the RK4 sub-steps: a lag below h/20 is invisible at the sample
    step and is taken as none; otherwise sub-steps of at most 2 lag_s keep explicit RK4 stable on the
    lag state (RK4 is stable for step/lag < 2.78)."""
    lag = float(terms.lag_s)
    if lag < h / 20.0:
        return 0.0, int(substeps)
    return lag, max(int(substeps), int(np.ceil(h / (2.0 * lag))))


def _arrays(terms: Terms):
    return (
        np.asarray(terms.feat_code, dtype=np.int64),
        np.asarray(terms.feat_eq, dtype=np.int64),
        np.asarray(terms.feat_coef, dtype=float),
    )


_HALF_CACHE: dict = {}


def half_grid(t: np.ndarray, y: np.ndarray, shift: float = 0.0) -> np.ndarray:
    """Cached :func:`_half_grid` (the fit simulates the same logged rudder thousands of times): keyed on
    the arrays' identity and contents' first/last values, their length and the shift."""
    key = (id(t), id(y), len(t), float(t[0]), float(y[0]), float(y[-1]), float(shift))
    hit = _HALF_CACHE.get(key)
    if hit is not None and hit[0] is t and hit[1] is y:
        return hit[2]
    out = _half_grid(t, y, shift)
    if len(_HALF_CACHE) > 256:
        _HALF_CACHE.clear()
    _HALF_CACHE[key] = (t, y, out)
    return out


def _half_grid(t: np.ndarray, y: np.ndarray, shift: float = 0.0) -> np.ndarray:
    """``y`` (logged at times ``t``) on the half-step grid t_0, t_0 + h/2, ..., t_N-1, evaluated at
    (time - shift), linearly interpolated, held at the ends."""
    t = np.asarray(t, dtype=float)
    th = np.empty(2 * t.size - 1)
    th[0::2] = t
    th[1::2] = 0.5 * (t[:-1] + t[1:])
    return np.interp(th - shift, t, np.asarray(y, dtype=float))


def speed_half(t, u_ratio, exponent: float) -> np.ndarray:
    """Speed factor (u/U)^n on the half grid (ones when there is no ratio or n = 0)."""
    n = 2 * len(t) - 1
    if u_ratio is None or exponent == 0.0:
        return np.ones(n)
    return np.power(np.clip(half_grid(t, u_ratio), 0.05, None), exponent)


def simulate_terms(theta, terms: Terms, x0, t, delta, u_ratio=None, substeps: int = 1) -> np.ndarray:
    """Free-run of the extended model from ``x0``, driven by the logged rudder.

    Parameters
    ----------
    theta : array_like, shape (6,)
        The linear part (a11, a12, a21, a22, b11, b21), units of pipeline.model.
    terms : Terms
        The effects' terms (:meth:`pipeline.diagnose.effects.base.Effect.apply`).
    x0 : array_like, shape (3,)
        The start (v m/s, r deg/s, psi deg).
    t : ndarray, shape (N,)
        Uniform time, s.
    delta : ndarray, shape (N,)
        Logged rudder, deg.
    u_ratio : ndarray, optional
        u/U per sample (speed-dependent terms); None: constant speed.
    substeps : int
        RK4 steps per sample (more where a servo lag needs them).

    Returns
    -------
    ndarray, shape (N, 3)
        (v m/s, r deg/s, psi deg); row 0 is ``x0``.

    Raises
    ------
    ModelError
        A rudder series not one-dimensional, shorter than 2 samples or not as long as ``t``.
    """
    th = as_theta(theta)
    d = np.asarray(delta, dtype=float)
    t = np.asarray(t, dtype=float)
    if d.ndim != 1 or d.size < 2 or t.size != d.size:
        raise ModelError("rudder series must be one-dimensional with at least 2 samples, as long as time")
    h = float(t[1] - t[0])
    a_half = half_grid(t, d, terms.delay_s)
    s_half = speed_half(t, u_ratio, terms.speed_exponent)
    codes, eqs, coefs = _arrays(terms)
    lag, m = _lag_and_substeps(terms, h, substeps)
    bias = reading_bias(terms, d.size, u_ratio)
    x0 = np.array(x0, dtype=float).reshape(3)
    if bias is not None:  # the reading's start -> the ship's (module docstring)
        x0[0] = x0[0] - bias[0]
    out = np.empty((d.size, 3))
    _run(out, 0, d.size, x0, a_half[0], a_half, s_half, h, m, th, codes, eqs, coefs, rudder_block(terms, lag))
    if bias is not None:  # the ship's sway velocity -> the reading
        out[:, 0] = out[:, 0] + bias
    return out


def reading_ratio(n: int, u_ratio) -> np.ndarray:
    """q = u/U_ref per sample (ones without u): the scale of a sway reading's bias (module docstring)."""
    return np.ones(n) if u_ratio is None else np.asarray(u_ratio, dtype=float)


def reading_bias(terms: Terms, n: int, u_ratio) -> np.ndarray | None:
    """The sway reading's bias v_bias_m_s q (m/s) at each of ``n`` samples, None without one; formed
    as the batch kernel forms it (the product, then the sum), so the bits agree."""
    vb = float(terms.v_bias_m_s)
    return None if vb == 0.0 else vb * reading_ratio(n, u_ratio)


def piece_step(length: int) -> int:
    """Samples between the starts of two pieces of ``length`` samples (:func:`piece_starts`): half a
    piece, at least one."""
    return max(1, int(length) // 2)


def piece_starts(n: int, horizon: int) -> tuple[int, np.ndarray]:
    """The pieces a run of ``n`` samples is predicted in from its measured states: (their length
    L = min(``horizon``, n) samples, the samples they start at: 0, every :func:`piece_step` (L // 2)
    up to n - L, so each sample is predicted twice)."""
    length = min(int(horizon), int(n))
    return length, np.arange(0, int(n) - length + 1, piece_step(length))


def predict_segments(
    theta, terms: Terms, states, t, delta, starts, length: int, u_ratio=None, substeps: int = 1
) -> np.ndarray:
    """Prediction over ``length`` samples from each measured state ``states[k]`` (k in ``starts``):
    (len(starts), length, 3).  The lag state at each start is the servo's own, run over the (delayed)
    logged rudder from the run's first sample (it depends on the rudder alone): a restart from the
    measured ship state is then a restart of the whole model's state, lag included.  (Taking the
    logged rudder itself there puts a 0.93 s lag's restarts a rudder swing off: one-ship-time-scale
    held-out MAE psi 0.71 deg against the whole run's 0.04.)"""
    th = as_theta(theta)
    t = np.asarray(t, dtype=float)
    h = float(t[1] - t[0])
    a_half = half_grid(t, delta, terms.delay_s)
    s_half = speed_half(t, u_ratio, terms.speed_exponent)
    codes, eqs, coefs = _arrays(terms)
    lag, m = _lag_and_substeps(terms, h, substeps)
    starts = np.asarray(starts, dtype=np.int64)
    xs = np.array(states, dtype=float, order="C")
    bias = reading_bias(terms, t.size, u_ratio)
    if bias is not None:  # the readings at the restarts -> the ship's states (module docstring)
        xs[:, 0] = xs[:, 0] - bias
    out = np.empty((len(starts), length, 3))
    _segments(out, starts, int(length), xs, a_half, s_half, h, m, th, codes, eqs, coefs,
              rudder_block(terms, lag))
    if bias is not None:
        out[:, :, 0] = out[:, :, 0] + bias[starts[:, None] + np.arange(length)[None, :]]
    return out


def simulate_extended(
    theta,
    x0,
    delta,
    h: float,
    *,
    t=None,
    offset_deg: float = 0.0,
    n_rrr_s_per_deg2: float = 0.0,
    delay_s: float | None = None,
    lag_s: float = 0.0,
    u_ratio=None,
    speed_exponent: float = 0.0,
    substeps: int = 1,
) -> np.ndarray:
    """Free-run with the classic effects by keyword (see module docstring).

    Parameters
    ----------
    theta : array_like, shape (6,)
        The linear part (a11, a12, a21, a22, b11, b21), units of pipeline.model.
    x0 : array_like, shape (3,)
        The start (v m/s, r deg/s, psi deg).
    delta : ndarray, shape (N,)
        Logged rudder, deg.
    h : float
        Sample step, s (the time grid when ``t`` is None).
    t : ndarray, optional
        Uniform time, s.
    offset_deg : float
        Rudder offset, deg.
    n_rrr_s_per_deg2 : float
        Cubic yaw damping, s/deg^2.
    delay_s : float, optional
        The physical dead time, s (None or 0: none).
    lag_s : float
        First-order servo lag, s.
    u_ratio : ndarray, optional
        u/U per sample; None: constant speed.
    speed_exponent : float
        The speed factor's exponent (speed_loss).
    substeps : int
        RK4 steps per sample.

    Returns
    -------
    ndarray, shape (N, 3)
        (v m/s, r deg/s, psi deg).
    """
    d = np.asarray(delta, dtype=float)
    if t is None:
        t = np.arange(d.size) * h
    terms = Terms(
        offset_deg=offset_deg, delay_s=float(delay_s or 0.0), lag_s=lag_s, speed_exponent=speed_exponent
    )
    if n_rrr_s_per_deg2:
        terms.feat_code.append(0)
        terms.feat_eq.append(1)
        terms.feat_coef.append(float(n_rrr_s_per_deg2))
    return simulate_terms(theta, terms, x0, t, d, u_ratio=u_ratio, substeps=substeps)


# ---------------------------------------------------------------- many parameter vectors in one call


@njit(cache=True)
def _oe_batch(res, thetas, coefs, blks, lags, ms, codes, eqs, a_buf, a_off, s_buf, s_off, x0s, runs, data,
              sc, scratch):  # pragma: no cover - compiled; held to fit._oe_residuals bit for bit by tests
    """Output-error residuals of every parameter vector (row c of ``res``) on every run k, in the
    layout of :func:`pipeline.diagnose.fit._oe_residuals`: per run w (psi_sim - psi)/sc_psi,
    w (r_sim - r)/sc_r and, when sway is measured, w (v_sim - v)/sc_v (same operations, same order,
    so the same bits).  Row c starts run k from x0s[c, k] and has the rudder block blks[c]; its rudder
    and speed factor on the half grid of run k start at a_buf[a_off[c, k]] and s_buf[s_off[c, k]]; its
    lag as integrated and RK4 sub-steps are lags[c, k], ms[c, k].  ``runs`` (runs, 6) int: samples n,
    first sample m_off in ``data``, first residual r_off, sway measured (1/0); ``data`` (5, samples):
    psi, r, v, q = u/U_ref and the sample step h (s) of every sample, the runs one after another.
    Row c's sway readings carry blks[c, B_VBIAS] q: x0s are readings, and so are the sway velocities
    compared.  ``sc``: (psi, r, v) spreads; run weights w = 1/sqrt(n)."""
    x0 = np.empty(3)
    blk = np.empty(BLOCK_SIZE)
    for c in range(thetas.shape[0]):
        for b in range(BLOCK_SIZE):
            blk[b] = blks[c, b]
        vb = blk[B_VBIAS]
        for k in range(runs.shape[0]):
            n, mo = runs[k, 0], runs[k, 1]
            nh = 2 * n - 1
            a_half = a_buf[a_off[c, k] : a_off[c, k] + nh]
            s_half = s_buf[s_off[c, k] : s_off[c, k] + nh]
            sim = scratch[:n]
            x0[0] = x0s[c, k, 0] - vb * data[3, mo] if vb != 0.0 else x0s[c, k, 0]
            x0[1] = x0s[c, k, 1]
            x0[2] = x0s[c, k, 2]
            blk[B_LAG] = lags[c, k]
            # np.int64(0), not 0: a literal would compile _run a second time (Literal[int](0))
            _run(sim, np.int64(0), n, x0, a_half[0], a_half, s_half, data[4, mo], ms[c, k], thetas[c], codes,
                 eqs, coefs[c], blk)
            _residuals(res[c], sim, k, runs, data, sc, vb)


@njit(cache=True, inline="always")
def _residuals(res, sim, k, runs, data, sc, vb):  # pragma: no cover - compiled
    """Run k's residuals of the simulated (v, r, psi) ``sim`` into ``res`` (:func:`_oe_batch`)."""
    n, mo, o = runs[k, 0], runs[k, 1], runs[k, 2]
    w = 1.0 / np.sqrt(n)
    for i in range(n):
        res[o + i] = w * (sim[i, 2] - data[0, mo + i]) / sc[0]
    o += n
    for i in range(n):
        res[o + i] = w * (sim[i, 1] - data[1, mo + i]) / sc[1]
    if runs[k, 3]:
        o += n
        for i in range(n):
            sv = sim[i, 0] + vb * data[3, mo + i] if vb != 0.0 else sim[i, 0]
            res[o + i] = w * (sv - data[2, mo + i]) / sc[2]


# ---------------------------------------------------------------- sensitivities (the analytic Jacobian)


@njit(cache=True)
def _feature_grad(code, v, r, s):  # pragma: no cover - compiled; held to finite differences by tests
    """(d/dv, d/dr) of :func:`_feature` ``code`` at (v m/s, r deg/s, speed factor s)."""
    if code == 0:
        return 0.0, 3.0 * r * r
    if code == 1:
        return 0.0, 2.0 * abs(r)
    if code == 2:
        return 2.0 * abs(v), 0.0
    if code == 3:
        return 2.0 * v * r, v * v
    if code == 4:
        return r * r, 2.0 * v * r
    if code == 5:
        return abs(r), v * (1.0 if r > 0.0 else (-1.0 if r < 0.0 else 0.0))
    if code == 6:
        return (1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)) * r, abs(v)
    if code == 8:
        return 2.0 * v * r / s, v * v / s
    if code == 9:
        return r * r / s, 2.0 * v * r / s
    if code == 10:
        return 0.0, 3.0 * r * r / s
    return 3.0 * v * v, 0.0


#: kernel columns of the sensitivities (:func:`_oe_jac`, :func:`kernel_vector`): theta (0-5), the feature
#: coefficients (6 .. 5 + nf), then these, counted from 6 + nf: the rudder block's offset, asymmetry and
#: cubic, and the sway reading's bias (the starts are columns of their own)
S_OFFSET, S_ASYM, S_CUBIC, S_VBIAS = 0, 1, 2, 3


@njit(cache=True)
def _run_sens(out, jac, rows, fac, jcol, jsc, n, x0, e0, s0, a_half, s_half, h, m, th, codes, eqs, coefs, blk,
              kid):  # pragma: no cover
    """:func:`_run` from sample 0 to n - 1 (the same operations on the state, so the same bits in
    ``out``) and, alongside, the exact derivatives of the discrete RK4 solution along the kernel
    parameters kid[j] (:func:`_deriv_at`), from ``s0`` (columns, 3) at the start: d(psi, r, v)_k /
    d(column j) times fac[0..2] jsc[j] is written to jac[rows[0..2] + k, jcol[j]] (rows[2] < 0: no v
    rows; jcol[j] < 0: not written).
    A clipped state (a diverging trial model) has derivative 0.

    The four stages' partial derivatives are made once per step, beside the stages themselves from the
    same feature values (:func:`_deriv_at`); each column's RK4 sensitivity step then runs on its own in
    registers (a column depends on no other), the same operations in the same order as the
    stage-by-stage form, so the same bits."""
    nc = s0.shape[0]
    tab = np.zeros((4, 2, 6 + codes.shape[0] + S_VBIAS + 2))    # the last slot: zero (a start, the bias)
    amat = np.empty((4, 4))
    v, r, psi, e = x0[0], x0[1], x0[2], e0
    sv, sr, sp = s0[:, 0].copy(), s0[:, 1].copy(), s0[:, 2].copy()
    hs = h / m
    half = 0.5 * hs
    c6 = hs / 6.0
    with_v = rows[2] >= 0
    for k in range(n):
        out[k, 0] = v
        out[k, 1] = r
        out[k, 2] = psi
        for j in range(nc):
            c = jcol[j]
            if c >= 0:
                jac[rows[0] + k, c] = fac[0] * jsc[j] * sp[j]
                jac[rows[1] + k, c] = fac[1] * jsc[j] * sr[j]
                if with_v:
                    jac[rows[2] + k, c] = fac[2] * jsc[j] * sv[j]
        if k == n - 1:
            break
        for jj in range(m):
            a0, a1, a2 = _stage_inputs(a_half, 2 * k, jj, m)
            q0, q1, q2 = _stage_inputs(s_half, 2 * k, jj, m)
            (vn, rn, psi, en, k1v, k1r, k1e, k2v, k2r, k2e, k3v, k3r, k3e,
             clip_psi) = _rk4_step(v, r, psi, e, a0, a1, a2, q0, q1, q2, hs, th, codes, eqs, coefs, blk, tab,
                                   amat, True)   # with the stages' partial derivatives at their own states
            zero_v = not (abs(vn) < _CLIP_V)     # clipped (_rk4_step): derivative 0
            zero_r = not (abs(rn) < _CLIP_R)
            for j in range(nc):
                b = kid[j]
                x, y = sv[j], sr[j]
                # d_i = A_i t_i + B_i; t_1 = S, t_2 = S + hs/2 d_1, t_3 = S + hs/2 d_2, t_4 = S + hs d_3
                d1v = amat[0, 0] * x + amat[0, 1] * y + tab[0, 0, b]
                d1r = amat[0, 2] * x + amat[0, 3] * y + tab[0, 1, b]
                t2v, t2r = x + half * d1v, y + half * d1r
                d2v = amat[1, 0] * t2v + amat[1, 1] * t2r + tab[1, 0, b]
                d2r = amat[1, 2] * t2v + amat[1, 3] * t2r + tab[1, 1, b]
                t3v, t3r = x + half * d2v, y + half * d2r
                d3v = amat[2, 0] * t3v + amat[2, 1] * t3r + tab[2, 0, b]
                d3r = amat[2, 2] * t3v + amat[2, 3] * t3r + tab[2, 1, b]
                t4v, t4r = x + hs * d3v, y + hs * d3r
                d4v = amat[3, 0] * t4v + amat[3, 1] * t4r + tab[3, 0, b]
                d4r = amat[3, 2] * t4v + amat[3, 3] * t4r + tab[3, 1, b]
                if not clip_psi:     # dpsi/dt = r: the heading's stages are the rate's stage states
                    sp[j] = sp[j] + c6 * (y + 2.0 * t2r + 2.0 * t3r + t4r)
                sv[j] = 0.0 if zero_v else x + c6 * (d1v + 2.0 * d2v + 2.0 * d3v + d4v)
                sr[j] = 0.0 if zero_r else y + c6 * (d1r + 2.0 * d2r + 2.0 * d3r + d4r)
            v, r, e = vn, rn, en


@njit(cache=True)
def _oe_jac(res, jac, th, coefs, blk, lags, ms, codes, eqs, a_buf, a_off, s_buf, s_off, x0s, runs, data, sc,
            scratch, ids, cols, xcols, xscale):  # pragma: no cover - compiled; held to finite differences
    """Residuals of ONE parameter vector (as :func:`_oe_batch`, the same bits) and their derivatives,
    written into the columns of ``jac`` (residuals, columns; zeros on entry): the derivative along
    kernel parameter ids[j] (theta 0-5, the feature coefficients, then the rudder block's offset,
    asymmetry, cubic and the sway reading's bias at :data:`S_OFFSET`... from 6 + nf) into column
    cols[j]; along run k's start state i (v0, r0, psi0) times xscale[k, i] into column xcols[k, i]
    (-1: none)."""
    nf = coefs.shape[0]
    pm = ids.shape[0]
    zero = 6 + nf + S_VBIAS + 1          # the zero slot of _deriv_at's table
    kid = np.empty(pm + 3, dtype=np.int64)
    for j in range(pm):
        kid[j] = ids[j] if ids[j] != 6 + nf + S_VBIAS else zero
    kid[pm:] = zero
    jcol = np.empty(pm + 3, dtype=np.int64)
    jsc = np.ones(pm + 3)
    jcol[:pm] = cols
    s0 = np.zeros((pm + 3, 3))
    x0 = np.empty(3)
    rows = np.empty(3, dtype=np.int64)
    fac = np.empty(3)
    vb = blk[B_VBIAS]
    ivb = -1
    for j in range(pm):
        if ids[j] == 6 + nf + S_VBIAS:
            ivb = j
    for k in range(runs.shape[0]):
        n, mo = runs[k, 0], runs[k, 1]
        nh = 2 * n - 1
        a_half = a_buf[a_off[k] : a_off[k] + nh]
        s_half = s_buf[s_off[k] : s_off[k] + nh]
        sim = scratch[:n]
        x0[0] = x0s[k, 0] - vb * data[3, mo] if vb != 0.0 else x0s[k, 0]
        x0[1] = x0s[k, 1]
        x0[2] = x0s[k, 2]
        s0[:, :] = 0.0
        if ivb >= 0:
            s0[ivb, 0] = -data[3, mo]       # the start is a reading: the ship's v0 = reading - vb q
        # only the start states asked for (xcols >= 0) get a sensitivity: each column is integrated on
        # its own, so leaving the others out changes no bit of the rest and saves their arithmetic
        nc = pm
        for i in range(3):
            if xcols[k, i] >= 0:
                s0[nc, i] = 1.0
                jcol[nc] = xcols[k, i]
                jsc[nc] = xscale[k, i]
                nc += 1
        blk[B_LAG] = lags[k]
        w = 1.0 / np.sqrt(n)
        o = runs[k, 2]
        rows[0], rows[1], rows[2] = o, o + n, (o + 2 * n if runs[k, 3] else -1)
        fac[0], fac[1], fac[2] = w / sc[0], w / sc[1], w / sc[2]
        _run_sens(sim, jac, rows, fac, jcol[:nc], jsc[:nc], n, x0, a_half[0], s0[:nc], a_half, s_half,
                  data[4, mo], ms[k], th, codes, eqs, coefs, blk, kid[:nc])
        _residuals(res, sim, k, runs, data, sc, vb)
        if runs[k, 3] and ivb >= 0:         # the reading's bias: v read = v + vb q
            for i in range(n):
                jac[rows[2] + i, cols[ivb]] += fac[2] * data[3, mo + i]


@njit(cache=True)
def _pe_jac(res, jac, th, coefs, blk, lags, ms, codes, eqs, a_buf, a_off, s_buf, s_off, runs, data, sc,
            scratch, seg, ids, cols, sens):  # pragma: no cover - compiled; held to fit._pe_residuals and
    # to finite differences by tests/test_diagnose_jacobian.py
    """Prediction-error residuals of ONE parameter vector on runs that all measure sway, in the layout
    of :func:`pipeline.diagnose.fit._pe_residuals` (the same operations, so the same bits) and, with
    ``sens``, their derivatives along kernel parameter ids[j] into column cols[j] of ``jac`` (zeros on
    entry; :func:`_oe_jac`'s kernel order).  Run k's pieces: seg[k] = (length L, start step, first
    residual); a piece starts at each measured state k0 = 0, step, ... up to n - L (the reading's bias
    taken off its v), with the servo's own lag state there (:func:`_lag_history`), and so has no
    derivative at its start but along the bias; the other arguments are :func:`_oe_jac`'s."""
    nf = coefs.shape[0]
    pm = ids.shape[0]
    zero = 6 + nf + S_VBIAS + 1
    kid = np.empty(pm, dtype=np.int64)
    ivb = -1
    for j in range(pm):
        kid[j] = ids[j] if ids[j] != 6 + nf + S_VBIAS else zero
        if ids[j] == 6 + nf + S_VBIAS:
            ivb = j
    jsc = np.ones(pm)
    s0 = np.zeros((pm, 3))
    x0 = np.empty(3)
    rows = np.empty(3, dtype=np.int64)
    fac = np.empty(3)
    vb = blk[B_VBIAS]
    for k in range(runs.shape[0]):
        n, mo = runs[k, 0], runs[k, 1]
        length, step, o = seg[k, 0], seg[k, 1], seg[k, 2]
        n_seg = (n - length) // step + 1
        nh = 2 * n - 1
        a_half = a_buf[a_off[k] : a_off[k] + nh]
        s_half = s_buf[s_off[k] : s_off[k] + nh]
        h = data[4, mo]
        blk[B_LAG] = lags[k]
        e_hist = _lag_history(a_half, h, ms[k], lags[k])
        w = 1.0 / np.sqrt(n_seg * length)
        fac[0], fac[1], fac[2] = w / sc[0], w / sc[1], w / sc[2]
        sim = scratch[:length]
        for i in range(n_seg):
            k0 = i * step
            x0[0] = data[2, mo + k0] - vb * data[3, mo + k0] if vb != 0.0 else data[2, mo + k0]
            x0[1] = data[1, mo + k0]
            x0[2] = data[0, mo + k0]
            pr = o + i * length                  # this piece's psi rows; its r and v rows follow a block on
            rows[0], rows[1], rows[2] = pr, pr + n_seg * length, pr + 2 * n_seg * length
            if sens:
                s0[:, :] = 0.0
                if ivb >= 0:
                    s0[ivb, 0] = -data[3, mo + k0]  # the start is a reading: v0 = reading - vb q
                _run_sens(sim, jac, rows, fac, cols, jsc, length, x0, e_hist[k0], s0, a_half[2 * k0:],
                          s_half[2 * k0:], h, ms[k], th, codes, eqs, coefs, blk, kid)
                if ivb >= 0:                    # the reading's bias: v read = v + vb q
                    for j in range(length):
                        jac[rows[2] + j, cols[ivb]] += fac[2] * data[3, mo + k0 + j]
            else:
                _run(sim, k0, k0 + length, x0, e_hist[k0], a_half, s_half, h, ms[k], th, codes, eqs, coefs,
                     blk)
            for j in range(length):
                res[rows[0] + j] = (w * (sim[j, 2] - data[0, mo + k0 + j])) / sc[0]
            for j in range(length):
                res[rows[1] + j] = (w * (sim[j, 1] - data[1, mo + k0 + j])) / sc[1]
            for j in range(length):
                sv = sim[j, 0] + vb * data[3, mo + k0 + j] if vb != 0.0 else sim[j, 0]
                res[rows[2] + j] = (w * (sv - data[2, mo + k0 + j])) / sc[2]


class OEBatch:
    """Output-error residuals of many parameter vectors of one structure on fixed runs, in one kernel
    call (:func:`_oe_batch`), and of one vector with their exact derivatives (:meth:`jacobian`).

    ``runs``: per run (t s, delta deg, x0, psi deg, r deg/s, v m/s or None, u_ratio or None, weight
    1/sqrt(samples)); ``scales``: (psi, r, v) spreads; ``unpack``: parameter vector -> (theta,
    Terms, values).  The inputs of every simulation are made by the same functions as
    :func:`simulate_terms` makes them (:func:`half_grid`, :func:`speed_half`, :func:`_lag_and_substeps`)."""

    def __init__(self, runs, scales, unpack):
        self.unpack = unpack
        self.t = [np.asarray(x[0], dtype=float) for x in runs]
        self.d = [np.asarray(x[1], dtype=float) for x in runs]
        self.ratios = [x[6] for x in runs]
        self.x0s = np.ascontiguousarray([np.asarray(x[2], dtype=float).reshape(3) for x in runs])
        ns = np.array([t.size for t in self.t], dtype=np.int64)
        for x, t in zip(runs, self.t, strict=True):
            if float(x[7]) != 1.0 / np.sqrt(t.size):
                raise ValueError("OEBatch weighs every run by 1/sqrt(samples)")
        has_v = np.array([x[5] is not None for x in runs], dtype=np.int64)
        sizes = ns * np.where(has_v, 3, 2)
        self.runs = np.column_stack([
            ns,
            np.concatenate([[0], np.cumsum(ns)[:-1]]),
            np.concatenate([[0], np.cumsum(sizes)[:-1]]),
            has_v,
        ]).astype(np.int64)
        self.data = np.ascontiguousarray(np.vstack([
            np.concatenate([np.asarray(x[3], dtype=float) for x in runs]),
            np.concatenate([np.asarray(x[4], dtype=float) for x in runs]),
            np.concatenate([np.zeros(t.size) if x[5] is None else np.asarray(x[5], dtype=float)
                            for x, t in zip(runs, self.t, strict=True)]),
            np.concatenate([reading_ratio(t.size, x[6]) for x, t in zip(runs, self.t, strict=True)]),
            np.concatenate([np.full(t.size, float(t[1] - t[0])) for t in self.t]),
        ]))
        self.hs = np.array([float(t[1] - t[0]) for t in self.t])
        self.sc = np.array([float(x) for x in scales])
        self.n_res = int(sizes.sum())
        self.scratch = np.empty((int(ns.max()), 3))
        self._seen: dict = {}

    def _inputs(self, terms: Terms, k: int):
        """(lag, sub-steps, rudder half grid, speed half grid) of run k: made once per instance and
        input-effect values (a finite-difference column moves one parameter, the rest repeat)."""
        key = (k, float(terms.lag_s), float(terms.delay_s), float(terms.speed_exponent))
        hit = self._seen.get(key)
        if hit is None:
            lag, m = _lag_and_substeps(terms, self.hs[k], 1)
            hit = (
                lag,
                m,
                half_grid(self.t[k], self.d[k], terms.delay_s),
                speed_half(self.t[k], self.ratios[k], terms.speed_exponent),
            )
            if len(self._seen) > 256:  # a time parameter being fitted makes new values each step
                self._seen.clear()
            self._seen[key] = hit
        return hit

    def _pack(self, cols):
        """Kernel arrays of the (theta, Terms) ``cols``: thetas, coefs, blocks, lags, sub-steps, codes,
        eqs, the rudder and speed half grids concatenated and each row's offsets into them."""
        nc, nk = len(cols), len(self.t)
        codes, eqs, _ = _arrays(cols[0][1])
        thetas = np.empty((nc, 6))
        coefs = np.empty((nc, codes.size))
        blks = np.empty((nc, BLOCK_SIZE))
        lags = np.empty((nc, nk))
        ms = np.empty((nc, nk), dtype=np.int64)
        a_off = np.empty((nc, nk), dtype=np.int64)
        s_off = np.empty((nc, nk), dtype=np.int64)
        a_parts, s_parts, a_at, s_at = [], [], {}, {}
        a_len = s_len = 0
        for c, (th, terms) in enumerate(cols):
            thetas[c] = th
            coefs[c] = terms.feat_coef
            blks[c] = rudder_block(terms)
            for k in range(nk):
                lags[c, k], ms[c, k], a, s = self._inputs(terms, k)
                if id(a) not in a_at:
                    a_at[id(a)] = a_len
                    a_parts.append(a)
                    a_len += a.size
                a_off[c, k] = a_at[id(a)]
                if id(s) not in s_at:
                    s_at[id(s)] = s_len
                    s_parts.append(s)
                    s_len += s.size
                s_off[c, k] = s_at[id(s)]
        return (thetas, coefs, blks, lags, ms, codes, eqs, np.concatenate(a_parts), a_off,
                np.concatenate(s_parts), s_off)

    def __call__(self, P, X0=None) -> np.ndarray:
        """Residuals (len(P), n_res) of the parameter vectors ``P`` (rows); ``X0`` (len(P), runs, 3):
        each row's initial states of the runs (v m/s, r deg/s, psi deg), default the runs' own."""
        P = np.atleast_2d(np.asarray(P, dtype=float))
        nc, nk = P.shape[0], len(self.t)
        if X0 is None:
            X0 = np.broadcast_to(self.x0s, (nc, nk, 3))
        X0 = np.array(X0, dtype=float, order="C")   # a writable copy: one compiled signature of _oe_batch
        packed = self._pack([self.unpack(p)[:2] for p in P])
        res = np.empty((nc, self.n_res))
        _oe_batch(res, *packed, X0, self.runs, self.data, self.sc, self.scratch)
        return res

    def jacobian(self, p, ids, cols, width: int, starts=(), x0=None, order: str = "C"
                 ) -> tuple[np.ndarray, np.ndarray]:
        """(residuals (n_res,), derivatives (n_res, ``width``)) of the parameter vector ``p`` from the
        runs' starts ``x0`` (runs, 3; default their own): the residuals are :meth:`__call__`'s bits;
        column cols[j] holds the derivative along the kernel parameter ids[j] (:func:`kernel_vector`'s
        order), column width - len(starts) + c the derivative along start state i of run k times w
        for starts[c] = (k, i, w) (:func:`_oe_jac`); other columns are zero.  ``order``: the Jacobian's
        memory layout ("C" or "F"; "F" is what LAPACK's QR reads without a copy, the same numbers)."""
        th, terms = self.unpack(np.asarray(p, dtype=float))[:2]
        x0 = self.x0s if x0 is None else np.ascontiguousarray(x0, dtype=float)
        nk = len(self.t)
        xcols = np.full((nk, 3), -1, dtype=np.int64)
        xscale = np.zeros((nk, 3))
        for c, (k, i, w) in enumerate(starts):
            xcols[k, i] = width - len(starts) + c
            xscale[k, i] = w
        thetas, coefs, blks, lags, ms, codes, eqs, a_buf, a_off, s_buf, s_off = self._pack([(th, terms)])
        res = np.empty(self.n_res)
        jac = _jac_buffer(self.n_res, width)
        _oe_jac(res, jac, thetas[0], coefs[0], blks[0], lags[0], ms[0], codes, eqs, a_buf, a_off[0], s_buf,
                s_off[0], x0, self.runs, self.data, self.sc, self.scratch, np.asarray(ids, dtype=np.int64),
                np.asarray(cols, dtype=np.int64), xcols, xscale)
        return res, _jac_view(jac, self.n_res, width, order)

    def pe_layout(self, horizon: int) -> np.ndarray | None:
        """Per run (piece length, start step, first residual) of the prediction-error residuals
        (:meth:`pe_jacobian`; the pieces of :func:`piece_starts`), with their total count as a last
        row; None where a run does not measure sway (its pieces start from the model's own free-run v)."""
        if not np.all(self.runs[:, 3]):
            return None
        seg = np.empty((len(self.t) + 1, 3), dtype=np.int64)
        o = 0
        for k, n in enumerate(self.runs[:, 0]):
            length, starts = piece_starts(int(n), horizon)
            seg[k] = (length, piece_step(length), o)
            o += 3 * starts.size * length
        seg[-1] = (0, 0, o)
        return seg

    def pe_jacobian(self, p, ids, cols, width: int, seg: np.ndarray, *, sens: bool = True, order: str = "C"
                    ) -> tuple[np.ndarray, np.ndarray | None]:
        """(prediction-error residuals, derivatives (residuals, ``width``) or None without ``sens``) of
        the parameter vector ``p`` over the pieces ``seg`` (:meth:`pe_layout`): the residuals are
        :func:`pipeline.diagnose.fit._pe_residuals`'s bits; column cols[j] holds the derivative along
        kernel parameter ids[j] (:meth:`jacobian`'s convention; a piece's start is measured, so it has
        no column of its own)."""
        th, terms = self.unpack(np.asarray(p, dtype=float))[:2]
        thetas, coefs, blks, lags, ms, codes, eqs, a_buf, a_off, s_buf, s_off = self._pack([(th, terms)])
        res = np.empty(int(seg[-1, 2]))
        jac = _jac_buffer(res.size if sens else 2, width if sens else 2)
        scratch = np.empty((max(int(seg[:-1, 0].max()), 1), 3))
        _pe_jac(res, jac, thetas[0], coefs[0], blks[0], lags[0], ms[0], codes, eqs, a_buf, a_off[0], s_buf,
                s_off[0], self.runs, self.data, self.sc, scratch, seg[:-1], np.asarray(ids, dtype=np.int64),
                np.asarray(cols, dtype=np.int64), sens)
        return res, (_jac_view(jac, res.size, width, order) if sens else None)


def _jac_buffer(rows: int, width: int) -> np.ndarray:
    """A zero Jacobian buffer for the kernels, Fortran-ordered with at least two columns and rows: numba
    types an array that is C- and F-contiguous at once (one column or row) as "C", and every layout
    is compiled apart (15-20 s CPU each for _run_sens and the kernels calling it, in a fresh tree), so
    the kernels see one layout only."""
    return np.zeros((max(rows, 2), max(width, 2)), order="F")


def _jac_view(jac: np.ndarray, rows: int, width: int, order: str) -> np.ndarray:
    """The first ``rows`` x ``width`` of a :func:`_jac_buffer`, in ``order`` ("F" a view, "C" a copy:
    the same numbers)."""
    out = jac[:rows, :width]
    return out if order == "F" else np.ascontiguousarray(out)


def kernel_vector(theta, terms: Terms) -> tuple[np.ndarray, tuple]:
    """(the kernel parameters with sensitivities, in :func:`_oe_jac`'s column order without the starts:
    theta, feature coefficients, offset deg, asymmetry, cubic 1/deg^2, sway bias m/s; the inputs
    without: (feature codes, equations, delay s, lag s, speed exponent)).  A parameter that moves only
    the first has its Jacobian column from the sensitivities; one that moves the second, by a
    finite difference."""
    vec = np.concatenate([np.asarray(theta, dtype=float), np.asarray(terms.feat_coef, dtype=float),
                          [terms.offset_deg, terms.asymmetry, terms.rudder_cubic_per_deg2, terms.v_bias_m_s]])
    other = (tuple(terms.feat_code), tuple(terms.feat_eq), float(terms.delay_s), float(terms.lag_s),
             float(terms.speed_exponent))
    return vec, other
