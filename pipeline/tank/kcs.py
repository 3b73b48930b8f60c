"""3-DOF MMG model of the KCS at model scale (SIMMAN 2020 deep water), integrated with RK4.

Model: the standard MMG method (Yasukawa & Yoshimura, J. Mar. Sci. Technol. 20 (2015) 37-52) for
hull, propeller and rudder forces, with Yoshimura's KCS coefficient set (SIMMAN 2008 proceedings),
as listed in docs/virtual-tank.md#the-ship (and its sources).  The coefficients are
non-dimensional, so the same set serves at any Froude-similar scale; here L = 6.0702 m.

Axes and signs (the MMG ones coincide with docs/contract.md#run-data here):

- x forward, y to starboard, z down; psi from x0 toward y0; r > 0 turns the bow to starboard;
  v > 0 is sway to starboard.  Earth-fixed origin at the midship position at t = 0.
- The hull coefficients are written in the drift angle ``beta = atan2(-v, u)`` (positive when the
  ship drifts to PORT, as it does in a starboard turn), which is where the MMG sign convention differs
  from the canonical one: the code converts v -> beta and never exposes beta.
- Rudder angle: ``delta > 0`` deflects the trailing edge to starboard, the rudder normal force
  F_N > 0 then pushes the stern to port (Y_R = -(1 + aH) F_N cos delta < 0) and, with
  x_R + aH x_H < 0, gives N_R > 0: a starboard turn.  So the MMG rudder angle equals the canonical
  delta (positive delta makes r positive); ``tests/test_tank.py`` checks this.  (MARIN's files use the
  opposite sign; their reader flips it, not this model.)

Equations of motion at midship, with the added-mass velocity terms folded into the hull coefficients
as in Yoshimura's set ("Xbr - m'y", "Yr - m'x"):

    (m + mx) du/dt                = X_H + X_R + X_P + m v r + xG m r^2
    (m + my) dv/dt + xG m dr/dt   = Y_H + Y_R - m u r
    (IzG + xG^2 m + Jz) dr/dt + xG m dv/dt = N_H + N_R - xG m u r

Decisions where the coefficient list is silent (documented, not tuned):

- Centre of gravity at the KCS's LCB, x'_G = -0.0148 (1.48 % L aft of midship, SIMMAN geometry);
  the hull derivatives are taken about midship.  With it, the central-difference linearisation
  (:func:`linearise`) gives K' 7.28, T1' 12.8, T2' 0.30, T3' 0.73, T' 12.3 against the reference's
  7.33, 12.9, 0.30, 0.73, 12.4 (with xG = 0 it would be K' 5.3, T' 8.9).  Yaw radius of gyration
  0.25 L (SIMMAN).
- Added masses as the literal formulas of the list (m'x = 1790.85 / (L^2 d / 2), ...).
- Wake in manoeuvring: w_P = w_P0 exp(-4 beta_P^2), beta_P = beta - x'_P r' (Hirano/Yoshimura form;
  the list gives no C1, C2 for the 2015 form).
- Flow-straightening coefficient gamma_R chosen by the sign of beta_R = beta - l'_R r'
  (0.492 for beta_R > 0, 0.338 otherwise), as in Yasukawa & Yoshimura 2015.  This is the model's
  only port/starboard asymmetry (a single-screw propeller effect): port and starboard runs mirror
  each other only approximately.
- Water density 1000 kg/m^3 (fresh-water tank); the non-dimensional model does not depend on it.
- Propeller at constant rps, trimmed (:func:`trim_rps`) so that the model holds the approach speed
  straight ahead with the rudder amidships.

All internal quantities are SI with angles in radians; :class:`KCSShip` speaks degrees at its edges.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.optimize import brentq

from pipeline.config import TankConfig
from pipeline.errors import ModelError
from pipeline.units import deg2rad, rad2deg


@dataclass(frozen=True)
class KCSCoefficients:
    """Yoshimura's KCS MMG set (non-dimensional; see the module docstring for the conventions)."""

    # principal particulars (model scale, m; scale-free ratios)
    breadth: float = 0.8498
    draft: float = 0.285
    displacement: float = 0.9565          # m^3
    rho: float = 1000.0                   # kg/m^3
    gyration: float = 0.25                # yaw radius of gyration / L
    xg: float = -0.0148                   # x'_G, centre of gravity / L (forward positive)
    # full-scale reference for the added-mass formulas
    full_lpp: float = 230.0
    full_draft: float = 10.8
    mx_full: float = 1790.85
    my_full: float = 44324.18
    jz_full: float = 140067300.0
    # hull (on rho/2 L d U^2 and rho/2 L^2 d U^2)
    X0: float = -0.0167
    Xbb: float = -0.0549
    Xbr_my: float = -0.1084
    Xrr: float = -0.0120
    Xbbbb: float = -0.0417
    Yb: float = 0.2252
    Yr_mx: float = 0.0398
    Ybbb: float = 1.7179
    Ybbr: float = -0.4832
    Ybrr: float = 0.8341
    Yrrr: float = -0.0050
    Nb: float = 0.1111
    Nr: float = -0.0465
    Nbbb: float = 0.1752
    Nbbr: float = -0.6168
    Nbrr: float = 0.0512
    Nrrr: float = -0.0387
    # propeller
    dp_full: float = 7.9                  # m, full scale
    wp0: float = 0.355                    # 1 - wP = 0.645
    tp: float = 0.207                     # 1 - t = 0.793
    kt0: float = 0.5228
    kt1: float = -0.4390
    kt2: float = -0.0609
    xp: float = -0.4565                   # x'_P
    # rudder
    epsilon: float = 0.956
    eta: float = 0.7979
    kappa: float = 0.633
    xr: float = -0.5                      # x'_R
    tr: float = 0.258                     # 1 - tR = 0.742
    ah: float = 0.361
    xh: float = -0.436                    # x'_H
    ar_ratio: float = 54.86               # A_R = L d / ar_ratio
    aspect: float = 2.164
    gamma_plus: float = 0.492             # gamma_R for beta_R > 0
    gamma_minus: float = 0.338            # gamma_R for beta_R <= 0
    lr: float = -0.755                    # l'_R


