"""An independent output-error fit, to show what the data allow (not the diagnosis method).

Used to check the KVLCC2 stand-in: do side-swap folds really let a richer model cut the held-out
heading error by half?  If no model can, the >= 50 % target of docs/diagnosis.md would be unfair on these
files.  Models (continuous time, docs/contract.md#run-data units, model scale)::

    v' = a11 v + a12 r + b11 (delta + d0) + sum_j Y_j phi_j(v, r)
    r' = a21 v + a22 r + b21 (delta + d0) + sum_j N_j phi_j(v, r)
    phi = (v|v|, r|r|, v^2 r, v r^2)              Abkowitz-type terms, both equations

"linear": no phi, no d0; "rich": all eight phi terms; "rich+offset": and d0.  Integration: RK4 at
half the sample step with the rudder interpolated (so no discretisation error of its own).  Fit:
prediction-error over 15 s segments, each started from the measured state (cannot diverge on a
course-unstable hull), then output-error polishing over whole runs; residuals of psi, r, v scaled by
their spread in the training runs.  Held-out figure: free-run MAE of psi on the validation runs from
the measured initial state.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.optimize import least_squares

NPHI = 4


@njit(cache=True)
def _deriv(p, v, r, d, nphi):  # pragma: no cover - compiled
    a11, a12, a21, a22, b11, b21, d0 = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    de = d + d0
    dv = a11 * v + a12 * r + b11 * de
    dr = a21 * v + a22 * r + b21 * de
    if nphi > 0:
        ph0 = v * abs(v)
        ph1 = r * abs(r)
        ph2 = v * v * r
        ph3 = v * r * r
        dv += p[7] * ph0 + p[8] * ph1 + p[9] * ph2 + p[10] * ph3
        dr += p[11] * ph0 + p[12] * ph1 + p[13] * ph2 + p[14] * ph3
    return dv, dr


@njit(cache=True)
def simulate(p, delta, h, v0, r0, psi0, nphi):  # pragma: no cover - compiled
    """Free run from (v0, r0, psi0) driven by the logged rudder; returns (n, 3) of v, r, psi."""
    n = delta.shape[0]
    out = np.empty((n, 3))
    v, r, psi = v0, r0, psi0
    hh = 0.5 * h
    for k in range(n):
        out[k, 0] = v
        out[k, 1] = r
        out[k, 2] = psi
        if k == n - 1:
            break
        d0 = delta[k]
        d1 = delta[k + 1]
        for s in range(2):
            da = d0 + (d1 - d0) * (0.5 * s)
            dm = d0 + (d1 - d0) * (0.5 * s + 0.25)
            db = d0 + (d1 - d0) * (0.5 * s + 0.5)
            k1v, k1r = _deriv(p, v, r, da, nphi)
            k2v, k2r = _deriv(p, v + 0.5 * hh * k1v, r + 0.5 * hh * k1r, dm, nphi)
            k3v, k3r = _deriv(p, v + 0.5 * hh * k2v, r + 0.5 * hh * k2r, dm, nphi)
            k4v, k4r = _deriv(p, v + hh * k3v, r + hh * k3r, db, nphi)
            psi += hh / 6.0 * (r + 2 * (r + 0.5 * hh * k1r) + 2 * (r + 0.5 * hh * k2r) + (r + hh * k3r))
            v += hh / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)
            r += hh / 6.0 * (k1r + 2 * k2r + 2 * k3r + k4r)
            if abs(r) > 1e3 or abs(v) > 1e3:
                v = min(max(v, -1e3), 1e3)
                r = min(max(r, -1e3), 1e3)
    return out


def _runs(frames):
    return [(f["time"].to_numpy(float), f["v"].to_numpy(float), f["r"].to_numpy(float),
             f["psi"].to_numpy(float), f["delta"].to_numpy(float)) for f in frames]


def _pack(p, model):
    full = np.zeros(7 + 2 * NPHI)
    full[:6] = p[:6]
    i = 6
    if model in ("rich", "rich+offset"):
        full[7:] = p[i:i + 2 * NPHI]
        i += 2 * NPHI
    if model in ("offset", "rich+offset"):
        full[6] = p[i]
    return full


def _nparams(model):
    return 6 + (2 * NPHI if model in ("rich", "rich+offset") else 0) + (1 if "offset" in model else 0)


def fit(frames, model: str = "linear", segment_s: float = 15.0, start=None):
    """Fit ``model`` on canonical frames (time, v, r, psi, delta); returns the full parameter vector."""
    runs = _runs(frames)
    nph = NPHI if model in ("rich", "rich+offset") else 0
    sc = np.array([np.std(np.concatenate([x[i] for x in runs])) for i in (1, 2, 3)])
    sc = np.where(sc > 0, sc, 1.0)

    def resid(p, seg):
        full = _pack(p, model)
        res = []
        for t, v, r, psi, d in runs:
            h = t[1] - t[0]
            m = int(round(seg / h)) if seg else len(t)
            for k in range(0, len(t) - 1, m):
                sl = slice(k, min(k + m + 1, len(t)))
                y = simulate(full, d[sl], h, v[k], r[k], psi[k], nph)
                res.append((y[:, 0] - v[sl]) / sc[0])
                res.append((y[:, 1] - r[sl]) / sc[1])
                res.append((y[:, 2] - psi[sl]) / sc[2])
        return np.concatenate(res)

    p0 = np.zeros(_nparams(model))
    if start is not None:
        p0[:6] = start[:6]
    else:
        p0[:6] = (-1.0, -0.05, -1.0, -0.5, 0.005, 0.05)
    a = least_squares(resid, p0, args=(segment_s,), x_scale="jac", max_nfev=3000)
    b = least_squares(resid, a.x, args=(None,), x_scale="jac", max_nfev=3000)
    best = b.x if b.cost <= resid(a.x, None).dot(resid(a.x, None)) / 2 else a.x
    return _pack(best, model)


def heldout_mae_psi(p, frames) -> float:
    """Mean over runs of the free-run MAE of psi (deg) from the measured initial state."""
    nph = NPHI if np.any(p[7:] != 0) else 0
    maes = []
    for t, v, r, psi, d in _runs(frames):
        y = simulate(p, d, t[1] - t[0], v[0], r[0], psi[0], nph)
        maes.append(float(np.mean(np.abs(y[:, 2] - psi))))
    return float(np.mean(maes))
