"""The sway-yaw identification model and its Nomoto indices (paper Eq. 6).

Contract: docs/contract.md#the-identification-model; method: docs/identification.md#the-model.

Units (the paper's and docs/contract.md's, in which Table 4 is given): v m/s, r deg/s, psi deg, delta deg,
step h s.  Parameters theta = (a11, a12, a21, a22, b11, b21).

The equations of motion are defined ONCE, in continuous time, by :func:`rhs`:

    dv/dt   = a11 v + a12 r + b11 delta
    dr/dt   = a21 v + a22 r + b21 delta
    dpsi/dt = r

The paper's discrete step (:func:`step`, :func:`simulate`) is the explicit Euler step of it,
x(k+1) = x(k) + h rhs(x(k), delta(k)).  :func:`simulate_zoh` integrates the same right-hand side
exactly with the rudder held over each step (zero-order hold, matrix exponential): the simulation of
the diagnosis, which must add no discretisation error of its own.  Copies (numba kernels elsewhere)
are held to :func:`rhs` by tests (tests/test_model_definition.py).
"""

from __future__ import annotations

import math

import numpy as np

from pipeline import paper
from pipeline.errors import ModelError

PARAM_NAMES = ("a11", "a12", "a21", "a22", "b11", "b21")
STATE_NAMES = ("v", "r", "psi")
INDEX_NAMES = ("K", "T1", "T2", "T3", "T")

#: Aliases of the paper's Table 4, Table 7 and graphical K, T, imported under these names across the package
#: (the figures themselves live in :mod:`pipeline.paper`).
PAPER_TABLE4 = paper.TABLE4
PAPER_TABLE7 = paper.TABLE7
PAPER_GRAPHICAL = paper.GRAPHICAL


def as_theta(params) -> np.ndarray:
    """Parameters as an array in PARAM_NAMES order.

    Parameters
    ----------
    params : mapping or sequence
        a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model), by name or a sequence of
        6 in PARAM_NAMES order.

    Returns
    -------
    numpy.ndarray
        Shape (6,), float, the same units.

    Raises
    ------
    ModelError
        When a parameter is missing or the sequence does not hold 6 values.

    Examples
    --------
    >>> as_theta(PAPER_TABLE4).tolist()
    [-1.882, -0.1232, -7.422, -0.8129, 0.0099, 0.1657]
    >>> as_theta([1.0, 2.0])
    Traceback (most recent call last):
    ...
    pipeline.errors.ModelError: expected 6 parameters (a11 a12 a21 a22 b11 b21), got 2
    """
    if isinstance(params, dict):
        missing = [n for n in PARAM_NAMES if n not in params]
        if missing:
            raise ModelError(f"parameters missing: {', '.join(missing)}")
        return np.array([float(params[n]) for n in PARAM_NAMES])
    theta = np.asarray(params, dtype=float).reshape(-1)
    if theta.size != 6:
        raise ModelError(f"expected 6 parameters (a11 a12 a21 a22 b11 b21), got {theta.size}")
    return theta


def rhs(x, delta, theta):
    """Continuous-time right-hand side dx/dt of the sway-yaw model, THE definition of the equations.

    Parameters
    ----------
    x : array
        (..., 3) = (v m/s, r deg/s, psi deg).
    delta : array or float
        Rudder angle, deg.
    theta : mapping or sequence
        The six parameters a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model), by
        name or in PARAM_NAMES order.

    Returns
    -------
    numpy.ndarray
        (..., 3) = (dv/dt m/s^2, dr/dt deg/s^2, dpsi/dt deg/s).

    Examples
    --------
    The paper's KCS (Table 4) turning at 1 deg/s with 10 deg of rudder:

    >>> rhs([0.0, 1.0, 0.0], 10.0, PAPER_TABLE4).round(4).tolist()
    [-0.0242, 0.8441, 1.0]
    """
    a11, a12, a21, a22, b11, b21 = as_theta(theta)
    x = np.asarray(x, dtype=float)
    v, r = x[..., 0], x[..., 1]
    out = np.empty_like(x)
    out[..., 0] = a11 * v + a12 * r + b11 * delta
    out[..., 1] = a21 * v + a22 * r + b21 * delta
    out[..., 2] = r
    return out


