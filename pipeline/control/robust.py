"""Robustness of the sampled course-keeping loop (docs/control.md, "Sampled-loop robustness").

The loop as it runs: the autopilot samples psi and r every ``dt`` s and holds its command (zero-order
hold); the steering gear lags it by ``servo_time_constant`` s (first order) and the hull sees it
``dead_time`` s later (rounded to whole samples); the plant is a Nomoto model psi/delta =
K (1 + T3 s)/(s (1 + T1 s)(1 + T2 s)) (K 1/s, time constants s, angles deg).  Servo and hull are
discretised exactly for the held command (python-control ``c2d``, zero-order hold).

The autopilot measures two outputs (psi and r), so the loop is broken at its single input, the rudder
command: with delta = -(C_psi(z) psi + C_r(z) r) (set-point and feedforward do not enter a margin),

    L(z) = C_psi(z) P_psi(z) + C_r(z) P_r(z).

Figures: gain margin (dB; inf when the phase never crosses -180 deg), phase margin (deg), delay margin
(s; phase margin in rad over the gain crossover frequency: the extra dead time the loop can take
before it loses stability), sensitivity peak Ms = max |1/(1 + L)| up to the Nyquist frequency, and
whether the closed loop's poles lie inside the unit circle.
"""

from __future__ import annotations

import control as ct
import numpy as np
from scipy.linalg import expm

from pipeline.control.autopilot import PIDDesign
from pipeline.control.design import CGSADesign
from pipeline.errors import ModelError


def delay_steps(dead_time: float, dt: float) -> int:
    """Whole samples of dead time, round(dead_time/dt) (the simulators use the same)."""
    return int(round(float(dead_time) / float(dt)))


def rate_tf(K: float, T1: float, T2: float = 0.0, T3: float = 0.0) -> ct.TransferFunction:
    """Rudder -> yaw rate of the Nomoto model, K (1 + T3 s)/((1 + T1 s)(1 + T2 s)) (deg/s per deg)."""
    den = np.polymul([T1, 1.0], [T2, 1.0]) if T2 > 0 else np.array([T1, 1.0])
    return ct.tf([K * T3, K] if T3 != 0 else [K], den)


def parameters_rate_tf(theta) -> ct.TransferFunction:
    """Rudder -> yaw rate of the sway-yaw model with the six parameters a11 ... b21
    (docs/contract.md#the-identification-model)."""
    a11, a12, a21, a22, b11, b21 = (float(x) for x in theta)
    return ct.tf(ct.ss([[a11, a12], [a21, a22]], [[b11], [b21]], [[0.0, 1.0]], [[0.0]]))


def sampled_plant_tf(r_tf: ct.TransferFunction, dt: float, *, servo_time_constant: float = 0.0,
                     dead_time: float = 0.0) -> ct.StateSpace:
    """Rudder command -> (psi deg, r deg/s) of a rudder -> yaw-rate model ``r_tf`` (strictly proper),
    sampled at dt s with zero-order hold, the servo lag and the dead time in whole samples; psi = r/s.
    One state-space model (two outputs), so the loop has no duplicated plant modes."""
    g = r_tf if servo_time_constant <= 0 else r_tf * ct.tf([1.0], [float(servo_time_constant), 1.0])
    sr = ct.ss(g)
    return sampled_plant_ss(sr.A, sr.B, sr.C, dt, dead_time=dead_time)


def parameters_plant(theta, dt: float, *, servo_time_constant: float = 0.0,
                     dead_time: float = 0.0) -> ct.StateSpace:
    """:func:`sampled_plant_ss` of the sway-yaw model with the six parameters a11 ... b21 (the same
    plant as ``sampled_plant_tf(parameters_rate_tf(theta), ...)`` without the transfer-function detour)."""
    a11, a12, a21, a22, b11, b21 = (float(x) for x in theta)
    return sampled_plant_ss([[a11, a12], [a21, a22]], [b11, b21], [0.0, 1.0], dt,
                            servo_time_constant=servo_time_constant, dead_time=dead_time)


