"""Square-root UKF with fuzzy fading memory (SR-UKF-FFM): the readable numpy reference path.

State (9): x = (v m/s, r deg/s, psi deg, a11, a12, a21, a22, b11, b21); the parameters follow a
random walk with zero process noise (paper Q).  Measurement: (v, r, psi), or a subset of them
(``meas_idx``) when a run has no sway velocity.  S is lower triangular with P = S S^T.

One step k (data y_k, rudder delta_{k-1} applied over the step into sample k):

* time update: sigma points X = [x, x + gamma S, x - gamma S] through the model
  (pipeline.model, docs/contract.md#the-identification-model); x- = sum Wm_i X_i;
  S- = tria([sqrt(W1)(X_1..2L - x-), sqrt(Q)]) by QR, then a rank-one cholupdate with point 0 and
  the sign of Wc0 (point 0 is kept out of the QR: a negative weight squared inside the QR would turn
  positive).
* measurement update: sigma points are redrawn from (x-, S-) (as filterpy 2 does, so the
  measurement statistics include Q), Y = h(X), Sy by QR + cholupdate of point 0 as above,
  Pxy = sum Wc_i dX_i dY_i^T, gain K = (Pxy / Sy^T) / Sy by two triangular solves,
  x = x- + K (y - y-), S = S- downdated by each column of U = K Sy.
* fading memory: S <- S / sqrt(f), f from the fuzzy rule table (:mod:`.fuzzy`).  The paper writes its
  fuzzy factor F as a multiplier on the updated factor; read literally, F in [0.95, 1] would shrink
  the covariance, the opposite of forgetting, so F is treated as the forgetting factor f here
  (P <- P / f inflates the covariance, old data weigh less):
  docs/identification.md#the-fuzzy-forgetting-factor.

A failed Cholesky downdate (the downdated matrix would not be positive definite) raises
:class:`~pipeline.errors.FilterError`; the filter never returns NaN silently.

:func:`ukf_run_reference` is the plain full-covariance UKF with the same weights, sigma points and
forgetting, the test reference: with any alpha, S S^T of the SR filter equals its P to round-off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular

from pipeline.errors import FilterError

NX = 9


@dataclass(frozen=True)
class Weights:
    """Unscented-transform weights and spread (van der Merwe): docs/identification.md#sr-ukf-ffm."""

    wm: np.ndarray
    wc: np.ndarray
    gamma: float


@dataclass(frozen=True)
class StepModel:
    """Everything one filter step reads besides the data and the posterior.

    Attributes
    ----------
    h : float
        Model step, s.
    sq_q : numpy.ndarray
        (9, 9) square root of the process noise Q (one-sigma per step in each state's unit:
        v m/s, r deg/s, psi deg, the parameters in theirs).
    sq_r : numpy.ndarray
        (m, m) square root of the measurement noise R of the measured channels (same units).
    meas_idx : numpy.ndarray
        (m,) indices of the measured states among (v, r, psi) = (0, 1, 2), int64.
    weights : Weights
        The unscented transform's weights and spread.
    """

    h: float
    sq_q: np.ndarray
    sq_r: np.ndarray
    meas_idx: np.ndarray
    weights: Weights

    @property
    def Q(self) -> np.ndarray:
        """The process noise covariance sq_q sq_q^T."""
        return self.sq_q @ self.sq_q.T

    @property
    def R(self) -> np.ndarray:
        """The measurement noise covariance sq_r sq_r^T."""
        return self.sq_r @ self.sq_r.T


def ut_weights(n: int, alpha: float, beta: float, kappa: float) -> Weights:
    """Weights of the scaled unscented transform for dimension ``n``."""
    lam = alpha ** 2 * (n + kappa) - n
    if not n + lam > 0:
        raise FilterError(f"unscented transform spread n + lambda = {n + lam:.3g} must be positive "
                          f"(alpha={alpha}, kappa={kappa})")
    wm = np.full(2 * n + 1, 1.0 / (2.0 * (n + lam)))
    wc = wm.copy()
    wm[0] = lam / (n + lam)
    wc[0] = wm[0] + 1.0 - alpha ** 2 + beta
    return Weights(wm=wm, wc=wc, gamma=math.sqrt(n + lam))