def state_matrices(theta) -> tuple[np.ndarray, np.ndarray]:
    """:func:`rhs` written as dx/dt = A x + B delta (read off the definition).

    Parameters
    ----------
    theta : mapping or sequence
        The six parameters a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model), by
        name or in PARAM_NAMES order.

    Returns
    -------
    tuple of numpy.ndarray
        A (3, 3) and B (3,), in the units that map (v m/s, r deg/s, psi deg) and delta (deg) to their
        rates.

    Examples
    --------
    >>> A, B = state_matrices(PAPER_TABLE4)
    >>> A[:2, :2].tolist(), B.tolist()
    ([[-1.882, -0.1232], [-7.422, -0.8129]], [0.0099, 0.1657, 0.0])
    """
    A = np.column_stack([rhs(e, 0.0, theta) for e in np.eye(3)])
    B = rhs(np.zeros(3), 1.0, theta)
    return A, B


def step(x, delta, theta, h: float):
    """One step of the paper's discrete model: the Euler step of :func:`rhs`.

    Parameters
    ----------
    x : array
        (..., 3) = (v m/s, r deg/s, psi deg).
    delta : array or float
        Rudder angle over the step, deg.
    theta : mapping or sequence
        The six parameters a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model), by
        name or in PARAM_NAMES order.
    h : float
        Step, s.

    Returns
    -------
    numpy.ndarray
        The state one step later, same shape and units as ``x``.

    Examples
    --------
    >>> step([0.0, 0.0, 0.0], 10.0, PAPER_TABLE4, 0.08).round(5).tolist()
    [0.00792, 0.13256, 0.0]
    """
    x = np.asarray(x, dtype=float)
    return x + h * rhs(x, delta, theta)


