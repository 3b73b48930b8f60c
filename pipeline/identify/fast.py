"""Numba kernel of the SR-UKF-FFM: the same maths as :mod:`.srukf`, step by step, allocation-free.

Every work array is allocated once per call (:func:`workspace`), never inside the per-step loop: the
kernel makes no heap allocation per step (issue 12).  QR is a Householder triangularisation of the
small (2L + L) x L matrix written out here (faster than a LAPACK call at this size), stored
transposed so that every inner loop runs along contiguous memory; zero columns of the square root of
Q (the six parameters have no process noise) are left out of the QR, where they would only add
zeros.  Everything else mirrors the reference path and the tests compare the two to round-off
(tests/test_srukf.py, tests/test_identify.py).

The paper's filter (the six parameters a random walk without process noise, v r psi measured) runs
a structured step (:func:`_steps_rw`, issue 12 item 4): the parameter rows of the propagated sigma
points are known (the prior's), so each +-pair of columns of the compound matrix is rotated into one
column carrying them and one with zero parameter rows; the prior factor is then a 9 x 12 QR instead
of 9 x 22, and the measurement update, linear in the state, needs neither sigma points nor a second
factor of 22 columns.  Same sigma points (same factor, same state order), equal in exact arithmetic;
tests/test_srukf.py holds it to the plain step to 1e-12 over a whole identification.  Measured and
dropped there: the state reordered parameters-first (a 3-row QR would do, but the sigma points of
another square root of P are another unscented transform: up to 3 % apart on var(v) for this
bilinear model, not round-off); ``inline="always"`` on the QR and the downdates (0.92x).

No fastmath: the additions run in the written order, so results are the same bits on every run and
worker.  Measured and dropped (issue 12): the QR with the state as contiguous 4-wide lanes and the
partial sums in a work array (same bits, but 0.75-0.9x: the sums live in memory, not registers).

Status codes returned by the kernels: 0 ok; 1 time-update downdate failed; 2 innovation-factor
downdate failed; 3 measurement-update downdate failed; the failing step is returned beside it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from pipeline.identify.fuzzy import fuzzy_factor_ws

NX = 9
NPTS = 2 * NX + 1
NP = 6          # parameters (a11 a12 a21 a22 b11 b21): random walk
ND = 3          # dynamic states (v r psi)


@njit(cache=True, error_model="numpy", inline="always")
def _f3(v, r, psi, a11, a12, a21, a22, b11, b21, delta, h):
    """The model's step (SPEC section 5) for one point: (v, r, psi) after h s with rudder delta."""
    return (v + h * (a11 * v + a12 * r + b11 * delta),
            r + h * (a21 * v + a22 * r + b21 * delta),
            psi + h * r)


@njit(cache=True, error_model="numpy")
def _fx(X, npts, delta, h, out):
    for i in range(npts):
        out[0, i], out[1, i], out[2, i] = _f3(X[0, i], X[1, i], X[2, i], X[3, i], X[4, i], X[5, i],
                                              X[6, i], X[7, i], X[8, i], delta, h)
        for j in range(3, NX):
            out[j, i] = X[j, i]


@njit(cache=True, error_model="numpy")
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
        ic = lkk / r            # 1 / c: one division per column instead of one per entry
        t = x[k] / lkk
        st = sign * t
        L[k, k] = r
        for i in range(k + 1, n):
            lik = (L[i, k] + st * x[i]) * ic
            L[i, k] = lik
            x[i] = c * x[i] - t * lik
    return True