DEFAULT_TANK = TankConfig()
DEFAULT_COEFFS = KCSCoefficients()

# indices into the parameter vector handed to the compiled code
(I_RHO, I_L, I_D, I_M, I_MX, I_MY, I_IZ, I_XG,
 I_X0, I_XBB, I_XBR, I_XRR, I_XBBBB,
 I_YB, I_YR, I_YBBB, I_YBBR, I_YBRR, I_YRRR,
 I_NB, I_NR, I_NBBB, I_NBBR, I_NBRR, I_NRRR,
 I_DP, I_WP0, I_TP, I_K0, I_K1, I_K2, I_XP, I_N,
 I_EPS, I_ETA, I_KAPPA, I_XRM, I_TR, I_AH, I_XHM, I_AR, I_FA, I_GP, I_GM, I_LR,
 I_HOLD, I_U0, N_PARAMS) = range(48)


def param_vector(cfg: TankConfig, coeffs: KCSCoefficients, rps: float) -> np.ndarray:
    """Dimensional parameter vector (SI) for the compiled force model at model scale ``cfg.lpp``.

    ``cfg.extra_yaw_damping`` is added to N'_rrr and ``cfg.hold_speed`` freezes u at
    ``cfg.approach_speed``.

    Parameters
    ----------
    cfg : TankConfig
        The tank (length m, approach speed m/s, effects).
    coeffs : KCSCoefficients
        The KCS coefficient set.
    rps : float
        Propeller speed, 1/s.

    Returns
    -------
    numpy.ndarray
        The parameter vector the force model reads (SI units).
    """
    c = coeffs
    L, d, rho = cfg.lpp, c.draft, c.rho
    p = np.zeros(N_PARAMS)
    nd_mass = 0.5 * rho * L * L * d                  # rho/2 L^2 d
    m = rho * c.displacement
    fl2d = 0.5 * c.full_lpp ** 2 * c.full_draft
    mx = c.mx_full / fl2d * nd_mass
    my = c.my_full / fl2d * nd_mass
    jz = c.jz_full / (0.5 * c.full_lpp ** 4 * c.full_draft) * nd_mass * L * L
    izg = m * (c.gyration * L) ** 2
    xg = c.xg * L
    p[I_RHO], p[I_L], p[I_D], p[I_M], p[I_MX], p[I_MY] = rho, L, d, m, mx, my
    p[I_IZ] = izg + xg * xg * m + jz
    p[I_XG] = xg
    p[I_X0:I_XBBBB + 1] = (c.X0, c.Xbb, c.Xbr_my, c.Xrr, c.Xbbbb)
    p[I_YB:I_YRRR + 1] = (c.Yb, c.Yr_mx, c.Ybbb, c.Ybbr, c.Ybrr, c.Yrrr)
    p[I_NB:I_NRRR + 1] = (c.Nb, c.Nr, c.Nbbb, c.Nbbr, c.Nbrr, c.Nrrr + cfg.extra_yaw_damping)
    p[I_DP] = c.dp_full * L / c.full_lpp             # Froude-similar propeller diameter
    p[I_WP0], p[I_TP], p[I_K0], p[I_K1], p[I_K2], p[I_XP] = c.wp0, c.tp, c.kt0, c.kt1, c.kt2, c.xp
    p[I_N] = rps
    aspect = c.aspect
    p[I_EPS], p[I_ETA], p[I_KAPPA] = c.epsilon, c.eta, c.kappa
    p[I_XRM], p[I_TR], p[I_AH], p[I_XHM] = c.xr * L, c.tr, c.ah, c.xh * L
    p[I_AR] = L * d / c.ar_ratio
    p[I_FA] = 6.13 * aspect / (2.25 + aspect)
    p[I_GP], p[I_GM], p[I_LR] = c.gamma_plus, c.gamma_minus, c.lr
    p[I_HOLD] = 1.0 if cfg.hold_speed else 0.0
    p[I_U0] = cfg.approach_speed
    return p


