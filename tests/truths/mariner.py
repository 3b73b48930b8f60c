"""A third ship, and another model family: the Mariner class vessel (Abkowitz model, full scale).

Model: the nonlinear Taylor-series (Abkowitz) manoeuvring model of the Mariner, L 160.93 m, 15 kn,
from the planar-motion-mechanism tests of Chislett & Stroem-Tejsen (1965), "Planar motion mechanism
tests and full-scale steering and manoeuvring predictions for a Mariner class vessel", Hydro- and
Aerodynamics Laboratory, Lyngby, report Hy-5; the hydrodynamic derivatives are theirs as tabulated
in Fossen, "Handbook of Marine Craft Hydrodynamics and Motion Control" (Wiley 2011), and carried by
his Marine Systems Simulator.  Written here from those published numbers, in the contract's signs
(docs/contract.md#run-data).

Not written in the diagnosis method's formulas, and unlike both other truths (tests/truths/swayyaw.py,
the KVLCC2 MMG of tests/truths/kvlcc2.py):

- forces are polynomials in (u', v', r', delta) made non-dimensional by the *instantaneous* speed U
  (prime system: force on 1/2 rho L^2 U^2 with rho and L^2 absorbed into the published numbers), so
  every coefficient changes with the speed the ship loses in a turn;
- the nonlinearity is in sway and in the cross terms (Y_vvv, Y_vvr, N_vvv, N_vvr), and in the rudder
  (Y_ddd, N_ddd, Y_vvd, N_vvd, ...); there is no pure r^3 or r|r| yaw damping term;
- the hull carries constant force and moment terms Y_0, N_0 (propeller asymmetry), which act as a
  steady rudder offset of about a degree (:func:`equivalent_offset_deg`);
- the linear Mariner is only just course-stable: its slow yaw pole is -0.0085 1/s, a time constant of
  118 s or 5.6 L/U (:func:`linear_poles`), so a linear fit must place a pole near the margin;
- the steering gear is a first-order servo (time constant 1 s) with a 5 deg/s rate limit and 40 deg
  saturation.  The *measured* rudder angle is logged (tank practice), so the servo is not a hidden
  effect here.

Variants (:class:`Mariner` ``form``):

- ``"linear"``: the linear terms only (Y_v, Y_r, Y_d, N_v, N_r, N_d), speed held: the baseline's own
  family in another parameterisation; a right diagnosis says "none";
- ``"offset"``: the linear Mariner with its Y_0, N_0: a right diagnosis names ``rudder_offset`` near
  :func:`equivalent_offset_deg`;
- ``"full"``: the published model with the surge equation (constant thrust balance, the ship slows in
  turns).

Signs: docs/contract.md#run-data (x forward, y to starboard, psi and r positive turning to starboard; delta
positive = trailing edge to port, which turns the ship to starboard).  The published model has N_d < 0
(its positive rudder turns to port), so its rudder angle is minus the contract's (docs/contract.md#run-data):
checked by
:func:`check_signs`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from truths import zigzag
from truths.disturbance import ornstein_uhlenbeck

RAD = math.pi / 180.0

# Published non-dimensional derivatives (prime system, x 1e-5 as tabulated).  Keys as in the tables:
# X, Y, N force / moment; subscripts u, v, r, d (delta); "dot" added-mass terms; 0 the constant terms.
_E5 = 1e-5
X_ = {"udot": -42, "u": -184, "uu": -110, "uuu": -215, "vv": -899, "rr": 18, "dd": -95, "udd": -190,
      "rv": 798, "vd": 93, "uvd": 93}
Y_ = {"vdot": -748, "rdot": -9.354, "v": -1160, "r": -499, "vvv": -8078, "vvr": 15356, "vu": -1160,
      "ru": -499, "d": 278, "ddd": -90, "ud": 556, "uud": 278, "vdd": -4, "vvd": 1190, "0": -4, "0u": -8,
      "0uu": -4}
N_ = {"vdot": 4.646, "rdot": -43.8, "v": -264, "r": -166, "vvv": 1636, "vvr": -5483, "vu": -264,
      "ru": -166, "d": -139, "ddd": 45, "ud": -278, "uud": -139, "vdd": 13, "vvd": -489, "0": 3, "0u": 6,
      "0uu": 3}
M_PRIME, IZ_PRIME, XG_PRIME = 798 * _E5, 39.2 * _E5, -0.023
LINEAR_KEYS = ("v", "r", "d")


@dataclass(frozen=True)
class Mariner:
    """The Mariner at full scale.  L m, U0 m/s, rudder limits deg and deg/s, servo time constant s."""

    form: str = "full"              # "linear" | "offset" | "full" (module docstring)
    L: float = 160.93
    U0: float = 7.7175               # 15 kn
    rudder_max: float = 40.0
    rudder_rate: float = 5.0
    servo_tau: float = 1.0

    def __post_init__(self):
        if self.form not in ("linear", "offset", "full"):
            raise ValueError(f"form must be linear, offset or full, not {self.form!r}")


def _coef(table: dict, key: str) -> float:
    return table.get(key, 0.0) * _E5


def forces(s: Mariner, u: float, v: float, r: float, d: float) -> tuple[float, float, float]:
    """Non-dimensional X', Y', N' of the published model at non-dimensional (u', v', r') and the
    published rudder angle d (rad, positive turning to PORT).  u' is the surge perturbation over U."""
    if s.form in ("linear", "offset"):
        Y = _coef(Y_, "v") * v + _coef(Y_, "r") * r + _coef(Y_, "d") * d
        N = _coef(N_, "v") * v + _coef(N_, "r") * r + _coef(N_, "d") * d
        if s.form == "offset":
            Y += _coef(Y_, "0")
            N += _coef(N_, "0")
        return 0.0, Y, N
    x, y, n = (lambda k: _coef(X_, k)), (lambda k: _coef(Y_, k)), (lambda k: _coef(N_, k))
    X = (x("u") * u + x("uu") * u**2 + x("uuu") * u**3 + x("vv") * v**2 + x("rr") * r**2 + x("rv") * r * v
         + x("dd") * d**2 + x("udd") * u * d**2 + x("vd") * v * d + x("uvd") * u * v * d)

    def lateral(c):
        return (c("v") * v + c("r") * r + c("vvv") * v**3 + c("vvr") * v**2 * r + c("vu") * v * u
                + c("ru") * r * u + c("d") * d + c("ddd") * d**3 + c("ud") * u * d + c("uud") * u**2 * d
                + c("vdd") * v * d**2 + c("vvd") * v**2 * d + c("0") + c("0u") * u + c("0uu") * u**2)

    return X, lateral(y), lateral(n)