@njit(cache=True, error_model="numpy", inline="always")
def _dot(A, j, k, lo, hi):
    """sum_{i=lo}^{hi-1} A[j, i] A[k, i] with four partial sums (breaks the add-latency chain; the
    order of the additions differs from a plain loop by round-off only).  Inlined into its caller
    at numba's level (``inline="always"``): called 36 times per QR, a real call cost ~15 % of the
    whole step (measured, same bits either way)."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    i = lo
    while i + 4 <= hi:
        s0 += A[j, i] * A[k, i]
        s1 += A[j, i + 1] * A[k, i + 1]
        s2 += A[j, i + 2] * A[k, i + 2]
        s3 += A[j, i + 3] * A[k, i + 3]
        i += 4
    while i < hi:
        s0 += A[j, i] * A[k, i]
        i += 1
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, error_model="numpy")
def _tria_t(A, m, out):
    """A (n, >= m): the first m columns are overwritten.  Writes lower S (n, n) with S S^T = A A^T
    (over those m columns), positive diagonal: Householder QR of A^T, row j of A = column j of A^T."""
    n = A.shape[0]
    for j in range(n):
        norm2 = _dot(A, j, j, j, m)
        norm = math.sqrt(norm2)
        if norm == 0.0:
            continue
        ajj = A[j, j]
        alpha = -norm if ajj >= 0.0 else norm
        v0 = ajj - alpha
        vnorm2 = norm2 - ajj * ajj + v0 * v0
        if vnorm2 == 0.0:
            continue
        A[j, j] = v0            # Householder vector stored in row j (columns j..m-1)
        two_over = 2.0 / vnorm2
        for k in range(j + 1, n):
            s = two_over * _dot(A, j, k, j, m)
            for i in range(j, m):
                A[k, i] -= s * A[j, i]
        A[j, j] = alpha
    for i in range(n):
        sg = -1.0 if A[i, i] < 0.0 else 1.0
        for j in range(n):
            out[j, i] = sg * A[j, i] if j >= i else 0.0


def _tria(M, n, out):
    """Lower S (n, n) with S S^T = M^T M for M (m, n) (test helper: the kernel calls :func:`_tria_t`)."""
    _tria_t(np.ascontiguousarray(np.asarray(M, dtype=float).T), M.shape[0], out)


@njit(cache=True, error_model="numpy")
def _factor(D, npts, sq_noise, noise_cols, wc, A, x, out):
    """Lower factor of sum_{i>=1} wc_i D_i D_i^T + N N^T + wc_0 D_0 D_0^T.

    ``noise_cols`` lists the non-zero columns of N (the others add nothing).  Point 0 joins the QR as
    one more column when wc_0 > 0 (the same factor as the reference path's rank-one update, without
    its n square roots and divisions in a chain); a negative wc_0 is a downdate, done by cholupdate
    after the QR as in the reference path.  A (n, >= npts + len(noise_cols)) and x (n,) are work
    arrays."""
    n = D.shape[0]
    s1 = math.sqrt(wc[1])
    nc = noise_cols.shape[0]
    cols = npts - 1 + nc
    w0 = wc[0]
    s0 = math.sqrt(abs(w0))
    for j in range(n):
        aj = A[j]
        dj = D[j]
        for i in range(1, npts):
            aj[i - 1] = s1 * dj[i]
        for c in range(nc):
            aj[npts - 1 + c] = sq_noise[j, noise_cols[c]]
        if w0 > 0.0:
            aj[cols] = s0 * dj[0]
    _tria_t(A, cols + 1 if w0 > 0.0 else cols, out)
    if w0 < 0.0:
        for j in range(n):
            x[j] = s0 * D[j, 0]
        return _cholupdate(out, x, -1.0)
    return True


def nonzero_columns(M: np.ndarray) -> np.ndarray:
    """Indices of the columns of M holding a non-zero entry (int64)."""
    return np.flatnonzero(np.any(np.asarray(M) != 0.0, axis=0)).astype(np.int64)


@njit(cache=True, error_model="numpy")
def workspace(m):
    """Every work array of :func:`srukf_steps` for m measured channels, allocated once."""
    return (np.empty((NX, NPTS)), np.empty((NX, NPTS)), np.empty(NX), np.empty((NX, NX)),
            np.empty((NX, NPTS + NX)), np.empty((m, NPTS + m)), np.empty((m, NPTS)),
            np.empty(m), np.empty((m, m)), np.empty((NX, m)), np.empty((m, NX)), np.empty((NX, m)),
            np.empty(m), np.empty(NX), np.empty(m), np.empty(NX), np.empty(m), np.empty(5), np.empty(5),
            np.empty(NX), np.empty((NX, NX)), np.empty((ND, NPTS)), np.empty((ND, NPTS + NX)),
            np.empty((ND, ND)), np.empty(ND), np.empty((m, ND + m)))


@njit(cache=True, error_model="numpy")
def _steps_plain(x, S, Y, delta_prev, h, sq_q, q_cols, sq_r, r_cols, meas_idx, wm, wc, gamma,
                 use_fuzzy, chan, fz, rules, ws,
                 x_prior_out, x_out, std_out, innov_out, nis_out, f_out):
    """The SR-UKF-FFM step by step as written in :mod:`.srukf` (any Q, any measured states)."""
    X, Xp, xm, Sm, Ax, Ay, DY, ym, Sy, Pxy, Z, K, innov, u, zt, xw, yw, me, md, _, _, _, _, _, _, _ = ws
    n = Y.shape[0]
    m = Y.shape[1]
    npts = NPTS
    prev_e = 0.0
    for k in range(n):
        # ---- time update
        for i in range(NX):
            xi = x[i]
            X[i, 0] = xi
            for j in range(NX):
                X[i, 1 + j] = xi + gamma * S[i, j]
                X[i, 1 + NX + j] = xi - gamma * S[i, j]
        _fx(X, npts, delta_prev[k], h, Xp)
        for i in range(NX):          # xm = Xp wm: the nine sums run side by side, each in point order
            xm[i] = 0.0
        for p in range(npts):
            wp = wm[p]
            for i in range(NX):
                xm[i] += wp * Xp[i, p]
        for i in range(NX):
            for p in range(npts):
                Xp[i, p] -= xm[i]
        if not _factor(Xp, npts, sq_q, q_cols, wc, Ax, xw, Sm):
            return 1, k
        # ---- measurement update: redraw sigma points from (xm, Sm); DX = X - xm = +-gamma Sm
        for i in range(NX):
            X[i, 0] = 0.0
            for j in range(NX):
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
        if not _factor(DY, npts, sq_r, r_cols, wc, Ay, yw, Sy):
            return 2, k
        # Pxy = sum_p wc_p DX_p DY_p^T with DX_0 = 0, DX_{1+c} = -DX_{1+NX+c} = gamma Sm[:, c] (Sm lower
        # triangular: c <= i) and equal weights wc_1 = ... = wc_2L
        for a in range(m):
            for i in range(NX):
                Pxy[i, a] = 0.0
            for c in range(NX):
                dd = DY[a, 1 + c] - DY[a, 1 + NX + c]
                for i in range(c, NX):
                    Pxy[i, a] += Sm[i, c] * dd
            for i in range(NX):
                Pxy[i, a] *= wc[1] * gamma
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
        for i in range(NX):
            for j in range(NX):
                S[i, j] = Sm[i, j]
        for a in range(m):
            for i in range(NX):
                acc = 0.0
                for b in range(a, m):
                    acc += K[i, b] * Sy[b, a]
                u[i] = acc
            if not _cholupdate(S, u, -1.0):
                return 3, k
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
            f = fuzzy_factor_ws(e, e - prev_e, fz[0], fz[1], fz[2], fz[3], fz[4], fz[5], rules, me, md)
            prev_e = e
            sc = 1.0 / math.sqrt(f)
            for i in range(NX):
                for j in range(i + 1):
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
    return 0, n


@njit(cache=True, error_model="numpy")
def _downdate_columns(L, U, m):
    """In place: L L^T - sum_a U[a] U[a]^T by m rank-one downdates (:func:`_cholupdate`, sign -1) of
    the rows of U (overwritten).  Column by column with the m downdates inside: every entry sees the
    same operations in the same order as m downdates one after the other (downdate a at column k uses
    column k after downdates 0..a-1 and its own vector after columns 0..k-1; nothing else), so the
    bits are those of the sequential loop, but the m square-root/division chains overlap (measured:
    the whole step 1.62 against 1.82 us with m sequential :func:`_cholupdate` calls, identical
    outputs).  False when a downdate fails."""
    n = L.shape[0]
    for k in range(n):
        for a in range(m):
            lkk = L[k, k]
            uk = U[a, k]
            r2 = lkk * lkk - uk * uk
            if not (r2 > 0.0) or not (lkk > 0.0):
                return False
            r = math.sqrt(r2)
            c = r / lkk
            ic = lkk / r
            t = uk / lkk
            st = -t
            L[k, k] = r
            for i in range(k + 1, n):
                lik = (L[i, k] + st * U[a, i]) * ic
                L[i, k] = lik
                U[a, i] = c * U[a, i] - t * lik
    return True


@njit(cache=True, error_model="numpy")
def _steps_rw(x, S, Y, delta_prev, h, sq_q, q_cols, sq_r, r_cols, meas_idx, wm, wc, gamma,
              use_fuzzy, chan, fz, rules, ws,
              x_prior_out, x_out, std_out, innov_out, nis_out, f_out):
    """:func:`_steps_plain` when the parameters are a random walk without process noise and only v,
    r, psi are measured (the paper's filter): the same sigma points (from the same lower factor S,
    states in the same order), equal in exact arithmetic, with the work the structure makes known in
    advance left out.  Proof (ALGORITHMS.md, square-root UKF):

    Time update.  The model keeps the parameters, so the parameter rows of the propagated deviations
    are +-gamma S_p[:, j] (S_p = rows 3..8 of S) and their mean is x_p (symmetric weights summing
    to 1).  An orthogonal rotation of each pair of columns (+j, -j) of the compound matrix
    [sqrt(wc1) D_1..2L, sqrt(Q), sqrt(wc0) D_0] (it leaves A A^T unchanged) gives, as
    sqrt(2 wc1) gamma = 1, the column [sqrt(wc1 / 2) (D+j - D-j)_d; S_p[:, j]] and the column
    [sqrt(wc1 / 2) (D+j + D-j)_d; 0].  The 9 + q + 1 columns with zero parameter rows are first
    reduced by a 3-row QR to 3 columns; the prior factor is then the QR of a 9 x 12 matrix instead
    of 9 x 22 (the lower factor with a positive diagonal is unique, so it is the plain QR's).
    Measurement update.  h(x) picks states, so the redrawn sigma points give exactly ym = H xm,
    Sy = tria([H Sm, sqrt R]) with H Sm = rows of the leading 3 x 3 block of Sm, Pxy = Sm (H Sm)^T;
    the downdate vectors U = K Sy = Pxy Sy^-T come from one forward solve, and
    x = xm + U (Sy^-1 innov), Sy^-1 innov being the NIS's solve already."""
    (X, Xp, xm, Sm, Ax, Ay, DY, ym, Sy, Pxy, Z, K, innov, u, zt, xw, yw, me, md,
     xq, Sq, Xd, Ad, Ld, dw, Ayq) = ws
    n = Y.shape[0]
    m = Y.shape[1]
    nq = q_cols.shape[0]
    nr = r_cols.shape[0]
    sh = math.sqrt(0.5 * wc[1])
    w0 = wc[0]
    s0 = math.sqrt(abs(w0))
    ncol = NX + nq + (1 if w0 > 0.0 else 0)
    prev_e = 0.0
    for k in range(n):
        dl = delta_prev[k]
        # ---- time update: sigma points through the model, dynamic rows only (Xd[:, p], p as in X)
        Xd[0, 0], Xd[1, 0], Xd[2, 0] = _f3(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8], dl, h)
        for j in range(NX):
            g0 = gamma * S[0, j]
            g1 = gamma * S[1, j]
            g2 = gamma * S[2, j]
            g3 = gamma * S[3, j]
            g4 = gamma * S[4, j]
            g5 = gamma * S[5, j]
            g6 = gamma * S[6, j]
            g7 = gamma * S[7, j]
            g8 = gamma * S[8, j]
            Xd[0, 1 + j], Xd[1, 1 + j], Xd[2, 1 + j] = _f3(
                x[0] + g0, x[1] + g1, x[2] + g2, x[3] + g3, x[4] + g4, x[5] + g5, x[6] + g6, x[7] + g7,
                x[8] + g8, dl, h)
            Xd[0, 1 + NX + j], Xd[1, 1 + NX + j], Xd[2, 1 + NX + j] = _f3(
                x[0] - g0, x[1] - g1, x[2] - g2, x[3] - g3, x[4] - g4, x[5] - g5, x[6] - g6, x[7] - g7,
                x[8] - g8, dl, h)
        for i in range(ND):
            acc = 0.0
            for p in range(NPTS):
                acc += wm[p] * Xd[i, p]
            xm[i] = acc
            for p in range(NPTS):
                Xd[i, p] -= acc
        for i in range(ND, NX):
            xm[i] = x[i]
        # the rotated compound: Ax (9 x 12) = [[M_d, L_N], [S_p, 0]]; Ad (3 x ncol) the columns with
        # zero parameter rows, reduced to L_N (3 x 3) by QR
        for i in range(ND):
            ai = Ad[i]
            di = Xd[i]
            axi = Ax[i]
            for j in range(NX):
                axi[j] = sh * (di[1 + j] - di[1 + NX + j])
                ai[j] = sh * (di[1 + j] + di[1 + NX + j])
            for c in range(nq):
                ai[NX + c] = sq_q[i, q_cols[c]]
            if w0 > 0.0:
                ai[ncol - 1] = s0 * di[0]
        _tria_t(Ad, ncol, Ld)
        for i in range(ND):
            for c in range(ND):
                Ax[i, NX + c] = Ld[i, c]
        for i in range(ND, NX):
            for j in range(NX):
                Ax[i, j] = S[i, j]
            for c in range(ND):
                Ax[i, NX + c] = 0.0
        _tria_t(Ax, NX + ND, Sm)
        if w0 < 0.0:
            for i in range(ND):
                xw[i] = s0 * Xd[i, 0]
            for i in range(ND, NX):
                xw[i] = 0.0
            if not _cholupdate(Sm, xw, -1.0):
                return 1, k
        # ---- measurement update (linear in the state: see the docstring)
        for a in range(m):
            ra = meas_idx[a]
            for c in range(ND):
                Ayq[a, c] = Sm[ra, c]
            for c in range(nr):
                Ayq[a, ND + c] = sq_r[a, r_cols[c]]
        _tria_t(Ayq, ND + nr, Sy)
        # Z = Sy^-1 Pxy^T, Pxy = Sm (H Sm)^T; row a of Z is column a of U = K Sy
        for a in range(m):
            ra = meas_idx[a]
            for i in range(NX):
                acc = 0.0
                for c in range(min(i, ra) + 1):
                    acc += Sm[i, c] * Sm[ra, c]
                for b in range(a):
                    acc -= Sy[a, b] * Z[b, i]
                Z[a, i] = acc / Sy[a, a]
        nis = 0.0
        for a in range(m):
            innov[a] = Y[k, a] - xm[meas_idx[a]]
            acc = innov[a]
            for b in range(a):
                acc -= Sy[a, b] * zt[b]
            zt[a] = acc / Sy[a, a]
            nis += zt[a] * zt[a]
        for i in range(NX):
            acc = xm[i]
            for a in range(m):
                acc += Z[a, i] * zt[a]
            x_prior_out[k, i] = xm[i]
            x[i] = acc
        for i in range(NX):
            for j in range(i + 1):
                S[i, j] = Sm[i, j]
        if not _downdate_columns(S, Z, m):
            return 3, k
        f = 1.0
        if use_fuzzy and chan >= 0:
            e = innov[chan]
            f = fuzzy_factor_ws(e, e - prev_e, fz[0], fz[1], fz[2], fz[3], fz[4], fz[5], rules, me, md)
            prev_e = e
            sc = 1.0 / math.sqrt(f)
            for i in range(NX):
                for j in range(i + 1):
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
    return 0, n