@njit(cache=True)
def _forces(s, delta, p):
    """Derivatives of state s = (u, v, r, x0, y0, psi) [m/s, m/s, rad/s, m, m, rad] for rudder delta [rad]."""
    u, v, r, psi = s[0], s[1], s[2], s[5]
    rho, L, d = p[I_RHO], p[I_L], p[I_D]
    m, mx, my, iz, xg = p[I_M], p[I_MX], p[I_MY], p[I_IZ], p[I_XG]
    U = math.sqrt(u * u + v * v)
    if U < 1e-9:
        U = 1e-9
    beta = math.atan2(-v, u)
    rp = r * L / U
    q = 0.5 * rho * L * d * U * U
    b2 = beta * beta
    XH = q * (p[I_X0] + p[I_XBB] * b2 + p[I_XBR] * beta * rp + p[I_XRR] * rp * rp + p[I_XBBBB] * b2 * b2)
    YH = q * (p[I_YB] * beta + p[I_YR] * rp + p[I_YBBB] * b2 * beta + p[I_YBBR] * b2 * rp
              + p[I_YBRR] * beta * rp * rp + p[I_YRRR] * rp * rp * rp)
    NH = q * L * (p[I_NB] * beta + p[I_NR] * rp + p[I_NBBB] * b2 * beta + p[I_NBBR] * b2 * rp
                  + p[I_NBRR] * beta * rp * rp + p[I_NRRR] * rp * rp * rp)
    # propeller
    n, dp = p[I_N], p[I_DP]
    beta_p = beta - p[I_XP] * rp
    wp = p[I_WP0] * math.exp(-4.0 * beta_p * beta_p)
    up = u * (1.0 - wp)
    J = up / (n * dp)
    kt = p[I_K0] + p[I_K1] * J + p[I_K2] * J * J
    XP = (1.0 - p[I_TP]) * rho * n * n * dp ** 4 * kt
    # rudder
    if J > 1e-6 and kt > 0.0:
        load = math.sqrt(1.0 + 8.0 * kt / (math.pi * J * J)) - 1.0
    else:
        load = 0.0
    eta = p[I_ETA]
    ur = p[I_EPS] * up * math.sqrt(eta * (1.0 + p[I_KAPPA] * load) ** 2 + (1.0 - eta))
    beta_r = beta - p[I_LR] * rp
    gam = p[I_GP] if beta_r > 0.0 else p[I_GM]
    vr = U * gam * beta_r
    alpha_r = delta - math.atan2(vr, ur)
    fn = 0.5 * rho * p[I_AR] * (ur * ur + vr * vr) * p[I_FA] * math.sin(alpha_r)
    XR = -(1.0 - p[I_TR]) * fn * math.sin(delta)
    YR = -(1.0 + p[I_AH]) * fn * math.cos(delta)
    NR = -(p[I_XRM] + p[I_AH] * p[I_XHM]) * fn * math.cos(delta)
    # equations of motion
    out = np.empty(6)
    if p[I_HOLD] > 0.5:
        out[0] = 0.0
    else:
        out[0] = (XH + XR + XP + m * v * r + xg * m * r * r) / (m + mx)
    fy = YH + YR - m * u * r
    fn_ = NH + NR - xg * m * u * r
    a11, a12, a21, a22 = m + my, xg * m, xg * m, iz
    det = a11 * a22 - a12 * a21
    out[1] = (a22 * fy - a12 * fn_) / det
    out[2] = (a11 * fn_ - a21 * fy) / det
    c, sn = math.cos(psi), math.sin(psi)
    out[3] = u * c - v * sn
    out[4] = u * sn + v * c
    out[5] = r
    return out


