"""A fourth ship and model family: a 190 000 dwt tanker (Van Berlekom & Goddard, full scale).

Model: the nonlinear manoeuvring model of a large tanker, L 304.8 m, draught 18.46 m, 80 rpm, by
Van Berlekom & Goddard (1972), "Maneuvering of large tankers", Trans. SNAME 80:264-298, in the
"bis" system (forces on the ship's mass, lengths on L); the published coefficients as tabulated in
Fossen, "Guidance and Control of Ocean Vehicles" (Wiley 1994), and carried by his Marine Systems
Simulator.  Written here from those published numbers, in the contract's signs (docs/contract.md#run-data).

Not written in the diagnosis method's formulas, and unlike the other truths (the sway-yaw family of
tests/truths/swayyaw.py, the KVLCC2 MMG of tests/truths/kvlcc2.py, the Mariner Abkowitz model of
tests/truths/mariner.py):

- hull damping in the modulus forms Y_vv |v| v and N_vr |v| r (a cross term of the |.| form);
- the rudder force goes with the square of the flow at the rudder, c^2 = c_un u n + c_nn n^2
  (propeller slipstream), and carries a rudder-drift interaction |c| c |beta| beta |delta|, a
  form no candidate has;
- the propeller's thrust gives a constant side force Y_T and yaw moment N_T (a single screw): a
  steady yaw moment that acts as a rudder offset of about half a degree
  (:func:`equivalent_offset_deg`);
- a surge equation at constant shaft speed (the ship slows in turns, and the rudder and propeller
  terms change with it);
- water depth enters through z = T / (h - T) (deep water here: h = 200 m, z = 0.10);
- the steering gear is a first-order servo (1 s) with the published 2.33 deg/s rate limit and a
  35 deg saturation (the published 10 deg is that study's autopilot limit, not the gear's); the
  *measured* rudder is logged (tank practice), so the servo is not a hidden effect here.

The linear part at the approach speed is course-unstable (:func:`linear_poles`: one positive pole):
what the issue's MARIN hull, "close to course-unstable", asks a baseline to fit and report.

Signs: docs/contract.md#run-data.  The published model's positive rudder gives a negative yaw moment
(N_ccd < 0: it turns the ship to port), so its rudder angle is minus the contract's
(docs/contract.md#run-data) (:func:`check_signs`).
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


@dataclass(frozen=True)
class Tanker:
    """The published tanker.  L, T, h m; rpm 1/min; rudder limits deg and deg/s; servo s."""

    form: str = "full"          # "full" | "linear" | "offset" (module docstring)
    L: float = 304.8
    T: float = 18.46            # draught
    h: float = 200.0            # water depth
    g: float = 9.8
    rpm: float = 80.0           # nominal shaft speed, held constant (free-running test)
    rudder_max: float = 35.0
    rudder_rate: float = 2.33
    servo_tau: float = 1.0
    # thrust deduction, rudder inflow c^2 = cun u n + cnn n^2 (n rps), thrust on the ship's mass
    t: float = 0.22
    cun: float = 0.605
    cnn: float = 38.2
    Tuu: float = -0.00695
    Tun: float = -0.00063
    Tnn: float = 0.0000354
    # masses (bis): 1 - X_udot, 1 - Y_vdot, k_z^2 - N_rdot
    m11: float = 1.050
    m22: float = 2.020
    m33: float = 0.1232
    d11: float = 2.020          # 1 + X_vr
    d22: float = -0.752         # Y_ur - 1
    d33: float = -0.231         # N_ur - x_G
    X: tuple = (("uu", -0.0377), ("vv", 0.3), ("ccdd", -0.093), ("ccbd", 0.152), ("uuz", -0.0061),
                ("vrz", 0.387), ("vvzz", 0.0125), ("udotz", -0.05))
    Y: tuple = (("T", 0.04), ("vv", -2.400), ("uv", -1.205), ("ccd", 0.208), ("ccbbd", -2.16),
                ("urz", 0.182), ("uvz", 0.0), ("vvz", -1.5), ("ccbbdz", -0.191), ("vdotz", -0.387))
    N: tuple = (("T", -0.02), ("vr", -0.300), ("uv", -0.451), ("ccd", -0.098), ("ccbbd", 0.688),
                ("urz", -0.047), ("uvz", -0.241), ("vrz", -0.120), ("ccbbdz", 0.344), ("rdotz", -0.0045))

    def __post_init__(self):
        if self.form not in ("full", "linear", "offset"):
            raise ValueError(f"form must be full, linear or offset, not {self.form!r}")

    @property
    def z(self) -> float:
        return self.T / (self.h - self.T)


def _c(table: tuple, key: str) -> float:
    return dict(table)[key]


def derivatives(s: Tanker, u: float, v: float, r: float, d: float, n_ext: float = 0.0) -> tuple:
    """(du/dt, dv/dt m/s^2, dr/dt rad/s^2) at surge u, sway v m/s, yaw rate r rad/s and the published
    rudder d rad (positive turning to PORT); ``n_ext`` an external yaw acceleration (rad/s^2) added
    to the hull's.  The ``linear`` and ``offset``
    forms: the published model linearised at the approach speed, speed held (du/dt = 0), the
    ``offset`` form with the propeller's constant force and moment there."""
    if s.form != "full":
        J, b, f0 = _linear(s)
        dv, dr = J @ np.array([v, r]) + b * d + (f0 if s.form == "offset" else 0.0)
        return 0.0, float(dv), float(dr + n_ext)
    return _full(s, u, v, r, d, n_ext)