@njit(cache=True, error_model="numpy")
def _structured(sq_q, meas_idx):
    """True when the parameters have no process noise and only v, r, psi are measured."""
    for i in range(ND, NX):
        for j in range(NX):
            if sq_q[i, j] != 0.0:
                return False
    for a in range(meas_idx.shape[0]):
        if meas_idx[a] < 0 or meas_idx[a] >= ND:
            return False
    return True


@njit(cache=True, error_model="numpy")
def srukf_steps(x, S, Y, delta_prev, h, sq_q, q_cols, sq_r, r_cols, meas_idx, wm, wc, gamma,
                use_fuzzy, chan, fz, rules, ws,
                x_prior_out, x_out, std_out, innov_out, nis_out, f_out):
    """Run the SR-UKF-FFM over the N samples of Y, updating the posterior (x, S) in place.

    ``ws`` is :func:`workspace` (m); q_cols / r_cols the non-zero columns of sq_q / sq_r
    (:func:`nonzero_columns`).  No allocation happens here.  Returns (status, step).
    The paper's filter (parameters without process noise, v r psi measured) runs
    :func:`_steps_rw`; any other Q runs :func:`_steps_plain`.
    """
    if not _structured(sq_q, meas_idx):
        return _steps_plain(x, S, Y, delta_prev, h, sq_q, q_cols, sq_r, r_cols, meas_idx, wm, wc, gamma,
                            use_fuzzy, chan, fz, rules, ws,
                            x_prior_out, x_out, std_out, innov_out, nis_out, f_out)
    return _steps_rw(x, S, Y, delta_prev, h, sq_q, q_cols, sq_r, r_cols, meas_idx, wm, wc, gamma,
                     use_fuzzy, chan, fz, rules, ws,
                     x_prior_out, x_out, std_out, innov_out, nis_out, f_out)