def _masses():
    m11 = M_PRIME - _coef(X_, "udot")
    m22 = M_PRIME - _coef(Y_, "vdot")
    m23 = M_PRIME * XG_PRIME - _coef(Y_, "rdot")
    m32 = M_PRIME * XG_PRIME - _coef(N_, "vdot")
    m33 = IZ_PRIME - _coef(N_, "rdot")
    return m11, m22, m23, m32, m33


def derivatives(
    s: Mariner, du_m: float, v: float, r: float, d: float, n_ext: float = 0.0
) -> tuple[float, float, float]:
    """(du/dt m/s^2, dv/dt m/s^2, dr/dt rad/s^2) at surge perturbation du_m m/s, sway v m/s, yaw rate
    r rad/s, published rudder d rad; ``n_ext`` an external yaw moment N' (prime system, the
    published tables' units) added to the hull's."""
    U = s.U0 if s.form != "full" else math.hypot(s.U0 + du_m, v)
    up = du_m / U if s.form == "full" else 0.0
    X, Y, N = forces(s, up, v / U, r * s.L / U, d)
    N += n_ext
    m11, m22, m23, m32, m33 = _masses()
    det = m22 * m33 - m23 * m32
    du = X * U * U / s.L / m11 if s.form == "full" else 0.0
    dv = (m33 * Y - m23 * N) * U * U / s.L / det
    dr = (m22 * N - m32 * Y) * U * U / s.L**2 / det
    return du, dv, dr


def linear_poles(s: Mariner | None = None) -> np.ndarray:
    """The two sway-yaw poles (1/s, full scale) of the linear Mariner at U0, from the Jacobian of
    :func:`derivatives` (central differences).  The tabulated Y_r, N_r carry the Coriolis terms
    m'u'r', m'x_G'u'r' (the table has Y_ru = Y_r, N_ru = N_r, and the equations of motion no separate
    m u r), so these are the poles of the published model, not of Y_r and m apart."""
    s = s or Mariner(form="linear")
    e = 1e-6
    J = np.empty((2, 2))
    for j in range(2):
        dp = [e if j == 0 else 0.0, e if j == 1 else 0.0]
        hi = derivatives(s, 0.0, dp[0], dp[1], 0.0)
        lo = derivatives(s, 0.0, -dp[0], -dp[1], 0.0)
        J[:, j] = [(hi[1] - lo[1]) / (2 * e), (hi[2] - lo[2]) / (2 * e)]
    return np.sort(np.linalg.eigvals(J).real)