@njit(cache=True)
def _rk4(s, delta, h, p):
    k1 = _forces(s, delta, p)
    k2 = _forces(s + 0.5 * h * k1, delta, p)
    k3 = _forces(s + 0.5 * h * k2, delta, p)
    k4 = _forces(s + h * k3, delta, p)
    return s + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


@njit(cache=True)
def _servo_effects(d_in, lag_state, h, lag, asym, stall):
    """(rudder angle the forces see before the offset, new lag state) [rad] from the delayed servo
    angle ``d_in``: a first-order lag of time constant ``lag`` s (explicit Euler; its output is the
    state before the step), then x (1 + asym sign), then ``stall`` tanh(angle / stall) (rad; 0 =
    off).  The one definition: :func:`_run` and :class:`KCSShip` both call it."""
    if lag > 0.0:
        d_in, lag_state = lag_state, lag_state + h * (d_in - lag_state) / lag
    if asym != 0.0:
        if d_in > 0.0:
            d_in = d_in * (1.0 + asym)
        elif d_in < 0.0:
            d_in = d_in * (1.0 - asym)
    if stall > 0.0:
        d_in = stall * math.tanh(d_in / stall)
    return d_in, lag_state


class Grid(NamedTuple):
    """The time grid of :func:`_run`."""

    n_log: int            # logged rows
    substeps: int         # integration steps per logging step
    h: float              # s, integration step


class Command(NamedTuple):
    """What the helm asks of :func:`_run` (angles in rad)."""

    zigzag: bool          # True: counter-rudder when the measured heading reaches +-trigger
    rudder: float         # rad, the rudder angle asked for
    trigger: float        # rad, the zigzag's heading trigger
    side: float           # +1 the first rudder to starboard, -1 to port
    release: int = -1     # logging row from which the command is 0 (a pull-out); -1: never


class Servo(NamedTuple):
    """The steering gear and the rudder effects of :func:`_run` (:func:`_servo_effects`)."""

    rate: float           # rad/s, rate limit
    dmax: float           # rad, angle limit
    delay_steps: int      # integration steps of dead time between the servo and the force model
    offset: float         # rad, added to the effective rudder
    lag: float = 0.0      # s, first-order lag of the effective rudder
    asym: float = 0.0     # effective angle x (1 + asym sign(angle))
    stall: float = 0.0    # rad, effective angle = stall tanh(angle / stall); 0 = off