def sampled_plant_ss(a, b, c, dt: float, *, servo_time_constant: float = 0.0,
                     dead_time: float = 0.0) -> ct.StateSpace:
    """:func:`sampled_plant_tf` from a state-space rudder -> yaw-rate model x' = a x + b delta,
    r = c x (deg/s per deg); the servo lag is added here as one more state.  The zero-order-hold
    discretisation is the matrix exponential of the augmented system (exact for the held command)."""
    a = np.atleast_2d(np.asarray(a, dtype=float))
    b = np.asarray(b, dtype=float).reshape(-1, 1)
    c = np.asarray(c, dtype=float).reshape(1, -1)
    tau = float(servo_time_constant)
    if tau > 0:                      # servo state s' = (u - s)/tau drives the hull
        n0 = a.shape[0]
        a2 = np.zeros((n0 + 1, n0 + 1))
        a2[:n0, :n0] = a
        a2[:n0, n0] = b[:, 0]
        a2[n0, n0] = -1.0 / tau
        b = np.zeros((n0 + 1, 1))
        b[n0, 0] = 1.0 / tau
        c = np.hstack([c, [[0.0]]])
        a = a2
    n = a.shape[0]
    big = np.zeros((n + 2, n + 2))
    big[:n, :n] = a
    big[n, :n] = c[0]
    big[:n, n + 1] = b[:, 0]
    e = expm(big * float(dt))
    cc = np.zeros((2, n + 1))
    cc[0, n] = 1.0
    cc[1, :n] = c[0]
    sysd = ct.ss(e[:n + 1, :n + 1], e[:n + 1, n + 1:], cc, np.zeros((2, 1)), dt)
    nd = delay_steps(dead_time, dt)
    if nd == 0:
        return sysd
    # dead time as a shift register of nd samples on the plant's input
    sh = np.diag(np.ones(nd - 1), -1)
    delay = ct.ss(sh, np.eye(nd)[:, :1], np.eye(nd)[-1:], [[0.0]], dt)
    return ct.series(delay, sysd)


def sampled_plant(K: float, T1: float, T2: float, T3: float, dt: float, *, servo_time_constant: float = 0.0,
                  dead_time: float = 0.0) -> ct.StateSpace:
    """Rudder command -> (psi, r) of the Nomoto model K (1/s), T1, T2, T3 (s) (:func:`sampled_plant_tf`)."""
    if not (np.isfinite(K) and K > 0 and np.isfinite(T1) and T1 > 0 and T2 >= 0):
        raise ModelError(f"Nomoto plant K = {K} 1/s, T1 = {T1}, T2 = {T2} s: need K, T1 > 0, T2 >= 0")
    return sampled_plant_tf(rate_tf(K, T1, T2, T3), dt, servo_time_constant=servo_time_constant,
                            dead_time=dead_time)


def feedback_parts(design, dt: float) -> tuple[ct.TransferFunction, ct.TransferFunction]:
    """(C_psi(z), C_r(z)) of a CGSA or PID design as implemented at step dt s."""
    if isinstance(design, PIDDesign):
        return design.feedback_tf(dt)
    if isinstance(design, CGSADesign):
        h = design.rate_filter
        den = np.trim_zeros(np.asarray(h.den[0][0], dtype=float), "f")
        c_r = (ct.tf([float(np.asarray(h.num[0][0], dtype=float)[-1] / den[0])], [1.0], dt) if den.size <= 1
               else ct.tf(ct.ss2tf(ct.c2d(ct.ss(h), dt, method="zoh"))))
        return ct.tf([design.Kp], [1.0], dt), c_r
    raise ModelError(f"unknown autopilot design {type(design).__name__}")


def loop_tf(design, plant: ct.StateSpace, dt: float) -> ct.StateSpace:
    """L(z) = C_psi P_psi + C_r P_r (module docstring), as one state-space model."""
    c_psi, c_r = feedback_parts(design, dt)
    ctl = ct.series(ct.append(ct.ss(c_psi), ct.ss(c_r)), ct.ss([], [], [], [[1.0, 1.0]], dt))
    return ct.series(plant, ctl)


def loop_response(loop: ct.StateSpace, omega: np.ndarray) -> np.ndarray:
    """L(e^{j omega dt}) of a discrete SISO state-space loop (omega rad/s), one batched solve."""
    a, b, c, d = (np.asarray(m, dtype=float) for m in (loop.A, loop.B, loop.C, loop.D))
    z = np.exp(1j * np.asarray(omega, dtype=float) * float(loop.dt))
    if a.size == 0:
        return np.full(z.shape, d[0, 0], dtype=complex)
    m = z[:, None, None] * np.eye(a.shape[0])[None] - a[None]
    x = np.linalg.solve(m, np.broadcast_to(b.astype(complex), (z.size,) + b.shape))
    return (c[None] @ x)[:, 0, 0] + d[0, 0]


def _crossings(x: np.ndarray) -> np.ndarray:
    """Indices i where x changes sign between i and i + 1."""
    return np.flatnonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))


