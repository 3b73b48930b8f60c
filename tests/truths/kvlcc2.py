"""Another ship and tank: a 3-DOF MMG model of the KVLCC2 at full scale (the stand-in for MARIN data).

Model: the MMG standard method of Yasukawa & Yoshimura (2015), "Introduction of MMG standard method
for ship maneuvering predictions", J Mar Sci Technol 20:37-52, with the KVLCC2 coefficients they
publish (Tables 1-3 there; the same numbers are carried by public MMG implementations).  Full scale,
L 320 m, approach 15.5 kn, sea water; the propeller rps is trimmed so that the ship holds 15.5 kn
straight ahead (the paper's model-scale rps does not Froude-scale to full scale: scale effects on
resistance), then kept constant (free-running test at constant rps, so the ship slows in turns).

Coordinates and signs (MMG = docs/contract.md#run-data): x forward, y to starboard, origin at midship;
v_m m/s lateral velocity at midship, positive to starboard; r rad/s internally, positive turning to
starboard; delta positive = trailing edge to port, which turns the ship to starboard, so positive
delta makes r positive (checked by :func:`check_signs`).  beta = atan(-v_m / u).

Not written in the diagnosis method's formulas: hull forces are Yoshimura's polynomial in
(v', r') on 1/2 rho L d U^2 (so every dimensional coefficient scales with U, and the cross terms
v^2 r, v r^2 and the cubic terms are there), propeller thrust depends on the advance ratio, the
rudder force on its own inflow (propeller slipstream and flow straightening with different gamma_R
for each sign of beta_R: a built-in port/starboard asymmetry), speed loss follows from the surge
equation.  "Clean" here means this model with seeded white sensor noise; there is no rudder offset,
dead time or servo lag beyond the steering gear's rate limit (2.34 deg/s full scale, SIMMAN).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from truths import zigzag
from truths.disturbance import ornstein_uhlenbeck

RAD = math.pi / 180.0
KNOT = 1852.0 / 3600.0


@dataclass(frozen=True)
class KVLCC2:
    """Yasukawa & Yoshimura (2015) KVLCC2, full scale.  Lengths m, areas m^2, volumes m^3."""

    rho: float = 1025.0
    L: float = 320.0
    B: float = 58.0
    d: float = 20.8
    volume: float = 312600.0
    xG: float = 11.2
    Cb: float = 0.810
    Dp: float = 9.86
    HR: float = 15.80
    AR: float = 112.5
    kzz_L: float = 0.25            # yaw radius of gyration / L
    # added masses, non-dimensional on 1/2 rho L^2 d and 1/2 rho L^4 d
    mx_: float = 0.022
    my_: float = 0.223
    Jz_: float = 0.011
    # hull (on 1/2 rho L d U^2, N on 1/2 rho L^2 d U^2)
    R0_: float = 0.022
    Xvv: float = -0.040
    Xvr: float = 0.002
    Xrr: float = 0.011
    Xvvvv: float = 0.771
    Yv: float = -0.315
    Yr: float = 0.083
    Yvvv: float = -1.607
    Yvvr: float = 0.379
    Yvrr: float = -0.391
    Yrrr: float = 0.008
    Nv: float = -0.137
    Nr: float = -0.049
    Nvvv: float = -0.030
    Nvvr: float = -0.294
    Nvrr: float = 0.055
    Nrrr: float = -0.013
    # propeller
    tP: float = 0.220
    wP0: float = 0.40
    k0: float = 0.2931
    k1: float = -0.2753
    k2: float = -0.1359
    xP_: float = -0.48
    C1: float = 2.0
    C2_plus: float = 1.6           # beta_P > 0
    C2_minus: float = 1.1          # beta_P <= 0
    # rudder
    tR: float = 0.387
    aH: float = 0.312
    xH_: float = -0.464
    xR_: float = -0.500
    gammaR_minus: float = 0.395    # beta_R < 0
    gammaR_plus: float = 0.640     # beta_R >= 0
    lR_: float = -0.710
    eps: float = 1.09
    kappa: float = 0.50
    f_alpha: float = 2.747
    # test conditions
    u0_kn: float = 15.5
    rudder_rate: float = 2.34      # deg/s, full scale steering gear (SIMMAN 2008 KVLCC2)
    servo_gain: float = 2.0        # 1/s, servo's proportional band near the command

    @property
    def u0(self) -> float:
        return self.u0_kn * KNOT

    @property
    def eta(self) -> float:
        return self.Dp / self.HR


def forces(s: KVLCC2, u: float, vm: float, r: float, delta_rad: float, n_p: float) -> tuple:
    """MMG forces X, Y (N) and moment N (N m) at midship; r rad/s, delta rad, n_p rps."""
    rho, L, d = s.rho, s.L, s.d
    U = math.hypot(u, vm)
    beta = math.atan2(-vm, u) if U > 0 else 0.0
    vp = -math.sin(beta)            # v'_m = v_m / U
    rp = r * L / U if U > 0 else 0.0
    XH_ = (-s.R0_ + s.Xvv * vp * vp + s.Xvr * vp * rp + s.Xrr * rp * rp + s.Xvvvv * vp**4)
    YH_ = (s.Yv * vp + s.Yr * rp + s.Yvvv * vp**3 + s.Yvvr * vp * vp * rp + s.Yvrr * vp * rp * rp
           + s.Yrrr * rp**3)
    NH_ = (s.Nv * vp + s.Nr * rp + s.Nvvv * vp**3 + s.Nvvr * vp * vp * rp + s.Nvrr * vp * rp * rp
           + s.Nrrr * rp**3)
    q = 0.5 * rho * L * d * U * U
    XH, YH, NH = q * XH_, q * YH_, q * L * NH_
    # propeller
    betaP = beta - s.xP_ * rp
    C2 = s.C2_plus if betaP > 0 else s.C2_minus
    wfac = 1.0 + (1.0 - math.exp(-s.C1 * abs(betaP))) * (C2 - 1.0)
    one_wP = (1.0 - s.wP0) * wfac
    JP = u * one_wP / (n_p * s.Dp)
    KT = s.k0 + s.k1 * JP + s.k2 * JP * JP
    XP = (1.0 - s.tP) * rho * n_p * n_p * s.Dp**4 * KT
    # rudder
    betaR = beta - s.lR_ * rp
    gammaR = s.gammaR_minus if betaR < 0 else s.gammaR_plus
    vR = U * gammaR * betaR
    slip = math.sqrt(1.0 + 8.0 * KT / (math.pi * JP * JP)) - 1.0 if JP > 1e-6 else 0.0
    uR = s.eps * u * one_wP * math.sqrt(s.eta * (1.0 + s.kappa * slip) ** 2 + (1.0 - s.eta))
    UR2 = uR * uR + vR * vR
    alphaR = delta_rad - math.atan2(vR, uR)
    FN = 0.5 * rho * s.AR * UR2 * s.f_alpha * math.sin(alphaR)
    XR = -(1.0 - s.tR) * FN * math.sin(delta_rad)
    YR = -(1.0 + s.aH) * FN * math.cos(delta_rad)
    NR = -(s.xR_ * L + s.aH * s.xH_ * L) * FN * math.cos(delta_rad)
    return XH + XP + XR, YH + YR, NH + NR


def trim_rps(s: KVLCC2) -> float:
    """Propeller rps holding u0 straight ahead (X = 0 at v = r = delta = 0), by bisection."""
    lo, hi = 0.1, 10.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if forces(s, s.u0, 0.0, 0.0, 0.0, mid)[0] < 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _mass(s: KVLCC2):
    m = s.rho * s.volume
    half = 0.5 * s.rho * s.L**2 * s.d
    mx, my = s.mx_ * half, s.my_ * half
    Jz = s.Jz_ * 0.5 * s.rho * s.L**4 * s.d
    IzG = m * (s.kzz_L * s.L) ** 2
    return m, mx, my, Jz, IzG


def simulate_zigzag(
    s: KVLCC2,
    rudder_deg: float,
    heading_deg: float,
    first_side: str = "starboard",
    duration: float = 800.0,
    dt_log: float = 0.5,
    h: float = 0.05,
    seed: int = 0,
    noise: bool = True,
    t_execute: float = 10.0,
    disturbance_deg: float = 0.0,
    disturbance_tau: float = 30.0,
) -> pd.DataFrame:
    """A full-scale zigzag; returns time s, x0, y0 m, psi deg, u, v m/s, r deg/s, delta deg
    (contract signs (docs/contract.md#run-data)), rpm 1/min, all full scale, logged every ``dt_log`` s.  RK4
    at ``h`` s (0.05 s full scale = 0.0074 s at 1:45.7).  Counter-rudder at a logging instant when the
    measured heading passes +-heading_deg.  White sensor noise, Froude-scaled from model-scale
    figures (psi 0.05 deg, r 0.05 deg/s, u, v 0.005 m/s, delta 0.05 deg at 1:45.7).

    Process disturbance (``disturbance_deg`` > 0), as in :func:`truths.mariner.simulate_zigzag`: an
    external yaw moment, stationary Ornstein-Uhlenbeck with correlation time ``disturbance_tau`` s,
    its std the rudder's moment at ``disturbance_deg`` (straight ahead at the approach speed), drawn
    afresh in every run from its own stream, exact at the logging step, held over the RK4 sub-steps."""
    m, mx, my, Jz, IzG = _mass(s)
    xG = s.xG
    n_p = trim_rps(s)
    # [[m+my, xG m], [xG m, IzG + xG^2 m + Jz]] [v', r'] = [Y - (m+mx) u r, N - xG m u r]
    M11, M12, M22 = m + my, xG * m, IzG + xG * xG * m + Jz
    det = M11 * M22 - M12 * M12
    n = int(round(duration / dt_log)) + 1
    rate = s.rudder_rate * RAD
    ks = s.servo_gain

    dist = np.zeros(n)
    if disturbance_deg > 0.0:
        dist = ornstein_uhlenbeck(n, dt_log, disturbance_tau, seed)
        per_deg = abs(forces(s, s.u0, 0.0, 0.0, RAD, n_p)[2] - forces(s, s.u0, 0.0, 0.0, 0.0, n_p)[2])
        dist *= per_deg * disturbance_deg

    def rhs(x, cmd, n_ext=0.0):
        u, vm, r, psi, X0, Y0, dl = x
        X, Y, N = forces(s, u, vm, r, dl, n_p)
        N += n_ext
        du = (X + (m + my) * vm * r + xG * m * r * r) / (m + mx)
        bY = Y - (m + mx) * u * r
        bN = N - xG * m * u * r
        dv = (M22 * bY - M12 * bN) / det
        dr = (M11 * bN - M12 * bY) / det
        dd = ks * (cmd - dl)
        dd = rate if dd > rate else (-rate if dd < -rate else dd)
        cp, sp = math.cos(psi), math.sin(psi)
        return (du, dv, dr, r, u * cp - vm * sp, u * sp + vm * cp, dd)

    e = zigzag.sensor_noise(n, 45.7, seed, noise)
    out = zigzag.run(
        rhs, [s.u0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        lambda t, x: (t, x[4], x[5], x[3] / RAD, x[0], x[1], x[2] / RAD, x[6] / RAD, n_p * 60.0),
        lambda x: x[3] / RAD, rudder_deg, heading_deg, first_side, n, dt_log, h, t_execute, e["psi"], dist)
    return zigzag.logged(out, ["time", "x0", "y0", "psi", "u", "v", "r", "delta", "rpm"], e)


def zigzag_metrics(f: pd.DataFrame, heading_deg: float) -> dict:
    """First and second overshoot angles (deg) and lowest u/u0 of a zigzag frame (ITTC 7.5-04-02-01:
    the heading beyond the trigger after each counter-rudder; taken from the true series if any)."""
    g = f.attrs.get("true", f)
    psi = g["psi"].to_numpy()
    d = g["delta"].to_numpy()
    r = g["r"].to_numpy()
    over = []
    # counter-rudder instants: the commanded side changes; the overshoot is the heading extremum
    # (r changes sign) after each of them, beyond the trigger
    sgn = np.sign(d)
    k = int(np.argmax(np.abs(d) > 1.0))
    side = sgn[k]
    while len(over) < 3:
        nxt = np.flatnonzero(sgn[k:] == -side)
        if not nxt.size:
            break
        k += int(nxt[0])
        turn = np.flatnonzero(np.sign(r[k:]) == -side)
        if not turn.size:
            break
        j = k + int(turn[0])
        over.append(float(abs(psi[j]) - heading_deg))
        side = -side
    u = g["u"].to_numpy()
    return {"overshoots_deg": over, "lowest_speed_ratio": float(u.min() / u[0])}


def check_signs(s: KVLCC2 | None = None) -> dict:
    """Steady response to +10 deg rudder after 120 s (noise-free): r > 0 (docs/contract.md#run-data) and v < 0
    (drift outward of a starboard turn: the stern slides out, the bow points inside)."""
    s = s or KVLCC2()
    f = simulate_zigzag(s, 10.0, 1e9, "starboard", duration=120.0, noise=False)
    return {"r_deg_s": float(f["r"].iloc[-1]), "v_m_s": float(f["v"].iloc[-1])}