@njit(cache=True, error_model="numpy")
def srukf_kernel(x0, S0, Y, delta_prev, h, sq_q, sq_r, meas_idx, wm, wc, gamma,
                 use_fuzzy, chan, fz, rules,
                 x_prior_out, x_out, std_out, innov_out, nis_out, f_out):
    """Run the SR-UKF-FFM over N samples from posterior (x0, S0).

    Y (N, m) measurements; delta_prev (N,) rudder over the step into each sample, deg; h s;
    sq_q (9, 9), sq_r (m, m) square roots of Q and R; meas_idx (m,) measured state indices;
    wm, wc, gamma weights; use_fuzzy; chan = position in meas_idx of the fuzzy channel (-1: none);
    fz = (e_lo, e_hi, de_lo, de_hi, f_lo, f_hi); rules (5, 5).
    Outputs (filled in place, N rows): x_prior, x, std (one-sigma of x), innov, nis, f.
    Returns (status, step, x, S).  Work arrays are allocated once here, none per step.
    """
    x = x0.copy()
    S = S0.copy()
    ws = workspace(Y.shape[1])
    q_cols = _nonzero_cols(sq_q)
    r_cols = _nonzero_cols(sq_r)
    st, k = srukf_steps(x, S, Y, delta_prev, h, sq_q, q_cols, sq_r, r_cols, meas_idx, wm, wc, gamma,
                        use_fuzzy, chan, fz, rules, ws,
                        x_prior_out, x_out, std_out, innov_out, nis_out, f_out)
    return st, k, x, S