def _full(s: Tanker, u: float, v: float, r: float, d: float, n_ext: float = 0.0) -> tuple:
    L, z = s.L, s.z
    n = s.rpm / 60.0
    X, Y, N = (lambda k: _c(s.X, k)), (lambda k: _c(s.Y, k)), (lambda k: _c(s.N, k))
    beta = math.atan(v / u)
    gT = s.Tuu * u * u / L + s.Tun * u * n + L * s.Tnn * abs(n) * n
    c = math.sqrt(s.cun * u * n + s.cnn * n * n)
    cc = abs(c) * c
    bb = abs(beta) * beta * abs(d)
    gX = (X("uu") * u * u + L * s.d11 * v * r + X("vv") * v * v + X("ccdd") * cc * d * d
          + X("ccbd") * cc * beta * d + L * gT * (1.0 - s.t) + X("uuz") * u * u * z
          + L * X("vrz") * v * r * z + X("vvzz") * v * v * z * z) / L
    gY = (Y("uv") * u * v + Y("vv") * abs(v) * v + Y("ccd") * cc * d + L * s.d22 * u * r
          + Y("ccbbd") * cc * bb + Y("T") * gT * L + L * Y("urz") * u * r * z + Y("uvz") * u * v * z
          + Y("vvz") * abs(v) * v * z + Y("ccbbdz") * cc * bb * z) / L
    gN = (N("uv") * u * v + L * N("vr") * abs(v) * r + N("ccd") * cc * d + L * s.d33 * u * r
          + N("ccbbd") * cc * bb + L * N("T") * gT + L * N("urz") * u * r * z + N("uvz") * u * v * z
          + L * N("vrz") * abs(v) * r * z + N("ccbbdz") * cc * bb * z)
    m11 = s.m11 - X("udotz") * z
    m22 = s.m22 - Y("vdotz") * z
    m33 = s.m33 - N("rdotz") * z
    return gX / m11, gY / m22, gN / (L * L * m33) + n_ext


