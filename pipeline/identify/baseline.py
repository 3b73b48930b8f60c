"""FFM-UKF baseline: filterpy's UnscentedKalmanFilter with MerweScaledSigmaPoints, same model,
settings and fuzzy forgetting factor as the SR-UKF-FFM, applied to its covariance (P <- P / f).

filterpy takes a Cholesky factor of (n + lambda) P at every step; when P has lost positive
definiteness through round-off it fails with "leading minor not positive definite".  Such failures
are counted, not hidden: the factorisation is retried on the nearest positive-definite matrix
(symmetrised, eigenvalues clipped) and the count goes into the trace and estimates.json.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

from pipeline.errors import FilterError
from pipeline.identify.fuzzy import forgetting_factor


class CountingCholesky:
    """scipy's upper Cholesky factor (what filterpy uses by default) that counts and repairs failures."""

    def __init__(self):
        self.failures = 0

    def __call__(self, A):
        try:
            return scipy.linalg.cholesky(A)
        except np.linalg.LinAlgError:
            self.failures += 1
            B = 0.5 * (A + A.T)
            w, V = np.linalg.eigh(B)
            if not np.all(np.isfinite(w)):
                raise FilterError("filterpy UKF: covariance is not finite") from None
            floor = max(1e-12 * float(np.max(np.abs(w))), 1e-300)
            B = (V * np.maximum(w, floor)) @ V.T
            try:
                return scipy.linalg.cholesky(0.5 * (B + B.T))
            except np.linalg.LinAlgError:
                raise FilterError("filterpy UKF: covariance could not be repaired to positive definite"
                                  ) from None


def _fx(x, dt, delta=0.0):
    v, r, psi, a11, a12, a21, a22, b11, b21 = x
    out = x.copy()
    out[0] = v + dt * (a11 * v + a12 * r + b11 * delta)
    out[1] = r + dt * (a21 * v + a22 * r + b21 * delta)
    out[2] = psi + dt * r
    return out


def make_filter(x0, P0, *, h: float, q_std, r_std, meas_idx, alpha: float, beta: float, kappa: float):
    """A filterpy UKF for the augmented model.

    Parameters
    ----------
    x0, P0 : array_like
        Initial posterior (9,), (9, 9) (v m/s, r deg/s, psi deg, the parameters in their units).
    h : float
        Step, s.
    q_std : sequence of float
        (9,) one-sigma process noise per step (each state's unit); Q is diagonal.
    r_std : sequence of float
        (m,) one-sigma measurement noise of the measured channels; R is diagonal.
    meas_idx : sequence of int
        The measured states among (v, r, psi) = (0, 1, 2).
    alpha, beta, kappa : float
        Merwe's sigma-point spread, prior-knowledge and secondary scaling (dimensionless).

    Returns
    -------
    (filterpy.kalman.UnscentedKalmanFilter, CountingCholesky)
        The filter and its Cholesky failure counter.
    """
    chol = CountingCholesky()
    pts = MerweScaledSigmaPoints(9, alpha=alpha, beta=beta, kappa=kappa, sqrt_method=chol)
    idx = np.asarray(meas_idx)
    ukf = UnscentedKalmanFilter(dim_x=9, dim_z=len(idx), dt=h, hx=lambda x: x[idx], fx=_fx, points=pts)
    ukf.x = np.array(x0, dtype=float)
    ukf.P = np.array(P0, dtype=float)
    ukf.Q = np.diag(np.asarray(q_std, float) ** 2)
    ukf.R = np.diag(np.asarray(r_std, float) ** 2)
    return ukf, chol


def run_ffm_ukf(ukf, chol, Y, delta_prev, *, fuzzy_cfg=None, chan: int = -1):
    """Run the baseline over Y (N, m) with rudder delta_prev (N,).  Returns a dict of arrays
    (x_prior, x, std, innov, nis, f, chol_failures cumulative) and the final x, P."""
    n, m = Y.shape
    out = {"x_prior": np.empty((n, 9)), "x": np.empty((n, 9)), "std": np.empty((n, 9)),
           "innov": np.empty((n, m)), "nis": np.empty(n), "f": np.ones(n),
           "chol_failures": np.zeros(n, dtype=np.int64)}
    prev_e = 0.0
    for k in range(n):
        ukf.predict(delta=float(delta_prev[k]))
        out["x_prior"][k] = ukf.x
        ukf.update(Y[k])
        y = ukf.y
        f = 1.0
        if fuzzy_cfg is not None and chan >= 0:
            e = float(y[chan])
            f = forgetting_factor(e, e - prev_e, fuzzy_cfg)
            prev_e = e
            ukf.P = ukf.P / f
        if not np.all(np.isfinite(ukf.x)):
            raise FilterError(f"filterpy UKF: state is not finite at step {k}")
        out["x"][k] = ukf.x
        out["std"][k] = np.sqrt(np.maximum(np.diag(ukf.P), 0.0))
        out["innov"][k] = y
        out["nis"][k] = float(y @ ukf.SI @ y)
        out["f"][k] = f
        out["chol_failures"][k] = chol.failures
    return out, ukf.x.copy(), ukf.P.copy()