@njit(cache=True)
def _run(p, s0, grid, command, servo, psi_noise):
    """Simulate a manoeuvre; returns (grid.n_log, 7): u, v, r, x0, y0, psi, servo rudder (SI, rad).

    Row k is the state at t = k * substeps * h (:class:`Grid`).  The rudder command is decided at
    each logging instant from the MEASURED heading psi + psi_noise[k] (:class:`Command`: zigzag,
    counter-rudder when the measured heading reaches +-trigger; otherwise a constant command
    side * rudder, returned to 0 from logging row ``release`` on when release >= 0: a pull-out).  The
    servo moves toward the command at ``rate`` (rad/s) within +-dmax; the force model sees the servo
    angle ``delay_steps`` integration steps earlier, through :func:`_servo_effects` (``lag`` s,
    ``asym``, ``stall`` rad), plus ``offset`` (:class:`Servo`).
    """
    n_log, substeps, h = grid
    zigzag, rudder, trigger, side, release = command
    rate, dmax, delay_steps, offset, lag, asym, stall = servo
    out = np.empty((n_log, 7))
    s = s0.copy()
    delta = 0.0
    sign = side
    hist = np.zeros(delay_steps + 1)
    pos = 0
    lag_state = 0.0
    for k in range(n_log):
        out[k, :6] = s
        out[k, 6] = delta
        if k == n_log - 1:
            break
        psi_m = s[5] + psi_noise[k]
        if zigzag:
            if sign > 0 and psi_m >= trigger:
                sign = -1.0
            elif sign < 0 and psi_m <= -trigger:
                sign = 1.0
        cmd = sign * rudder
        if release >= 0 and k >= release:
            cmd = 0.0
        for _ in range(substeps):
            step = cmd - delta
            lim = rate * h
            if step > lim:
                step = lim
            elif step < -lim:
                step = -lim
            delta = min(max(delta + step, -dmax), dmax)
            hist[pos] = delta
            pos = (pos + 1) % (delay_steps + 1)
            d_in, lag_state = _servo_effects(hist[pos], lag_state, h, lag, asym, stall)  # oldest entry
            s = _rk4(s, d_in + offset, h, p)
    return out


def u_dot_straight(p: np.ndarray, u: float) -> float:
    """Surge acceleration straight ahead with the rudder amidships.

    Parameters
    ----------
    p : numpy.ndarray
        Parameter vector of :func:`param_vector`.
    u : float
        Surge speed, m/s.

    Returns
    -------
    float
        du/dt, m/s^2.
    """
    q = p.copy()
    q[I_HOLD] = 0.0
    return float(_forces(np.array([u, 0.0, 0.0, 0.0, 0.0, 0.0]), 0.0, q)[0])


def trim_rps(cfg: TankConfig = DEFAULT_TANK, coeffs: KCSCoefficients = DEFAULT_COEFFS) -> float:
    """Propeller speed that holds ``cfg.approach_speed`` straight ahead (thrust = resistance).

    Parameters
    ----------
    cfg : TankConfig
        The tank (approach speed m/s).
    coeffs : KCSCoefficients
        The KCS coefficient set.

    Returns
    -------
    float
        Propeller speed, 1/s.
    """
    def f(n):
        return u_dot_straight(param_vector(cfg, coeffs, n), cfg.approach_speed)
    try:
        return float(brentq(f, 1.0, 200.0, xtol=1e-10))
    except ValueError:
        raise ModelError("cannot trim the propeller to hold the approach speed") from None


def linearise(cfg: TankConfig = DEFAULT_TANK, coeffs: KCSCoefficients = DEFAULT_COEFFS, *,
              step: float = 1e-6) -> dict[str, float]:
    """Second-order Nomoto indices of the sway-yaw dynamics linearised straight ahead.

    Central differences in v (m/s), r (rad/s) and delta (rad) at the trimmed approach condition;
    at beta_R = 0 the flow-straightening coefficient has a kink (gamma_R switches), and central
    differences take the mean of the two one-sided slopes.

    Parameters
    ----------
    cfg : TankConfig
        The tank.
    coeffs : KCSCoefficients
        The KCS coefficient set.
    step : float
        Central-difference step in each of v (m/s), r (rad/s), delta (rad).

    Returns
    -------
    dict
        Dimensional K (1/s), T1, T2, T3, T (s) and the non-dimensional K', T1', T2', T3', T' (time
        scale L/U).
    """
    p = param_vector(cfg, coeffs, trim_rps(cfg, coeffs))
    s0 = initial_state(cfg)

    def f(s, d):
        return _forces(s, d, p)[1:3]

    a = np.zeros((2, 2))
    for j, idx in enumerate((1, 2)):
        e = np.zeros(6)
        e[idx] = step
        a[:, j] = (f(s0 + e, 0.0) - f(s0 - e, 0.0)) / (2 * step)
    b = (f(s0, step) - f(s0, -step)) / (2 * step)
    (a11, a12), (a21, a22) = a
    det = a11 * a22 - a12 * a21
    tsum, tprod = -(a11 + a22) / det, 1.0 / det
    root = math.sqrt(max(tsum * tsum - 4.0 * tprod, 0.0))
    k = (a21 * b[0] - a11 * b[1]) / det
    t1, t2 = (tsum + root) / 2.0, (tsum - root) / 2.0
    t3 = b[1] / det / k
    lu = cfg.lpp / cfg.approach_speed
    out = {"K": k, "T1": t1, "T2": t2, "T3": t3, "T": t1 + t2 - t3}
    out.update({"K'": k * lu, "T1'": t1 / lu, "T2'": t2 / lu, "T3'": t3 / lu, "T'": (t1 + t2 - t3) / lu})
    return {key: float(val) for key, val in out.items()}