def discrete_margins(loop: ct.StateSpace | ct.TransferFunction, *, n_grid: int = 1500) -> dict:
    """Margins of a sampled open loop L(z) under unity negative feedback (module docstring).

    ``loop`` is SISO and discrete (its ``dt`` the sample time, s).  On a log grid of ``n_grid``
    frequencies from 1e-4 rad/s to the Nyquist frequency pi/dt, crossings refined by linear
    interpolation: gain crossovers where |L| = 1 (phase margin 180 deg + arg L there, the smallest;
    delay margin the smallest phase margin (rad) / crossover frequency over them), phase crossovers
    where L crosses the negative real axis with |L| < 1 (gain margin -20 log10 |L| there, the
    smallest: the upper gain margin; crossings at |L| > 1, where a loop with two integrators starts,
    are lower gain margins and not reported).  Unstable closed loop: delay margin 0.
    """
    loop = ct.ss(loop)
    dt = float(loop.dt)
    if not dt or loop.ninputs != 1 or loop.noutputs != 1:
        raise ModelError("discrete_margins needs a discrete SISO loop")
    d0 = float(np.asarray(loop.D)[0, 0])
    a_cl = np.asarray(loop.A) - np.asarray(loop.B) @ np.asarray(loop.C) / (1.0 + d0)
    stable = bool(np.all(np.abs(np.linalg.eigvals(a_cl)) < 1.0)) if a_cl.size else True
    w = np.logspace(-4, np.log10(np.pi / dt), int(n_grid))
    w[-1] = np.pi / dt * (1 - 1e-9)
    h = loop_response(loop, w)
    mag = np.abs(h)
    sens = 1.0 / np.abs(1.0 + h)
    i = int(np.argmax(sens))
    pms, wgcs = [], []
    lm = np.log(mag)
    for k in _crossings(lm):
        f = lm[k] / (lm[k] - lm[k + 1])
        hc = h[k] + f * (h[k + 1] - h[k])
        wc = w[k] * (w[k + 1] / w[k]) ** f
        pms.append(float(np.degrees(np.angle(-hc))))            # 180 deg + arg L, in (-180, 180]
        wgcs.append(wc)
    gms, wpcs = [], []
    for k in _crossings(h.imag):
        f = h.imag[k] / (h.imag[k] - h.imag[k + 1])
        hc = h[k] + f * (h[k + 1] - h[k])
        if hc.real < 0 and abs(hc) < 1:
            gms.append(-20 * np.log10(abs(hc)))
            wpcs.append(w[k] * (w[k + 1] / w[k]) ** f)
    hn = h[-1]                       # at the Nyquist frequency L is real: a crossing exactly there
    if hn.real < 0 and abs(hn.imag) <= 1e-6 * abs(hn) and abs(hn) < 1 and not (wpcs and wpcs[-1] >= w[-2]):
        gms.append(-20 * np.log10(abs(hn)))
        wpcs.append(float(np.pi / dt))
    if pms:
        j = int(np.argmin(pms))
        pm, wgc = float(pms[j]), float(wgcs[j])
        dm = float(min(np.radians(p) / wc for p, wc in zip(pms, wgcs, strict=True)))
    else:
        pm, wgc, dm = float("inf"), float("nan"), float("inf")
    if gms:
        j = int(np.argmin(gms))
        gm_db, wpc = float(gms[j]), float(wpcs[j])
    else:
        gm_db, wpc = float("inf"), float("nan")
    if not stable:
        dm = 0.0
    return {"gain_margin_db": gm_db, "phase_margin_deg": pm, "delay_margin_s": dm, "gain_crossover": wgc,
            "phase_crossover": wpc, "sensitivity_peak": float(sens[i]),
            "sensitivity_peak_omega": float(w[i]), "stable": stable}


def sampled_margins(design, K: float, T1: float, T2: float, T3: float, dt: float, *,
                    servo_time_constant: float = 0.0, dead_time: float = 0.0) -> dict:
    """Margins of ``design`` on the Nomoto plant K, T1, T2, T3 sampled at dt s (module docstring)."""
    plant = sampled_plant(K, T1, T2, T3, dt, servo_time_constant=servo_time_constant, dead_time=dead_time)
    return discrete_margins(loop_tf(design, plant, dt))


def nyquist_data(design, K: float, T1: float, T2: float, T3: float, dt: float, *, servo_time_constant=0.0,
                 dead_time=0.0, n: int = 300) -> dict:
    """L(e^{j w dt}) and |S| on a log grid up to the Nyquist frequency: omega rad/s, re, im, sens_db."""
    loop = loop_tf(design, sampled_plant(K, T1, T2, T3, dt, servo_time_constant=servo_time_constant,
                                         dead_time=dead_time), dt)
    w = np.logspace(-3, np.log10(np.pi / dt * 0.999), int(n))
    h = loop_response(loop, w)
    return {"omega": w, "re": h.real, "im": h.imag, "sens_db": 20 * np.log10(np.abs(1.0 / (1.0 + h)))}
