"""A fifth ship and model family, with a degree of freedom the diagnosis has not: the Son & Nomoto
high-speed container ship, sway-yaw-ROLL coupled (full scale).

Model: the nonlinear four-degree-of-freedom (surge, sway, roll, yaw) manoeuvring model of a
single-screw container ship, L 175 m, B 25.4 m, draught 8.5 m, GM 0.3 m, by Son & Nomoto (1982),
"On the coupled motion of steering and rolling of a high speed container ship", Naval Architect of
Ocean Engineering 20:73-83 (from J.S.N.A. Japan 150, 1981), in their prime system (forces on
1/2 rho L^2 U^2, moments on 1/2 rho L^3 U^2, the instantaneous speed U); the published coefficients
as tabulated in Fossen, "Guidance and Control of Ocean Vehicles" (Wiley 1994), and carried by his
Marine Systems Simulator.  Written here from those published numbers, in the contract's signs
(docs/contract.md#run-data).

Not written in the diagnosis method's formulas, and unlike every other truth (tests/truths/
swayyaw.py, kvlcc2.py, mariner.py, tanker.py):

- a ROLL mode: the small GM (0.3 m) heels the ship outward in a turn (several degrees in a 20/20
  zigzag), roll's natural period (about 30 s) is within the zigzag's band, and the heel feeds back
  into sway and yaw through N_phi, N_p, N_vvphi, N_rrphi, ... : the yaw response carries a lightly
  damped second-order mode the sway-yaw model cannot write, and no candidate effect describes it;
- hull nonlinearity in cubic forms of every kind (v^3, r^3, v^2 r, v r^2, and with the heel);
- the rudder force from the propeller's slipstream (thrust loading, the flow straightened by the
  hull at the rudder, v_R = gamma v + c_r r + ...), so the rudder's effectiveness moves with the
  sway, the yaw rate and the speed;
- a surge equation at constant shaft speed (the ship slows in turns);
- port/starboard symmetric: no propeller side force, so no offset of any kind;
- the steering gear a first-order servo (1 s) with a 5 deg/s rate limit (the published one) and a
  35 deg saturation (the published 10 deg is that study's autopilot limit, not the gear's); the
  *measured* rudder is logged (tank practice), so the servo is not a hidden effect here.

Variants (:class:`Container` ``form``):

- ``"full"``: the published model;
- ``"linear"``: the published model linearised in (v, r, p, phi, delta) at the approach speed,
  speed held: the baseline's own family plus the roll mode, nothing else;
- ``"noroll"``: the published model with the roll held upright (p = phi = 0): what the heel adds
  is the difference from ``"full"``.

Signs: docs/contract.md#run-data.  The published model's positive rudder gives a positive yaw rate (turning to
starboard) as the contract's (docs/contract.md#run-data) does: checked by :func:`check_signs`.  psi_dot = r
cos(phi): the logged yaw rate is the heading's derivative (docs/contract.md#run-data: r = d(psi)/dt), the
logged sway the horizontal one.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from truths import zigzag
from truths.disturbance import ornstein_uhlenbeck

RAD = math.pi / 180.0

#: the published prime-system coefficients (Son & Nomoto 1982, as tabulated by Fossen 1994)
X_ = {"uu": -0.0004226, "vr": -0.00311, "rr": 0.00020, "phiphi": -0.00020, "vv": -0.00386}
K_ = {"v": 0.0003026, "r": -0.000063, "p": -0.0000075, "phi": -0.000021, "vvv": 0.002843, "rrr": -0.0000462,
      "vvr": -0.000588, "vrr": 0.0010565, "vvphi": -0.0012012, "vphiphi": -0.0000793, "rrphi": -0.000243,
      "rphiphi": 0.00003569}
Y_ = {"v": -0.0116, "r": 0.00242, "p": 0.0, "phi": -0.000063, "vvv": -0.109, "rrr": 0.00177, "vvr": 0.0214,
      "vrr": -0.0405, "vvphi": 0.04605, "vphiphi": 0.00304, "rrphi": 0.009325, "rphiphi": -0.001368}
N_ = {"v": -0.0038545, "r": -0.00222, "p": 0.000213, "phi": -0.0001424, "vvv": 0.001492, "rrr": -0.00229,
      "vvr": -0.0424, "vrr": 0.00156, "vvphi": -0.019058, "vphiphi": -0.0053766, "rrphi": -0.0038592,
      "rphiphi": 0.0024195}


@dataclass(frozen=True)
class Container:
    """The published container ship.  L, D m; nabla m^3; rpm 1/min; rudder limits deg and deg/s;
    servo s."""

    form: str = "full"          # "full" | "linear" | "noroll" (module docstring)
    L: float = 175.0
    rpm: float = 80.0           # shaft speed, held constant (free-running test)
    rudder_max: float = 35.0
    rudder_rate: float = 5.0
    servo_tau: float = 1.0
    g: float = 9.81
    nabla: float = 21222.0
    D: float = 6.533            # propeller diameter
    GM: float = 0.3
    AR: float = 33.0376         # rudder area m^2
    Delta: float = 1.8219       # rudder aspect ratio
    # masses and inertias (prime), the added ones as published
    m: float = 0.00792
    mx: float = 0.000238
    my: float = 0.007049
    Ix: float = 0.0000176
    Jx: float = 0.0000034
    Iz: float = 0.000456
    Jz: float = 0.000419
    alphay: float = 0.05
    lx: float = 0.0313
    ly: float = 0.0313
    # propeller, rudder and hull-rudder interaction
    t: float = 0.175
    kk: float = 0.631
    epsilon: float = 0.921
    xR: float = -0.5
    wp: float = 0.184
    tau: float = 1.09
    xp: float = -0.526
    ga: float = 0.088
    cRr: float = -0.156
    cRrrr: float = -0.275
    cRrrv: float = 1.96
    cRX: float = 0.71
    aH: float = 0.237
    zR: float = 0.033
    xH: float = -0.48

    def __post_init__(self):
        if self.form not in ("full", "linear", "noroll"):
            raise ValueError(f"form must be full, linear or noroll, not {self.form!r}")


def _forces(s: Container, u: float, v: float, r: float, p: float, phi: float, d: float) -> tuple:
    """Prime-system (X, Y, K, N) and the prime speed-dependent restoring W at dimensional surge u,
    sway v m/s, yaw rate r, roll rate p rad/s, heel phi and rudder d rad (the published model)."""
    U = math.hypot(u, v)
    L = s.L
    up, vp, rp, pp = u / U, v / U, r * L / U, p * L / U
    n = s.rpm / 60.0                                        # rev/s
    vR = s.ga * vp + s.cRr * rp + s.cRrrr * rp ** 3 + s.cRrrv * rp * rp * vp
    uP = up * ((1.0 - s.wp) + s.tau * (vp + s.xp * rp) ** 2)
    J = uP * U / (n * s.D)
    KT = 0.527 - 0.455 * J
    uR = uP * s.epsilon * math.sqrt(1.0 + 8.0 * s.kk * KT / (math.pi * J * J))
    aR = d + math.atan(vR / uR)
    FN = -((6.13 * s.Delta) / (s.Delta + 2.25)) * (s.AR / L ** 2) * (uR * uR + vR * vR) * math.sin(aR)
    T = 2.0 * s.D ** 4 / (U * U * L * L) * KT * n * abs(n)
    W = s.g * s.nabla / (L * L * U * U / 2.0)
    gm = s.GM / L

    def hull(c):
        return (c["v"] * vp + c["r"] * rp + c["p"] * pp + c["phi"] * phi + c["vvv"] * vp ** 3
                + c["rrr"] * rp ** 3 + c["vvr"] * vp * vp * rp + c["vrr"] * vp * rp * rp
                + c["vvphi"] * vp * vp * phi + c["vphiphi"] * vp * phi * phi + c["rrphi"] * rp * rp * phi
                + c["rphiphi"] * rp * phi * phi)

    X = (X_["uu"] * up * up + (1.0 - s.t) * T + X_["vr"] * vp * rp + X_["vv"] * vp * vp + X_["rr"] * rp * rp
         + X_["phiphi"] * phi * phi + s.cRX * FN * math.sin(d) + (s.m + s.my) * vp * rp)
    Y = hull(Y_) + (1.0 + s.aH) * FN * math.cos(d) - (s.m + s.mx) * up * rp
    K = hull(K_) - (1.0 + s.aH) * s.zR * FN * math.cos(d) + s.mx * s.lx * up * rp - W * gm * phi
    N = hull(N_) + (s.xR + s.aH * s.xH) * FN * math.cos(d)
    return X, Y, K, N, U


def _full(s: Container, u, v, r, p, phi, d, roll: bool = True) -> tuple:
    """(du, dv m/s^2, dr, dp rad/s^2, dphi rad/s) of the published model; ``roll`` False holds the
    ship upright (p = phi = 0, dp = dphi = 0)."""
    if not roll:
        p = phi = 0.0
    X, Y, K, N, U = _forces(s, u, v, r, p, phi, d)
    L = s.L
    m11, m22 = s.m + s.mx, s.m + s.my
    m32, m42 = -s.my * s.ly, s.my * s.alphay
    m33, m44 = s.Ix + s.Jx, s.Iz + s.Jz
    if not roll:        # sway-yaw alone: the 2 x 2 mass matrix of (Y, N) without the roll row
        det = m22 * m44 - m42 * m42
        dv = (m44 * Y - m42 * N) / det * U * U / L
        dr = (m22 * N - m42 * Y) / det * U * U / L ** 2
        return X * U * U / L / m11, dv, dr, 0.0, 0.0
    det = m22 * m33 * m44 - m32 * m32 * m44 - m42 * m42 * m33
    dv = -((-m33 * m44 * Y + m32 * m44 * K + m42 * m33 * N) / det) * U * U / L
    dr = ((-m42 * m33 * Y + m32 * m42 * K + N * m22 * m33 - N * m32 * m32) / det) * U * U / L ** 2
    dp = ((-m32 * m44 * Y + K * m22 * m44 - K * m42 * m42 + m32 * m42 * N) / det) * U * U / L ** 2
    return X * U * U / L / m11, dv, dr, dp, p


def approach_speed(s: Container | None = None) -> float:
    """The surge speed (m/s) at which the ship holds its shaft speed straight ahead (du/dt = 0 at
    v = r = p = phi = delta = 0), by bisection."""
    s = s or Container()
    lo, hi = 1.0, 20.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if _full(s, mid, 0.0, 0.0, 0.0, 0.0, 0.0)[0] > 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@functools.lru_cache(maxsize=8)
def _linear(s: Container) -> tuple[np.ndarray, np.ndarray]:
    """The published model at its approach speed, speed held: d(dv, dr, dp, dphi)/d(v, r, p, phi)
    and d(...)/d(rudder rad), by central differences."""
    u0, e = approach_speed(s), 1e-6
    x0 = np.zeros(4)
    A = np.empty((4, 4))
    for j in range(4):
        hi, lo = x0.copy(), x0.copy()
        hi[j], lo[j] = e, -e
        A[:, j] = (np.array(_full(s, u0, *hi, 0.0)[1:]) - np.array(_full(s, u0, *lo, 0.0)[1:])) / (2 * e)
    hi, lo = _full(s, u0, 0, 0, 0, 0, RAD)[1:], _full(s, u0, 0, 0, 0, 0, -RAD)[1:]
    b = (np.array(hi) - np.array(lo)) / (2 * RAD)
    return A, b


def derivatives(s: Container, u, v, r, p, phi, d, n_ext: float = 0.0) -> tuple:
    """(du, dv, dr, dp, dphi) of the form of ``s`` at the state (m/s, rad/s, rad) and rudder d rad;
    ``n_ext`` an external yaw acceleration (rad/s^2) added."""
    if s.form == "linear":
        A, b = _linear(s)
        dv, dr, dp, dphi = A @ np.array([v, r, p, phi]) + b * d
        return 0.0, float(dv), float(dr + n_ext), float(dp), float(dphi)
    du, dv, dr, dp, dphi = _full(s, u, v, r, p, phi, d, roll=s.form == "full")
    return du, dv, dr + n_ext, dp, dphi


def linear_poles(s: Container | None = None) -> np.ndarray:
    """The four sway-yaw-roll poles (1/s, full scale, complex) linearised at the approach speed."""
    return np.linalg.eigvals(_linear(s or Container())[0])


def simulate_zigzag(
    s: Container,
    rudder_deg: float,
    heading_deg: float,
    first_side: str = "starboard",
    duration: float = 600.0,
    dt_log: float = 0.5,
    h: float = 0.05,
    seed: int = 0,
    noise: bool = True,
    t_execute: float = 10.0,
    scale: float = 35.0,
    disturbance_deg: float = 0.0,
    disturbance_tau: float = 30.0,
) -> pd.DataFrame:
    """A full-scale zigzag; returns time s, x0, y0 m, psi deg, u, v m/s, r deg/s, delta deg
    (docs/contract.md#run-data signs, the *measured* rudder), rpm 1/min, phi deg, p deg/s, logged every
    ``dt_log`` s.  RK4 at
    ``h`` s, counter-rudder on the measured heading, white sensor noise Froude-scaled from model-scale
    figures at 1:``scale`` (as :func:`truths.tanker.simulate_zigzag`, and phi 0.05 deg, p 0.05 deg/s);
    the process disturbance as there.  The ship starts straight and upright at its approach speed."""
    u0 = approach_speed(s)
    n = int(round(duration / dt_log)) + 1
    rate, dmax = s.rudder_rate * RAD, s.rudder_max * RAD
    dist = np.zeros(n)
    if disturbance_deg > 0.0:
        dist = ornstein_uhlenbeck(n, dt_log, disturbance_tau, seed)
        dist = dist * abs(_linear(s)[1][1]) * disturbance_deg * RAD

    def rhs(x, cmd, n_ext=0.0):
        u, v, r, p, phi, psi, _, _, d = x
        du, dv, dr, dp, dphi = derivatives(s, u, v, r, p, phi, d, n_ext)
        c = max(-dmax, min(dmax, cmd))
        dd = max(-rate, min(rate, (c - d) / s.servo_tau))
        cp, sp, cf = math.cos(psi), math.sin(psi), math.cos(phi)
        return (du, dv, dr, dp, dphi, r * cf, u * cp - v * cf * sp, u * sp + v * cf * cp, dd)

    def row(t, x):
        u, v, r, p, phi, psi, x0, y0, d = x
        cf = math.cos(phi)
        return (t, x0, y0, psi / RAD, u, v * cf, r * cf / RAD, d / RAD, s.rpm, phi / RAD, p / RAD)

    e = zigzag.sensor_noise(n, scale, seed, noise, {"phi": 0.05, "p": 0.05 / math.sqrt(scale)})
    out = zigzag.run(rhs, [u0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], row, lambda x: x[5] / RAD,
                     rudder_deg, heading_deg, first_side, n, dt_log, h, t_execute, e["psi"], dist)
    return zigzag.logged(out, ["time", "x0", "y0", "psi", "u", "v", "r", "delta", "rpm", "phi", "p"], e)


def check_signs(s: Container | None = None) -> dict:
    """Steady response to +10 deg (docs/contract.md#run-data) rudder after 300 s, noise-free: r > 0, v < 0 and
    the heel outward (phi > 0 is starboard down in the published axes; a turn to starboard heels to port)."""
    f = simulate_zigzag(s or Container(), 10.0, 1e9, "starboard", duration=300.0, noise=False)
    return {"r_deg_s": float(f["r"].iloc[-1]), "v_m_s": float(f["v"].iloc[-1]),
            "phi_deg": float(f["phi"].iloc[-1])}