def equivalent_offset_deg(s: Mariner | None = None) -> float:
    """The contract-signed (docs/contract.md#run-data) rudder offset (deg) that gives the linear Mariner the
    same steady yaw rate at zero rudder as its Y_0, N_0 do: the ``rudder_offset`` a right diagnosis estimates
    on the
    ``offset`` form (the two constants are not exactly a rudder force, so the sway differs a little).
    """
    yv, yr, yd = (_coef(Y_, k) for k in LINEAR_KEYS)
    nv, nr, nd = (_coef(N_, k) for k in LINEAR_KEYS)
    # steady state of the linear prime equations (Coriolis terms inside Y_r, N_r, as tabulated):
    # 0 = Y_v v + Y_r r + Y_d d + Y_0, 0 = N_v v + N_r r + N_d d + N_0; steady r per unit rudder and
    # from the constants
    A = np.array([[yv, yr], [nv, nr]])
    r_d = np.linalg.solve(A, -np.array([yd, nd]))[1]
    r_0 = np.linalg.solve(A, -np.array([_coef(Y_, "0"), _coef(N_, "0")]))[1]
    return -(r_0 / r_d) / RAD     # published rudder -> contract rudder: minus


def simulate_zigzag(
    s: Mariner,
    rudder_deg: float,
    heading_deg: float,
    first_side: str = "starboard",
    duration: float = 600.0,
    dt_log: float = 0.5,
    h: float = 0.05,
    seed: int = 0,
    noise: bool = True,
    t_execute: float = 10.0,
    scale: float = 40.0,
    disturbance_deg: float = 0.0,
    disturbance_tau: float = 30.0,
) -> pd.DataFrame:
    """A full-scale zigzag; returns time s, x0, y0 m, psi deg, u, v m/s, r deg/s, delta deg
    (docs/contract.md#run-data signs; the *measured* rudder), logged every ``dt_log`` s.  RK4 at ``h`` s.
    Counter-rudder at a logging instant when the measured heading passes +-heading_deg.  White sensor noise,
    Froude-scaled from model-scale figures at 1:``scale`` (psi 0.05 deg, r 0.05 deg/s, u, v
    0.005 m/s, delta 0.05 deg).  The ship starts straight at U0 with zero rudder; the first 10 s
    (before the execute) show any drift the hull has of its own.

    Process disturbance (``disturbance_deg`` > 0): an external yaw moment that no candidate effect
    describes, as wind gusts in a sea trial or a tank's residual circulation give: a stationary
    Ornstein-Uhlenbeck process with correlation time ``disturbance_tau`` s and a standard deviation
    of the yaw moment ``disturbance_deg`` of rudder gives (|N_d| x angle), drawn afresh in every run
    (its own random stream, so the sensor noise is the same with and without it), exact at the
    logging step and held over the RK4 sub-steps.  Its run mean is random, so no constant effect (an
    offset) explains it on runs it was not fitted on."""
    n = int(round(duration / dt_log)) + 1
    rate, dmax = s.rudder_rate * RAD, s.rudder_max * RAD

    dist = np.zeros(n)
    if disturbance_deg > 0.0:
        dist = ornstein_uhlenbeck(n, dt_log, disturbance_tau, seed)
        dist *= abs(_coef(N_, "d")) * disturbance_deg * RAD

    def rhs(x, cmd_pub, n_ext=0.0):
        du_m, v, r, psi, _, _, d = x
        du, dv, dr = derivatives(s, du_m, v, r, d, n_ext)
        c = max(-dmax, min(dmax, cmd_pub))
        dd = (c - d) / s.servo_tau
        dd = max(-rate, min(rate, dd))
        U = s.U0 + du_m
        cp, sp = math.cos(psi), math.sin(psi)
        return (du, dv, dr, r, U * cp - v * sp, U * sp + v * cp, dd)

    e = zigzag.sensor_noise(n, scale, seed, noise)
    out = zigzag.run(
        rhs, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        lambda t, x: (t, x[4], x[5], x[3] / RAD, s.U0 + x[0], x[1], x[2] / RAD, -x[6] / RAD),
        lambda x: x[3] / RAD, rudder_deg, heading_deg, first_side, n, dt_log, h, t_execute, e["psi"], dist,
        command=lambda c: -c)     # the published rudder is minus the contract's (docs/contract.md#run-data)
    return zigzag.logged(out, ["time", "x0", "y0", "psi", "u", "v", "r", "delta"], e)


def check_signs(form: str = "linear") -> dict:
    """Steady response to +10 deg (docs/contract.md#run-data) rudder after 200 s, noise-free:
    r > 0 and v < 0."""
    f = simulate_zigzag(Mariner(form=form), 10.0, 1e9, "starboard", duration=200.0, noise=False)
    return {"r_deg_s": float(f["r"].iloc[-1]), "v_m_s": float(f["v"].iloc[-1])}