def zoh_matrices(theta, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation of :func:`rhs` at step ``h``: the matrix
    exponential of the augmented [[A, B], [0, 0]] h.

    Parameters
    ----------
    theta : mapping or sequence
        The six parameters a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model), by
        name or in PARAM_NAMES order.
    h : float
        Step, s.

    Returns
    -------
    tuple of numpy.ndarray
        Ad (3, 3) and Bd (3,): x[k+1] = Ad x[k] + Bd delta[k] (x in m/s, deg/s, deg; delta deg).

    Examples
    --------
    At a small step the exact discretisation approaches the Euler step (I + A h, B h):

    >>> Ad, Bd = zoh_matrices(PAPER_TABLE4, 1e-4)
    >>> A, B = state_matrices(PAPER_TABLE4)
    >>> bool(np.allclose(Ad, np.eye(3) + A * 1e-4, atol=1e-7) and np.allclose(Bd, B * 1e-4, atol=1e-9))
    True
    """
    from scipy.linalg import expm

    A, B = state_matrices(theta)
    M = np.zeros((4, 4))
    M[:3, :3] = A
    M[:3, 3] = B
    E = expm(M * float(h))
    return E[:3, :3], E[:3, 3]


def simulate_zoh(theta, x0, delta, h: float) -> np.ndarray:
    """Free-run of the continuous-time model with the rudder held over each step (exact, no
    discretisation error).

    Parameters
    ----------
    theta : mapping or sequence
        The six parameters a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model), by
        name or in PARAM_NAMES order.
    x0 : sequence
        Initial (v m/s, r deg/s, psi deg).
    delta : array
        Rudder angle sequence, deg, length N.
    h : float
        Step, s.

    Returns
    -------
    numpy.ndarray
        (N, 3) of (v, r, psi); row 0 is ``x0``, row k+1 follows from row k and delta[k].

    Examples
    --------
    A held 10 deg rudder for 8 s: the yaw rate settles toward K delta (K 0.387 1/s, 3.87 deg/s):

    >>> x = simulate_zoh(PAPER_TABLE4, [0.0, 0.0, 0.0], np.full(101, 10.0), 0.08)
    >>> x.shape, round(float(x[-1, 1]), 2)
    ((101, 3), 3.4)
    """
    Ad, Bd = zoh_matrices(theta, h)
    d = np.asarray(delta, dtype=float)
    out = np.empty((d.size, 3))
    x = np.asarray(x0, dtype=float).reshape(3).copy()
    for k in range(d.size):
        out[k] = x
        x = Ad @ x + Bd * d[k]
    return out


def simulate(theta, x0, delta, h: float) -> np.ndarray:
    """Free-run simulation of the paper's discrete (Euler) model driven by the rudder alone.

    Parameters
    ----------
    theta, x0, delta, h
        As for :func:`simulate_zoh`: the six parameters (1/s, 1/s^2), the initial (v m/s, r deg/s,
        psi deg), the rudder sequence (deg, length N) and the step (s).

    Returns
    -------
    numpy.ndarray
        (N, 3) of (v m/s, r deg/s, psi deg); row 0 is ``x0``, row k+1 follows from row k and delta[k]
        by :func:`step`.

    Examples
    --------
    >>> x = simulate(PAPER_TABLE4, [0.0, 0.0, 0.0], np.full(100, 10.0), 0.08)
    >>> x.shape, x[0].tolist(), round(float(x[-1, 1]), 2)
    ((100, 3), [0.0, 0.0, 0.0], 3.4)
    """
    A, B = state_matrices(theta)
    Ad, Bd = np.eye(3) + h * A, h * B  # the Euler step of rhs, as a matrix (exactly :func:`step`)
    d = np.asarray(delta, dtype=float)
    out = np.empty((d.size, 3))
    x = np.asarray(x0, dtype=float).reshape(3).copy()
    for k in range(d.size):
        out[k] = x
        x = Ad @ x + Bd * d[k]
    return out


def nomoto_indices(params) -> dict[str, float]:
    """Second-order Nomoto indices from the six parameters (paper Eq. 6).

    With D = a11 a22 - a12 a21: K = (a21 b11 - a11 b21)/D, T1 T2 = 1/D,
    T1 + T2 = -(a11 + a22)/D, K T3 = b21/D, T = T1 + T2 - T3.  T1 >= T2.

    Parameters
    ----------
    params : mapping or sequence
        a11 a12 a21 a22 b11 b21 (units of docs/contract.md#the-identification-model)
        (docs/contract.md#run-data units).

    Returns
    -------
    dict
        {"K" (1/s: deg/s of yaw rate per deg of rudder), "T1", "T2", "T3", "T" (s)}.

    Raises
    ------
    ModelError
        When the time constants are not real and positive (D <= 0, complex roots) or K = 0.

    Examples
    --------
    Table 4 of the paper gives back its Table 7 (K 0.3867 1/s, T1 3.9688 s, ...) to the rounding of
    Table 4:

    >>> {k: round(v, 3) for k, v in nomoto_indices(PAPER_TABLE4).items()}
    {'K': 0.387, 'T1': 3.969, 'T2': 0.409, 'T3': 0.695, 'T': 3.683}
    """
    a11, a12, a21, a22, b11, b21 = as_theta(params)
    det = a11 * a22 - a12 * a21
    if not det > 0:
        raise ModelError(f"a11 a22 - a12 a21 = {det:.4g} <= 0: the model has no two positive time constants")
    s = -(a11 + a22) / det          # T1 + T2
    p = 1.0 / det                   # T1 T2
    disc = s * s - 4.0 * p
    if not s > 0:
        raise ModelError(f"T1 + T2 = {s:.4g} <= 0: the model is unstable")
    if disc < 0:
        raise ModelError("the time constants are complex (oscillatory yaw mode): no real T1, T2")
    root = math.sqrt(disc)
    t1, t2 = (s + root) / 2.0, (s - root) / 2.0
    k = (a21 * b11 - a11 * b21) / det
    if k == 0:
        raise ModelError("K = 0: the rudder has no steady effect on yaw rate")
    t3 = b21 / det / k
    return {"K": float(k), "T1": float(t1), "T2": float(t2), "T3": float(t3), "T": float(t1 + t2 - t3)}
