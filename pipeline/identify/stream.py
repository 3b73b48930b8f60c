"""Streaming SR-UKF-FFM: the identifier fed one sample at a time (docs/control.md, "Identification in
the loop").

``StreamingIdentifier.update(sample)`` runs the same compiled kernel as the batch path
(:func:`pipeline.identify.fast.srukf_steps`) over that one sample, keeping the posterior (x, S) and the
fuzzy channel's previous innovation in its own workspace, so N calls equal one batch run over the N
samples, sample for sample.  ``estimate()`` returns the current parameters, their covariance and the
Nomoto indices (Eq. 6) where they exist.

A sample is a mapping with ``delta`` (deg, the rudder held over the step INTO this sample, as the batch
path's ``delta_prev``) and the measured ``v`` (m/s; NaN or absent when not measured), ``r`` (deg/s),
``psi`` (deg).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pipeline.config import FilterConfig
from pipeline.errors import FilterError, InputError, ModelError
from pipeline.identify import fast
from pipeline.identify.core import _FAIL_WHAT, kernel_settings
from pipeline.model import PARAM_NAMES, nomoto_indices


class StreamingIdentifier:
    """SR-UKF-FFM over samples given one at a time.

    Parameters
    ----------
    x0 : (9,) initial posterior mean (v m/s, r deg/s, psi deg, a11 ... b21).
    P0 : (9, 9) initial posterior covariance (same units squared).
    h : model step, s.
    cfg : filter settings (Q, R of the measured channels, fuzzy forgetting, UT spread).
    meas_idx : measured states among (v, r, psi) = (0, 1, 2).
    """

    def __init__(self, x0, P0, h: float, cfg: FilterConfig | None = None, meas_idx=(0, 1, 2)):
        cfg = cfg or FilterConfig()
        if not h > 0:
            raise InputError(f"model step h = {h} s must be > 0")
        self.cfg, self.h = cfg, float(h)
        self.meas_idx = np.asarray(meas_idx, dtype=np.int64)
        m = self.meas_idx.size
        self.x = np.array(x0, dtype=float).reshape(9)
        try:
            self.S = np.linalg.cholesky(np.asarray(P0, dtype=float))
        except np.linalg.LinAlgError:
            raise FilterError("initial covariance is not positive definite") from None
        settings = kernel_settings(cfg, self.meas_idx, self.h)
        self.sq_q, self.sq_r = settings.model.sq_q, settings.model.sq_r
        self._p = settings.steps_tuple()
        self._ws = fast.workspace(m)
        self._out = (np.empty((1, 9)), np.empty((1, 9)), np.empty((1, 9)), np.empty((1, m)), np.empty(1),
                     np.empty(1))
        self.steps = 0
        self.last: dict[str, Any] = {}

    def update(self, sample) -> dict[str, Any]:
        """Take one sample (module docstring); returns its innovation, NIS and forgetting factor."""
        try:
            y = np.array([[float(sample[("v", "r", "psi")[i]]) if ("v", "r", "psi")[i] in sample
                           else np.nan for i in self.meas_idx]])
            dp = np.array([float(sample["delta"])])
        except (KeyError, TypeError, ValueError):
            raise InputError(f"sample {self.steps}: needs numbers 'delta' and "
                             f"{', '.join(('v', 'r', 'psi')[i] for i in self.meas_idx)}") from None
        if not np.all(np.isfinite(y)) or not np.isfinite(dp[0]):
            raise InputError(f"sample {self.steps}: NaN or infinite measurement or rudder")
        st, _ = fast.srukf_steps(self.x, self.S, (y, dp), self._p, self._ws, self._out)
        if st != 0:
            raise FilterError(f"SR-UKF {_FAIL_WHAT[st]} failed at streamed sample {self.steps}: covariance "
                              "lost positive definiteness")
        self.steps += 1
        _, _, _, innov, nis, f = self._out
        self.last = {"innov": innov[0].copy(), "nis": float(nis[0]), "f": float(f[0])}
        return self.last

    def estimate(self) -> dict[str, Any]:
        """Current posterior: state (v, r, psi), parameters (order and units of
        docs/contract.md#the-identification-model), their 6 x 6 covariance, the Nomoto indices K (1/s), T1,
        T2, T3, T (s) or None where they do not exist."""
        theta = self.x[3:].copy()
        try:
            idx = nomoto_indices(theta)
        except ModelError:
            idx = None
        P = self.S @ self.S.T
        return {"state": self.x[:3].copy(),
                "parameters": dict(zip(PARAM_NAMES, map(float, theta), strict=True)),
                "covariance": P[3:, 3:].copy(), "indices": idx, "steps": self.steps}