def model_fx(X: np.ndarray, delta: float, h: float) -> np.ndarray:
    """The augmented model (docs/contract.md#the-identification-model) on sigma points X (9, npts);
    parameters unchanged."""
    v, r, psi = X[0], X[1], X[2]
    a11, a12, a21, a22, b11, b21 = X[3], X[4], X[5], X[6], X[7], X[8]
    out = X.copy()
    out[0] = v + h * (a11 * v + a12 * r + b11 * delta)
    out[1] = r + h * (a21 * v + a22 * r + b21 * delta)
    out[2] = psi + h * r
    return out


def cholupdate(L: np.ndarray, x: np.ndarray, sign: float, *, what: str = "cholupdate") -> np.ndarray:
    """Rank-one update (sign +1) or downdate (sign -1) of a lower Cholesky factor (LINPACK style).

    Returns L' with L' L'^T = L L^T + sign x x^T.  A downdate that would leave the matrix not
    positive definite raises :class:`FilterError`.
    """
    L = np.array(L, dtype=float, copy=True)
    x = np.array(x, dtype=float, copy=True)
    s = 1.0 if sign >= 0 else -1.0
    n = L.shape[0]
    for k in range(n):
        r2 = L[k, k] ** 2 + s * x[k] ** 2
        if not r2 > 0.0 or not L[k, k] > 0.0:
            raise FilterError(f"{what}: Cholesky downdate failed at diagonal {k} "
                              f"(matrix would not be positive definite, r^2 = {r2:.3g})")
        r = math.sqrt(r2)
        c = r / L[k, k]
        t = x[k] / L[k, k]
        L[k, k] = r
        L[k + 1:, k] = (L[k + 1:, k] + s * t * x[k + 1:]) / c
        x[k + 1:] = c * x[k + 1:] - t * L[k + 1:, k]
    return L


def tria(A: np.ndarray) -> np.ndarray:
    """Lower-triangular S (positive diagonal) with S S^T = A A^T, by QR of A^T."""
    R = np.linalg.qr(A.T, mode="r")
    n = A.shape[0]
    R = R[:n, :n]
    sgn = np.where(np.diag(R) < 0, -1.0, 1.0)     # numpy's QR may give negative diagonal entries
    return (R * sgn[:, None]).T


def sigma_points(x: np.ndarray, S: np.ndarray, gamma: float) -> np.ndarray:
    """X = [x, x + gamma S, x - gamma S], shape (n, 2n + 1)."""
    return np.hstack([x[:, None], x[:, None] + gamma * S, x[:, None] - gamma * S])


def _factor_with_point0(D: np.ndarray, sq_noise: np.ndarray, wc: np.ndarray, what: str) -> np.ndarray:
    S = tria(np.hstack([math.sqrt(wc[1]) * D[:, 1:], sq_noise]))
    if wc[0] != 0.0:
        S = cholupdate(S, math.sqrt(abs(wc[0])) * D[:, 0], np.sign(wc[0]), what=what)
    return S


@dataclass
class StepResult:
    x_prior: np.ndarray
    x: np.ndarray
    S: np.ndarray
    innov: np.ndarray
    nis: float


def srukf_step(x, S, y, delta_prev: float, model: StepModel, f: float = 1.0) -> StepResult:
    """One time + measurement update of the SR-UKF from posterior (x, S) with measurement y (m,) and
    rudder ``delta_prev`` (deg) over the step, then forgetting S <- S / sqrt(f)."""
    w = model.weights
    # time update
    Xp = model_fx(sigma_points(x, S, w.gamma), delta_prev, model.h)
    xm = Xp @ w.wm
    Sm = _factor_with_point0(Xp - xm[:, None], model.sq_q, w.wc, "time update")
    # measurement update (sigma points redrawn from the prior)
    X = sigma_points(xm, Sm, w.gamma)
    Y = X[model.meas_idx]
    ym = Y @ w.wm
    DX = X - xm[:, None]
    DY = Y - ym[:, None]
    Sy = _factor_with_point0(DY, model.sq_r, w.wc, "innovation covariance")
    Pxy = (DX * w.wc) @ DY.T
    K = solve_triangular(Sy.T, solve_triangular(Sy, Pxy.T, lower=True), lower=False).T
    innov = y - ym
    xn = xm + K @ innov
    U = K @ Sy
    Sn = Sm
    for j in range(U.shape[1]):
        Sn = cholupdate(Sn, U[:, j], -1.0, what="measurement update")
    z = solve_triangular(Sy, innov, lower=True)
    return StepResult(x_prior=xm, x=xn, S=Sn / math.sqrt(f), innov=innov, nis=float(z @ z))