@njit(cache=True, error_model="numpy")
def _nonzero_cols(M):
    cnt = 0
    for j in range(M.shape[1]):
        for i in range(M.shape[0]):
            if M[i, j] != 0.0:
                cnt += 1
                break
    out = np.empty(cnt, dtype=np.int64)
    c = 0
    for j in range(M.shape[1]):
        for i in range(M.shape[0]):
            if M[i, j] != 0.0:
                out[c] = j
                c += 1
                break
    return out


@njit(cache=True, error_model="numpy")
def _batch_range(lo, hi, x0s, S0, Ys, deltas_prev, h, sq_q, q_cols, sq_r, r_cols, meas_idx, wm, wc, gamma,
                 use_fuzzy, chan, fz, rules, x_final, S_final, status):
    n = Ys.shape[1]
    m = Ys.shape[2]
    ws = workspace(m)
    xp = np.empty((n, NX))
    xo = np.empty((n, NX))
    so = np.empty((n, NX))
    io = np.empty((n, m))
    ni = np.empty(n)
    fo = np.empty(n)
    x = np.empty(NX)
    S = np.empty((NX, NX))
    for r in range(lo, hi):
        x[:] = x0s[r]
        S[:, :] = S0
        st, _ = srukf_steps(x, S, Ys[r], deltas_prev[r], h, sq_q, q_cols, sq_r, r_cols, meas_idx, wm, wc,
                            gamma, use_fuzzy, chan, fz, rules, ws, xp, xo, so, io, ni, fo)
        status[r] = st
        x_final[r] = x
        S_final[r] = S