def approach_speed(s: Tanker | None = None) -> float:
    """The surge speed (m/s) at which the ship holds its shaft speed straight ahead (du/dt = 0 at
    v = r = delta = 0), by bisection; 8.23 m/s (16 kn) in deep water at 80 rpm."""
    s = s or Tanker()
    lo, hi = 1.0, 15.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if _full(s, mid, 0.0, 0.0, 0.0)[0] > 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _jacobian(s: Tanker, u: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The published model at surge speed u (m/s): d(dv, dr)/d(v, r) (1/s, m/(s rad), ...),
    d(dv, dr)/d(published rudder) per rad, and (dv, dr) at v = r = delta = 0 (the propeller's
    constants), by central differences; the rudder column at a 1 deg step (its |beta| beta |delta|
    term is second order)."""
    e = 1e-6
    J = np.empty((2, 2))
    for j in range(2):
        hi = _full(s, u, e if j == 0 else 0.0, e if j == 1 else 0.0, 0.0)
        lo = _full(s, u, -e if j == 0 else 0.0, -e if j == 1 else 0.0, 0.0)
        J[:, j] = [(hi[1] - lo[1]) / (2 * e), (hi[2] - lo[2]) / (2 * e)]
    hi, lo = _full(s, u, 0.0, 0.0, RAD), _full(s, u, 0.0, 0.0, -RAD)
    b = np.array([(hi[1] - lo[1]) / (2 * RAD), (hi[2] - lo[2]) / (2 * RAD)])
    return J, b, np.array(_full(s, u, 0.0, 0.0, 0.0)[1:])


@functools.lru_cache(maxsize=8)
def _linear(s: Tanker) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return _jacobian(s, approach_speed(s))


def linear_poles(s: Tanker | None = None) -> np.ndarray:
    """The two sway-yaw poles (1/s, full scale) of the tanker linearised at its approach speed."""
    return np.sort(np.linalg.eigvals(_linear(s or Tanker())[0]).real)


def equivalent_offset_deg(s: Tanker | None = None, u: float | None = None) -> float:
    """The contract-signed (docs/contract.md#run-data) rudder offset (deg) that gives the tanker linearised at
    surge speed ``u`` m/s (default its approach speed) the same steady yaw rate at zero rudder as its
    propeller's constant Y_T, N_T do (as :func:`truths.mariner.equivalent_offset_deg`; the constants are not
    exactly a rudder force, and they grow as the ship slows: thrust loading rises)."""
    s = s or Tanker()
    J, b, f0 = _jacobian(s, approach_speed(s) if u is None else u)
    r_d = np.linalg.solve(J, -b)[1]
    r_0 = np.linalg.solve(J, -f0)[1]
    return -(r_0 / r_d) / RAD     # published rudder -> contract rudder: minus


def simulate_zigzag(
    s: Tanker,
    rudder_deg: float,
    heading_deg: float,
    first_side: str = "starboard",
    duration: float = 900.0,
    dt_log: float = 0.5,
    h: float = 0.05,
    seed: int = 0,
    noise: bool = True,
    t_execute: float = 10.0,
    scale: float = 50.0,
    disturbance_deg: float = 0.0,
    disturbance_tau: float = 30.0,
) -> pd.DataFrame:
    """A full-scale zigzag; returns time s, x0, y0 m, psi deg, u, v m/s, r deg/s, delta deg
    (docs/contract.md#run-data signs, the *measured* rudder), rpm 1/min, logged every ``dt_log`` s.  RK4 at
    ``h`` s. Counter-rudder at a logging instant when the measured heading passes +-heading_deg.  White
    sensor noise, Froude-scaled from model-scale figures at 1:``scale`` (psi 0.05 deg, r 0.05 deg/s,
    u, v 0.005 m/s, delta 0.05 deg).  The ship starts straight at its approach speed with zero
    rudder; the first 10 s (before the execute) show the drift its propeller gives it.

    Process disturbance (``disturbance_deg`` > 0), as in :func:`truths.mariner.simulate_zigzag`: an
    external yaw acceleration, stationary Ornstein-Uhlenbeck with correlation time
    ``disturbance_tau`` s, its std what the rudder gives at ``disturbance_deg`` (linearised at the
    approach speed), drawn afresh in every run from its own stream, held over the RK4 sub-steps."""
    u0 = approach_speed(s)
    n = int(round(duration / dt_log)) + 1
    rate, dmax = s.rudder_rate * RAD, s.rudder_max * RAD
    dist = np.zeros(n)
    if disturbance_deg > 0.0:
        dist = ornstein_uhlenbeck(n, dt_log, disturbance_tau, seed)
        dist *= abs(_linear(s)[1][1]) * disturbance_deg * RAD

    def rhs(x, cmd_pub, n_ext=0.0):
        u, v, r, psi, _, _, d = x
        du, dv, dr = derivatives(s, u, v, r, d, n_ext)
        c = max(-dmax, min(dmax, cmd_pub))
        dd = max(-rate, min(rate, (c - d) / s.servo_tau))
        cp, sp = math.cos(psi), math.sin(psi)
        return (du, dv, dr, r, u * cp - v * sp, u * sp + v * cp, dd)

    e = zigzag.sensor_noise(n, scale, seed, noise)
    out = zigzag.run(
        rhs, [u0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        lambda t, x: (t, x[4], x[5], x[3] / RAD, x[0], x[1], x[2] / RAD, -x[6] / RAD, s.rpm),
        lambda x: x[3] / RAD, rudder_deg, heading_deg, first_side, n, dt_log, h, t_execute, e["psi"], dist,
        command=lambda c: -c)     # the published rudder is minus the contract's (docs/contract.md#run-data)
    return zigzag.logged(out, ["time", "x0", "y0", "psi", "u", "v", "r", "delta", "rpm"], e)


def check_signs(s: Tanker | None = None) -> dict:
    """Steady response to +10 deg (docs/contract.md#run-data) rudder after 300 s, noise-free:
    r > 0 and v < 0."""
    f = simulate_zigzag(s or Tanker(), 10.0, 1e9, "starboard", duration=300.0, noise=False)
    return {"r_deg_s": float(f["r"].iloc[-1]), "v_m_s": float(f["v"].iloc[-1])}
