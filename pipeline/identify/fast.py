"""Numba kernel of the SR-UKF-FFM: the same maths as :mod:`.srukf`, step by step, without allocations
in the inner loop.  QR is a Householder triangularisation of the small (2L + L) x L matrix written
out here (faster than a LAPACK call at this size); everything else mirrors the reference path and
the tests compare the two to round-off.

Status codes returned by the kernels: 0 ok; 1 time-update downdate failed; 2 innovation-factor
downdate failed; 3 measurement-update downdate failed; the failing step is returned beside it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from pipeline.identify.fuzzy import fuzzy_factor_nb

NX = 9


@njit(cache=True)
def _fx(X, npts, delta, h, out):
    for i in range(npts):
        v = X[0, i]
        r = X[1, i]
        out[0, i] = v + h * (X[3, i] * v + X[4, i] * r + X[7, i] * delta)
        out[1, i] = r + h * (X[5, i] * v + X[6, i] * r + X[8, i] * delta)
        out[2, i] = X[2, i] + h * r
        for j in range(3, NX):
            out[j, i] = X[j, i]


@njit(cache=True)
def _cholupdate(L, x, sign):
    """In place: L L^T + sign x x^T (x is overwritten).  Returns False when a downdate fails."""
    n = L.shape[0]
    for k in range(n):
        lkk = L[k, k]
        r2 = lkk * lkk + sign * x[k] * x[k]
        if not (r2 > 0.0) or not (lkk > 0.0):
            return False
        r = math.sqrt(r2)
        c = r / lkk
        t = x[k] / lkk
        L[k, k] = r
        for i in range(k + 1, n):
            L[i, k] = (L[i, k] + sign * t * x[i]) / c
            x[i] = c * x[i] - t * L[i, k]
    return True


@njit(cache=True)
def _tria(M, n, out):
    """M (m, n) = A^T, overwritten.  Writes lower S (n, n) with S S^T = M^T M, positive diagonal."""
    m = M.shape[0]
    for j in range(n):
        norm2 = 0.0
        for i in range(j, m):
            norm2 += M[i, j] * M[i, j]
        norm = math.sqrt(norm2)
        if norm == 0.0:
            continue
        alpha = -norm if M[j, j] >= 0.0 else norm
        v0 = M[j, j] - alpha
        vnorm2 = norm2 - M[j, j] * M[j, j] + v0 * v0
        if vnorm2 == 0.0:
            continue
        M[j, j] = v0            # Householder vector stored in column j (rows j..m-1)
        for k in range(j + 1, n):
            dot = 0.0
            for i in range(j, m):
                dot += M[i, j] * M[i, k]
            s = 2.0 * dot / vnorm2
            for i in range(j, m):
                M[i, k] -= s * M[i, j]
        M[j, j] = alpha
    for i in range(n):
        sg = -1.0 if M[i, i] < 0.0 else 1.0
        for j in range(n):
            out[j, i] = sg * M[i, j] if j >= i else 0.0


@njit(cache=True)
def _factor(D, npts, sq_noise, wc, M, out):
    """Lower factor of sum_{i>=1} wc_i D_i D_i^T + N N^T + wc_0 D_0 D_0^T (point 0 by cholupdate)."""
    n = D.shape[0]
    s1 = math.sqrt(wc[1])
    for i in range(1, npts):
        for j in range(n):
            M[i - 1, j] = s1 * D[j, i]
    for i in range(sq_noise.shape[1]):
        for j in range(n):
            M[npts - 1 + i, j] = sq_noise[j, i]
    _tria(M, n, out)
    if wc[0] != 0.0:
        s0 = math.sqrt(abs(wc[0]))
        x = np.empty(n)
        for j in range(n):
            x[j] = s0 * D[j, 0]
        return _cholupdate(out, x, 1.0 if wc[0] > 0.0 else -1.0)
    return True


@njit(cache=True)
def srukf_kernel(x0, S0, Y, delta_prev, h, sq_q, sq_r, meas_idx, wm, wc, gamma,
                 use_fuzzy, chan, fz, rules,
                 x_prior_out, x_out, std_out, innov_out, nis_out, f_out):
    """Run the SR-UKF-FFM over N samples from posterior (x0, S0).

    Y (N, m) measurements; delta_prev (N,) rudder over the step into each sample, deg; h s;
    sq_q (9, 9), sq_r (m, m) square roots of Q and R; meas_idx (m,) measured state indices;
    wm, wc, gamma weights; use_fuzzy; chan = position in meas_idx of the fuzzy channel (-1: none);
    fz = (e_lo, e_hi, de_lo, de_hi, f_lo, f_hi); rules (5, 5).
    Outputs (filled in place, N rows): x_prior, x, std (one-sigma of x), innov, nis, f.
    Returns (status, step, x, S).
    """
    n = Y.shape[0]
    m = Y.shape[1]
    npts = 2 * NX + 1
    x = x0.copy()
    S = S0.copy()
    X = np.empty((NX, npts))
    Xp = np.empty((NX, npts))
    xm = np.empty(NX)
    Sm = np.empty((NX, NX))
    Mx = np.empty((npts - 1 + NX, NX))
    My = np.empty((npts - 1 + m, m))
    DY = np.empty((m, npts))
    ym = np.empty(m)
    Sy = np.empty((m, m))
    Pxy = np.empty((NX, m))
    Z = np.empty((m, NX))
    K = np.empty((NX, m))
    innov = np.empty(m)
    u = np.empty(NX)
    zt = np.empty(m)
    prev_e = 0.0
    for k in range(n):
        # ---- time update
        for i in range(NX):
            X[i, 0] = x[i]
        for j in range(NX):
            for i in range(NX):
                X[i, 1 + j] = x[i] + gamma * S[i, j]
                X[i, 1 + NX + j] = x[i] - gamma * S[i, j]
        _fx(X, npts, delta_prev[k], h, Xp)
        for i in range(NX):
            acc = 0.0
            for p in range(npts):
                acc += wm[p] * Xp[i, p]
            xm[i] = acc
        for p in range(npts):
            for i in range(NX):
                Xp[i, p] -= xm[i]
        if not _factor(Xp, npts, sq_q, wc, Mx, Sm):
            return 1, k, x, S
        # ---- measurement update: redraw sigma points from (xm, Sm); DX = X - xm = +-gamma Sm
        for j in range(NX):
            for i in range(NX):
                X[i, 0] = 0.0
                X[i, 1 + j] = gamma * Sm[i, j]
                X[i, 1 + NX + j] = -gamma * Sm[i, j]
        for a in range(m):
            idx = meas_idx[a]
            acc = 0.0
            for p in range(npts):
                acc += wm[p] * (xm[idx] + X[idx, p])
            ym[a] = acc
            for p in range(npts):
                DY[a, p] = xm[idx] + X[idx, p] - acc
        if not _factor(DY, npts, sq_r, wc, My, Sy):
            return 2, k, x, S
        for i in range(NX):
            for a in range(m):
                acc = 0.0
                for p in range(npts):
                    acc += wc[p] * X[i, p] * DY[a, p]
                Pxy[i, a] = acc
        # K = (Pxy / Sy^T) / Sy: solve Sy Z = Pxy^T (forward), then Sy^T K^T = Z (backward)
        for c in range(NX):
            for a in range(m):
                acc = Pxy[c, a]
                for b in range(a):
                    acc -= Sy[a, b] * Z[b, c]
                Z[a, c] = acc / Sy[a, a]
            for a in range(m - 1, -1, -1):
                acc = Z[a, c]
                for b in range(a + 1, m):
                    acc -= Sy[b, a] * K[c, b]
                K[c, a] = acc / Sy[a, a]
        for a in range(m):
            innov[a] = Y[k, a] - ym[a]
        for i in range(NX):
            acc = xm[i]
            for a in range(m):
                acc += K[i, a] * innov[a]
            x_prior_out[k, i] = xm[i]
            x[i] = acc
        # S = downdate of Sm by the columns of U = K Sy
        for j in range(NX):
            for i in range(NX):
                S[i, j] = Sm[i, j]
        for a in range(m):
            for i in range(NX):
                acc = 0.0
                for b in range(a, m):
                    acc += K[i, b] * Sy[b, a]
                u[i] = acc
            if not _cholupdate(S, u, -1.0):
                return 3, k, x, S
        # NIS = |Sy^-1 innov|^2
        nis = 0.0
        for a in range(m):
            acc = innov[a]
            for b in range(a):
                acc -= Sy[a, b] * zt[b]
            zt[a] = acc / Sy[a, a]
            nis += zt[a] * zt[a]
        # fuzzy fading memory: S <- S / sqrt(f)
        f = 1.0
        if use_fuzzy and chan >= 0:
            e = innov[chan]
            f = fuzzy_factor_nb(e, e - prev_e, fz[0], fz[1], fz[2], fz[3], fz[4], fz[5], rules)
            prev_e = e
            sc = 1.0 / math.sqrt(f)
            for j in range(NX):
                for i in range(j, NX):
                    S[i, j] *= sc
        for i in range(NX):
            acc = 0.0
            for j in range(i + 1):
                acc += S[i, j] * S[i, j]
            std_out[k, i] = math.sqrt(acc)
            x_out[k, i] = x[i]
        for a in range(m):
            innov_out[k, a] = innov[a]
        nis_out[k] = nis
        f_out[k] = f
    return 0, n, x, S


@njit(cache=True)
def srukf_batch_kernel(x0s, S0, Ys, deltas_prev, h, sq_q, sq_r, meas_idx, wm, wc, gamma,
                       use_fuzzy, chan, fz, rules, x_final, S_final, status):
    """Run the kernel over R runs of equal length: Ys (R, N, m), deltas_prev (R, N), x0s (R, 9).

    Writes the final posterior of each run into x_final (R, 9), S_final (R, 9, 9), and its status.
    """
    nr = Ys.shape[0]
    n = Ys.shape[1]
    m = Ys.shape[2]
    xp = np.empty((n, NX))
    xo = np.empty((n, NX))
    so = np.empty((n, NX))
    io = np.empty((n, m))
    ni = np.empty(n)
    fo = np.empty(n)
    for r in range(nr):
        st, _, x, S = srukf_kernel(x0s[r], S0, Ys[r], deltas_prev[r], h, sq_q, sq_r, meas_idx, wm, wc,
                                   gamma, use_fuzzy, chan, fz, rules, xp, xo, so, io, ni, fo)
        status[r] = st
        x_final[r] = x
        S_final[r] = S