@njit(cache=True, error_model="numpy")
def srukf_batch_kernel(x0s, S0, Ys, deltas_prev, h, sq_q, sq_r, meas_idx, wm, wc, gamma,
                       use_fuzzy, chan, fz, rules, x_final, S_final, status):
    """Run the kernel over R runs of equal length: Ys (R, N, m), deltas_prev (R, N), x0s (R, 9).

    Writes the final posterior of each run into x_final (R, 9), S_final (R, 9, 9), and its status.
    Serial; one workspace for all runs.
    """
    _batch_range(0, Ys.shape[0], x0s, S0, Ys, deltas_prev, h, sq_q, _nonzero_cols(sq_q), sq_r,
                 _nonzero_cols(sq_r), meas_idx, wm, wc, gamma, use_fuzzy, chan, fz, rules,
                 x_final, S_final, status)


@njit(cache=True, parallel=True, error_model="numpy")
def srukf_batch_kernel_parallel(x0s, S0, Ys, deltas_prev, h, sq_q, sq_r, meas_idx, wm, wc, gamma,
                                use_fuzzy, chan, fz, rules, x_final, S_final, status, chunks):
    """:func:`srukf_batch_kernel` with the runs split into ``chunks`` contiguous blocks run on numba's
    threads (one workspace per block).  Each run's numbers are those of the serial kernel: runs are
    independent and each is computed by the same serial code."""
    nr = Ys.shape[0]
    q_cols = _nonzero_cols(sq_q)
    r_cols = _nonzero_cols(sq_r)
    for c in prange(chunks):
        lo = (nr * c) // chunks
        hi = (nr * (c + 1)) // chunks
        _batch_range(lo, hi, x0s, S0, Ys, deltas_prev, h, sq_q, q_cols, sq_r, r_cols, meas_idx, wm, wc,
                     gamma, use_fuzzy, chan, fz, rules, x_final, S_final, status)