def srukf_run_reference(x0, S0, Y, delta_prev, model: StepModel, *, f_of=None):
    """Run the reference SR-UKF from posterior (x0, S0) over samples Y (N, m) with rudder
    ``delta_prev`` (N,), deg.

    ``f_of(innov_channel_value, previous)`` gives the forgetting factor (None: f = 1).  Returns a dict
    of arrays: x_prior (N, 9), x (N, 9), S (N, 9, 9), innov (N, m), nis (N,), f (N,).
    """
    x, S = np.asarray(x0, float), np.asarray(S0, float)
    n = Y.shape[0]
    out = {"x_prior": np.empty((n, NX)), "x": np.empty((n, NX)), "S": np.empty((n, NX, NX)),
           "innov": np.empty((n, len(model.meas_idx))), "nis": np.empty(n), "f": np.ones(n)}
    prev_e = 0.0
    for k in range(n):
        try:
            res = srukf_step(x, S, Y[k], delta_prev[k], model)
        except FilterError as exc:
            raise FilterError(f"SR-UKF step {k}: {exc}") from None
        f = 1.0
        if f_of is not None:
            f, prev_e = f_of(res.innov, prev_e)
        x, S = res.x, res.S / math.sqrt(f)
        out["x_prior"][k], out["x"][k], out["S"][k] = res.x_prior, x, S
        out["innov"][k], out["nis"][k], out["f"][k] = res.innov, res.nis, f
    return out


def ukf_run_reference(x0, P0, Y, delta_prev, model: StepModel, *, f_of=None):
    """Plain full-covariance UKF with the same weights, sigma points and forgetting (test reference):
    Q = sq_q sq_q^T and R = sq_r sq_r^T of ``model``.

    Returns a dict of arrays: x_prior, x, P (N, 9, 9), innov, nis, f.
    """
    x, P = np.asarray(x0, float), np.asarray(P0, float)
    h, Q, R, meas_idx, w = model.h, model.Q, model.R, model.meas_idx, model.weights
    n = Y.shape[0]
    out = {"x_prior": np.empty((n, NX)), "x": np.empty((n, NX)), "P": np.empty((n, NX, NX)),
           "innov": np.empty((n, len(meas_idx))), "nis": np.empty(n), "f": np.ones(n)}
    prev_e = 0.0
    for k in range(n):
        Xp = model_fx(sigma_points(x, np.linalg.cholesky(P), w.gamma), delta_prev[k], h)
        xm = Xp @ w.wm
        D = Xp - xm[:, None]
        Pm = (D * w.wc) @ D.T + Q
        X = sigma_points(xm, np.linalg.cholesky(Pm), w.gamma)
        Yp = X[meas_idx]
        ym = Yp @ w.wm
        DX, DY = X - xm[:, None], Yp - ym[:, None]
        Pyy = (DY * w.wc) @ DY.T + R
        Pxy = (DX * w.wc) @ DY.T
        K = np.linalg.solve(Pyy, Pxy.T).T
        innov = Y[k] - ym
        x = xm + K @ innov
        P = Pm - K @ Pyy @ K.T
        f = 1.0
        if f_of is not None:
            f, prev_e = f_of(innov, prev_e)
        P = P / f
        out["x_prior"][k], out["x"][k], out["P"][k] = xm, x, P
        out["innov"][k], out["nis"][k], out["f"][k] = innov, float(innov @ np.linalg.solve(Pyy, innov)), f
    return out