def initial_state(cfg: TankConfig) -> np.ndarray:
    """Straight ahead at the approach speed, at the origin, heading 0.

    Parameters
    ----------
    cfg : TankConfig
        The tank (approach speed m/s).

    Returns
    -------
    numpy.ndarray
        (u m/s, v m/s, r rad/s, x0 m, y0 m, psi rad).
    """
    return np.array([cfg.approach_speed, 0.0, 0.0, 0.0, 0.0, 0.0])


class KCSShip:
    """Stepping simulator of the virtual KCS for closed-loop use (noise-free).

    ``step(delta_cmd_deg, dt, disturbance_deg=0.0)`` advances ``dt`` seconds (RK4 substeps no longer
    than ``cfg.sim_dt``): the servo moves toward the command at ``cfg.rudder_rate`` within
    +-``cfg.rudder_max``; the forces see the servo angle (delayed by ``cfg.rudder_delay``, through the
    lag, asymmetry and stall of ``cfg``) plus ``cfg.rudder_offset`` plus ``disturbance_deg`` (wind
    and waves as an equivalent rudder angle).
    Returns dict(time s, x0 m, y0 m, psi deg, u m/s, v m/s, r deg/s, delta deg = actual servo angle).
    The effect settings of ``cfg`` apply as in :func:`pipeline.tank.simulate`.
    """

    def __init__(self, cfg: TankConfig = DEFAULT_TANK, coeffs: KCSCoefficients = DEFAULT_COEFFS):
        self.cfg = cfg
        self.coeffs = coeffs
        self.rps = trim_rps(cfg, coeffs)
        self.rpm = 60.0 * self.rps
        self._p = param_vector(cfg, coeffs, self.rps)
        self.reset()

    def reset(self) -> dict:
        """Straight ahead at the approach speed, psi 0, rudder amidships, time 0."""
        self.time = 0.0
        self._s = initial_state(self.cfg)
        self._delta = 0.0
        self._hist: deque[float] = deque()
        self._lag = 0.0
        return self.state()

    def state(self) -> dict:
        u, v, r, x, y, psi = (float(x) for x in self._s)
        return {"time": self.time, "x0": x, "y0": y, "psi": rad2deg(psi), "u": u, "v": v,
                "r": rad2deg(r), "delta": rad2deg(self._delta)}

    def step(self, delta_cmd_deg: float, dt: float, disturbance_deg: float = 0.0) -> dict:
        if not dt > 0:
            raise ModelError(f"time step must be positive, got {dt}")
        cfg = self.cfg
        n = max(1, math.ceil(dt / cfg.sim_dt - 1e-9))
        h = dt / n
        cmd = deg2rad(float(delta_cmd_deg))
        lim = deg2rad(cfg.rudder_rate) * h
        dmax = deg2rad(cfg.rudder_max)
        extra = deg2rad(cfg.rudder_offset + float(disturbance_deg))
        lag = int(round(cfg.rudder_delay / h))
        for _ in range(n):
            self._delta = min(max(self._delta + min(max(cmd - self._delta, -lim), lim), -dmax), dmax)
            self._hist.append(self._delta)
            while len(self._hist) > lag + 1:
                self._hist.popleft()
            d_eff = self._hist[0] if len(self._hist) == lag + 1 else 0.0
            d_eff, self._lag = _servo_effects(d_eff, self._lag, h, cfg.rudder_lag, cfg.rudder_asymmetry,
                                              deg2rad(cfg.rudder_stall_deg))
            self._s = _rk4(self._s, d_eff + extra, h, self._p)
            self.time += h
        return self.state()
