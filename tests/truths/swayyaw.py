"""A continuous-time sway-yaw ship with injectable effects: an independent truth for the diagnosis.

Deliberately not the method's model: it is integrated in continuous time by classical RK4 at a fine
step (default 0.01 s) and only *logged* every 0.08 s; the rudder is a servo state; the effects are
written in forms of their own (r|r| beside r^3, a first-order servo lag beside a dead time, tanh
stall, side-dependent effectiveness, |.| cross terms, a surge equation driven by drift and yaw).
It imports nothing from ``pipeline``.

Equations (units of docs/contract.md#run-data: v m/s positive to starboard, r deg/s, psi deg, delta deg,
u m/s, t s; positive delta makes r positive)::

    servo      d_log'  = clip(k_s (cmd - d_log), -rate, +rate)          the rudder angle sensor reads d_log
    dead time  d_dly(t) = d_log(t - delay_s)
    servo lag  d_lag'  = (d_dly - d_lag) / lag_s                        (d_lag = d_dly when lag_s = 0)
    offset     d_e     = d_lag + offset_deg
    rudder     f(d_e)  = g(d_e) * (1 + asym) if d_e > 0 else g(d_e) * (1 - asym)
               g(x)    = stall_deg tanh(x / stall_deg)                  (g(x) = x when stall_deg is None)
    s          = u / U0                                                 (1 without speed loss)
    v' = s a11 v + s a12 r + s^2 b11 f(d_e) + y_vv v|v| + y_vrr v r^2 + y_vabsr v|r|
    r' = s a21 v + s a22 r + s^2 b21 f(d_e) + n_rr r|r| + n_rrr r^3 + n_vv v|v|
         + n_vvr v^2 r + n_rabsv r|v|
    u' = -(u - U0) / tau_u + x_vr v r_rad  (x_vr >= 0: a turn with drift, v r < 0, slows the ship)
    psi' = r;  x0' = u cos(psi) - v sin(psi);  y0' = u sin(psi) + v cos(psi)

Linear coefficients a11 ... b21 are those of docs/contract.md#the-identification-model in continuous time;
each ship is specified by its Nomoto indices K, T1, T2, T3 plus the sway damping a11 and the sway rudder force
b11 (:func:`nomoto_to_coefficients`).  Nonlinear magnitudes are usually given as *shares* of the
ship's own linear behaviour at a reference amplitude (:func:`effect_coefficients`), so one share
means the same thing on a fast and on a slow ship.

Zigzag logic: straight approach for ``t_execute`` s at rudder 0, then the commanded rudder is
+-rudder_deg, switched at a logging instant when the *measured* heading (with its noise) passes
+-heading_deg, as a tank's autopilot would.

"Clean" means: exactly these equations without any effect (linear hull, linear rudder, no offset,
no delay, no lag, constant speed), integrated at the fine step, plus seeded sensor noise (white by
default; AR(1) coloured and an encoder quantisation of the logged rudder are options of
:class:`Sensors`).  Even clean data are not the Euler model of docs/contract.md#the-identification-model at
0.08 s, and the logged rudder is the servo angle sampled every 0.08 s, not the rudder the integrator saw
between samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

RAD = math.pi / 180.0


def nomoto_to_coefficients(K: float, T1: float, T2: float, T3: float, a11: float, b11: float) -> dict:
    """Linear sway-yaw coefficients (docs/contract.md#the-identification-model) from Nomoto indices.

    K 1/s, T1, T2, T3 s (Eq. 6: T1 T2 = 1/D, T1 + T2 = -(a11 + a22)/D, K T3 = b21/D,
    K = (a21 b11 - a11 b21)/D, D = a11 a22 - a12 a21); a11 1/s and b11 (m/s^2)/deg are chosen.
    """
    D = 1.0 / (T1 * T2)
    a22 = -(T1 + T2) * D - a11
    b21 = K * T3 * D
    a21 = (K * D + a11 * b21) / b11
    a12 = (a11 * a22 - D) / a21
    return {"a11": a11, "a12": a12, "a21": a21, "a22": a22, "b11": b11, "b21": b21}


def coefficients_to_nomoto(c: dict) -> dict:
    """K 1/s, T1, T2, T3, T s of a coefficient dict (the inverse check of the above)."""
    a11, a12, a21, a22, b11, b21 = (c[k] for k in ("a11", "a12", "a21", "a22", "b11", "b21"))
    D = a11 * a22 - a12 * a21
    K = (a21 * b11 - a11 * b21) / D
    s, p = -(a11 + a22) / D, 1.0 / D
    disc = math.sqrt(max(s * s - 4 * p, 0.0))
    T1, T2 = (s + disc) / 2, (s - disc) / 2
    T3 = b21 / D / K
    return {"K": K, "T1": T1, "T2": T2, "T3": T3, "T": T1 + T2 - T3}


@dataclass(frozen=True)
class Ship:
    """A ship at model scale, given by its Nomoto indices (docs/contract.md#the-identification-model /
    docs/indices.md#nomoto-indices-from-the-identified-model).

    lpp_m m, u0_m_s m/s approach speed, K 1/s, T1/T2/T3 s, a11 1/s, b11 (m/s^2)/deg,
    rudder_rate deg/s (servo rate limit, model scale), servo_gain 1/s, max_rudder deg.
    """

    name: str
    lpp_m: float
    u0_m_s: float
    K: float
    T1: float
    T2: float
    T3: float
    a11: float
    b11: float
    rudder_rate: float = 15.0
    servo_gain: float = 10.0
    max_rudder: float = 35.0

    @property
    def coefficients(self) -> dict:
        return nomoto_to_coefficients(self.K, self.T1, self.T2, self.T3, self.a11, self.b11)

    @property
    def T(self) -> float:
        return self.T1 + self.T2 - self.T3

    def nondimensional(self) -> dict:
        """K' = K L/U, T' = T U/L (docs/indices.md#non-dimensional-indices)."""
        lu = self.lpp_m / self.u0_m_s
        return {"K'": self.K * lu, "T1'": self.T1 / lu, "T2'": self.T2 / lu, "T3'": self.T3 / lu,
                "T'": self.T / lu}


# A fast, strongly stable ship (a twin-screw ferry or naval ship model, Fn 0.40, fast steering gear
# 25 deg/s at model scale): K' 0.96, T1' 1.0, T2' 0.16, T3' 0.28, T' 0.875.  a11 = -3.0 1/s and
# b11 = 0.0331 (m/s^2)/deg put the steady drift at v/r = -0.031 (m/s)/(deg/s): a pivot point 0.44 L
# ahead of midship in a steady turn.  Resulting coefficients: a11 -3.0, a12 -0.1496, a21 -15.87,
# a22 -1.625, b11 0.0331, b21 0.675.  Clean zigzags: 10/10 overshoots 4.0, 4.6 deg; 20/20 11.5, 12.7.
FAST = Ship("fast", lpp_m=4.0, u0_m_s=2.5, K=0.6, T1=1.6, T2=0.25, T3=0.45, a11=-3.0, b11=0.03308,
            rudder_rate=25.0)

# A slow, nearly course-unstable full form (a tanker or bulk carrier model, Fn 0.135): K' 2.2,
# T1' 8.0, T' 7.8 (T1 = 40 s: the slow pole is 1/40 1/s, close to zero).  a11 = -0.6 1/s and
# b11 = 0.00227 (m/s^2)/deg give v/r = -0.031 (m/s)/(deg/s): a pivot point 0.4 L ahead of midship,
# as for full forms.  Resulting coefficients: a11 -0.6, a12 -0.0237, a21 -1.616, a22 -0.0917,
# b11 0.00227, b21 0.01833 (little yaw damping of its own: the sway coupling carries it).
SLOW = Ship("slow", lpp_m=4.5, u0_m_s=0.9, K=0.44, T1=40.0, T2=1.5, T3=2.5, a11=-0.6, b11=0.002269,
            rudder_rate=15.0)

SHIPS = {"fast": FAST, "slow": SLOW}


@dataclass(frozen=True)
class Effects:
    """Effects injected into the truth (all off by default = clean).  Units in each comment."""

    offset_deg: float = 0.0          # deg, effective rudder = lagged/delayed logged rudder + offset
    delay_s: float = 0.0             # s, dead time between logged and effective rudder (>= the fine step)
    lag_s: float = 0.0               # s, first-order servo lag between logged and effective rudder
    n_rr: float = 0.0                # 1/deg, r' += n_rr r|r| (negative = more yaw damping)
    n_rrr: float = 0.0               # s/deg^2, r' += n_rrr r^3
    y_vv: float = 0.0                # 1/m, v' += y_vv v|v|
    n_vv: float = 0.0                # deg/m^2: r' (deg/s^2) += n_vv v|v| (v m/s)
    y_vrr: float = 0.0               # v' (m/s^2) += y_vrr v r^2  (r deg/s)
    y_vabsr: float = 0.0             # v' += y_vabsr v |r|
    n_vvr: float = 0.0               # r' (deg/s^2) += n_vvr v^2 r
    n_rabsv: float = 0.0             # r' += n_rabsv r |v|
    stall_deg: float | None = None   # deg, rudder force ~ stall tanh(d_e / stall) instead of d_e
    asym: float = 0.0                # rudder effectiveness 1 + asym to starboard (d_e > 0), 1 - asym to port
    x_vr: float = 0.0                # 1/rad: u' += x_vr v r_rad (speed loss; enables s = u/U0)
    tau_u_lu: float = 8.0            # surge recovery time constant, in units of L/U0

    @property
    def speed_loss(self) -> bool:
        return self.x_vr != 0.0


@dataclass(frozen=True)
class Sensors:
    """Measurement model of the logged channels (each seeded).

    Standard deviations: psi deg, r deg/s, v m/s, u m/s, delta deg.  ``ar1_phi`` in [0, 1): the
    noise of every channel is AR(1) with this correlation between 0.08 s samples and the same
    stationary standard deviation (0 = white).  ``quant_delta`` deg: the logged rudder is rounded
    to this encoder resolution (0 = none), after its noise.
    """

    noise_psi: float = 0.05
    noise_r: float = 0.05
    noise_v: float = 0.005
    noise_u: float = 0.005
    noise_delta: float = 0.05
    ar1_phi: float = 0.0
    quant_delta: float = 0.0


@dataclass(frozen=True)
class Zigzag:
    """A rudder/heading zigzag: rudder_deg deg, heading_deg deg, first execute to ``first_side``."""

    rudder_deg: float
    heading_deg: float
    first_side: str = "starboard"
    duration: float = 70.0          # s, logged span
    t_execute: float = 1.0          # s of straight approach before the first execute

    @property
    def name(self) -> str:
        side = "S" if self.first_side == "starboard" else "P"
        return f"zz_{self.rudder_deg:g}_{self.heading_deg:g}_{side}"

    @property
    def test_name(self) -> str:
        return f"zigzag {self.rudder_deg:g}/{self.heading_deg:g} {self.first_side}"


@dataclass(frozen=True)
class Truth:
    ship: Ship = FAST
    effects: Effects = field(default_factory=Effects)
    sensors: Sensors = field(default_factory=Sensors)
    dt_log: float = 0.08            # s, logging step
    h: float = 0.01                 # s, RK4 step (dt_log must be a multiple)

    def with_effects(self, **kw) -> Truth:
        return replace(self, effects=replace(self.effects, **kw))


def _noise(rng: np.random.Generator, sigma: float, n: int, phi: float) -> np.ndarray:
    """Stationary AR(1) noise of standard deviation sigma (white when phi = 0)."""
    w = rng.normal(0.0, sigma, n)
    if phi <= 0.0 or sigma == 0.0:
        return w
    e = np.empty(n)
    e[0] = w[0]
    c = math.sqrt(1.0 - phi * phi)
    for k in range(1, n):
        e[k] = phi * e[k - 1] + c * w[k]
    return e


def simulate(truth: Truth, zz: Zigzag, seed: int, noise: bool = True) -> pd.DataFrame:
    """Simulate one zigzag; returns the logged frame (time, x0, y0, psi, u, v, r, delta), units of
    docs/contract.md#run-data.

    Also returned as ``frame.attrs``: the true (noise-free) series under ``"true"`` (a DataFrame
    with the same columns plus ``delta_eff``, the rudder the hull felt, deg).
    """
    ship, ef, sen = truth.ship, truth.effects, truth.sensors
    c = ship.coefficients
    a11, a12, a21, a22, b11, b21 = (c[k] for k in ("a11", "a12", "a21", "a22", "b11", "b21"))
    u0 = ship.u0_m_s
    h = truth.h
    sub = int(round(truth.dt_log / h))
    if abs(sub * h - truth.dt_log) > 1e-9:
        raise ValueError(f"dt_log {truth.dt_log} s is not a multiple of the step {h} s")
    if 0.0 < ef.delay_s < h:
        raise ValueError(f"a dead time ({ef.delay_s} s) shorter than the step {h} s cannot be resolved")
    n = int(round(zz.duration / truth.dt_log)) + 1
    nsub = (n - 1) * sub
    rng = np.random.default_rng(seed)
    phi = sen.ar1_phi
    if noise:
        e_psi = _noise(rng, sen.noise_psi, n, phi)
        e_r = _noise(rng, sen.noise_r, n, phi)
        e_v = _noise(rng, sen.noise_v, n, phi)
        e_u = _noise(rng, sen.noise_u, n, phi)
        e_d = _noise(rng, sen.noise_delta, n, phi)
    else:
        e_psi = e_r = e_v = e_u = e_d = np.zeros(n)

    rate, ks = ship.rudder_rate, ship.servo_gain
    delay, lag, off = ef.delay_s, ef.lag_s, ef.offset_deg
    stall, asym = ef.stall_deg, ef.asym
    speed = ef.speed_loss
    tau_u = ef.tau_u_lu * ship.lpp_m / u0
    x_vr = ef.x_vr
    n_rr, n_rrr, y_vv, n_vv = ef.n_rr, ef.n_rrr, ef.y_vv, ef.n_vv
    y_vrr, y_vabsr, n_vvr, n_rabsv = ef.y_vrr, ef.y_vabsr, ef.n_vvr, ef.n_rabsv
    # servo history on the fine grid, for the dead time (linear interpolation between steps)
    hist = np.zeros(nsub + 2)

    def d_delayed(t: float, d_now: float, k: int) -> float:
        if delay == 0.0:
            return d_now
        td = t - delay
        if td <= 0.0:
            return 0.0
        x = td / h
        j = int(x)
        f = x - j
        if j + 1 > k:  # cannot happen for delay >= h
            return hist[k]
        return hist[j] * (1.0 - f) + hist[j + 1] * f

    def force(de: float) -> float:
        g = stall * math.tanh(de / stall) if stall else de
        if asym:
            g *= (1.0 + asym) if de > 0.0 else (1.0 - asym)
        return g

    def rhs(t, x, cmd, k):
        v, r, psi, u, X, Y, d, dl = x
        dd = ks * (cmd - d)
        dd = rate if dd > rate else (-rate if dd < -rate else dd)
        dly = d_delayed(t, d, k)
        if lag > 0.0:
            ddl = (dly - dl) / lag
            deff = dl + off
        else:
            ddl = 0.0
            deff = dly + off
        fd = force(deff)
        s = u / u0 if speed else 1.0
        s2 = s * s
        av, ar = abs(v), abs(r)
        dv = s * (a11 * v + a12 * r) + s2 * b11 * fd + y_vv * v * av + y_vrr * v * r * r + y_vabsr * v * ar
        dr = (s * (a21 * v + a22 * r) + s2 * b21 * fd + n_rr * r * ar + n_rrr * r * r * r + n_vv * v * av
              + n_vvr * v * v * r + n_rabsv * r * av)
        du = (-(u - u0) / tau_u + x_vr * v * r * RAD) if speed else 0.0
        ps = psi * RAD
        cp, sp = math.cos(ps), math.sin(ps)
        return (dv, dr, r, du, u * cp - v * sp, u * sp + v * cp, dd, ddl), deff

    x = [0.0, 0.0, 0.0, u0, 0.0, 0.0, 0.0, 0.0]
    out = np.zeros((n, 9))  # time x0 y0 psi u v r delta delta_eff
    sign = 1.0 if zz.first_side == "starboard" else -1.0
    cmd = 0.0
    executed = False
    for k in range(nsub + 1):
        t = k * h
        hist[k] = x[6]
        if k % sub == 0:
            i = k // sub
            deff_now = rhs(t, x, cmd, k)[1]
            out[i] = (t, x[4], x[5], x[2], x[3], x[0], x[1], x[6], deff_now)
            psi_meas = x[2] + e_psi[i]
            if not executed and t >= zz.t_execute - 1e-9:
                cmd, executed = sign * zz.rudder_deg, True
            elif executed:
                if cmd > 0 and psi_meas >= zz.heading_deg:
                    cmd = -zz.rudder_deg
                elif cmd < 0 and psi_meas <= -zz.heading_deg:
                    cmd = zz.rudder_deg
        if k == nsub:
            break
        k1 = rhs(t, x, cmd, k)[0]
        x2 = [a + 0.5 * h * b for a, b in zip(x, k1, strict=True)]
        k2 = rhs(t + 0.5 * h, x2, cmd, k)[0]
        x3 = [a + 0.5 * h * b for a, b in zip(x, k2, strict=True)]
        k3 = rhs(t + 0.5 * h, x3, cmd, k)[0]
        x4 = [a + h * b for a, b in zip(x, k3, strict=True)]
        k4 = rhs(t + h, x4, cmd, k)[0]
        x = [a + h / 6.0 * (b1 + 2 * b2 + 2 * b3 + b4)
             for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4, strict=True)]
        if not all(math.isfinite(z) for z in x) or abs(x[1]) > 200.0:
            raise ValueError(f"truth diverged at t = {t:.2f} s ({ship.name}, {zz.name})")
    true = pd.DataFrame(out, columns=["time", "x0", "y0", "psi", "u", "v", "r", "delta", "delta_eff"])
    frame = true.drop(columns="delta_eff").copy()
    frame["psi"] += e_psi
    frame["r"] += e_r
    frame["v"] += e_v
    frame["u"] += e_u
    d = frame["delta"].to_numpy() + e_d
    if sen.quant_delta > 0.0:
        d = np.round(d / sen.quant_delta) * sen.quant_delta
    frame["delta"] = d
    frame.attrs["true"] = true
    return frame


def reference_amplitudes(ship: Ship, duration: float = 70.0) -> dict:
    """Largest |r| deg/s and |v| m/s of the clean, noise-free 20/20 zigzag to starboard, and the
    ship's effective yaw damping 1/T 1/s: the scales the effect shares are taken against."""
    f = simulate(Truth(ship=ship), Zigzag(20, 20, "starboard", duration), seed=0, noise=False)
    return {"r_ref": float(np.abs(f["r"]).max()), "v_ref": float(np.abs(f["v"]).max()),
            "damping": 1.0 / ship.T}


def effect_coefficients(ship: Ship, kind: str, share: float, ref: dict | None = None) -> dict:
    """Effects-field values for a nonlinear effect of the given *share* of the linear behaviour.

    The share is the size of the added term at the reference amplitude (largest |r|, |v| of the
    clean 20/20 zigzag) against the linear term it competes with: yaw terms against the ship's
    effective yaw damping r_ref / T (so a share 0.3 cuts the steady yaw rate near r_ref by about
    0.3 / 1.3 = 23 %), sway terms against |a11| v_ref.  Signs are the physical ones (more damping;
    for v|v| in yaw the sign of a21, as N'vvv has the sign of N'v on real hulls).
    """
    ref = ref or reference_amplitudes(ship)
    r0, v0, damp = ref["r_ref"], ref["v_ref"], ref["damping"]
    a11 = ship.coefficients["a11"]
    a21 = ship.coefficients["a21"]
    if kind == "r|r|":
        return {"n_rr": -share * damp / r0}
    if kind == "r^3":
        return {"n_rrr": -share * damp / r0**2}
    if kind == "v|v|":
        # sway: share of |a11| v0; yaw: share of the linear a21 v0 moment (same sign as a21)
        return {"y_vv": -share * abs(a11) / v0, "n_vv": share * a21 / v0}
    if kind == "cross":
        # v^2 r in yaw (N'vvr < 0: more yaw damping at drift), v r^2 in sway (Y'vrr < 0)
        return {"n_vvr": -share * damp / v0**2, "y_vrr": -share * abs(a11) / r0**2}
    if kind == "cross_abs":
        # the |.| forms: r|v| in yaw, v|r| in sway
        return {"n_rabsv": -share * damp / v0, "y_vabsr": -share * abs(a11) / r0}
    raise ValueError(f"unknown nonlinear kind {kind!r}")


def speed_loss_for(ship: Ship, loss: float, duration: float = 70.0) -> float:
    """x_vr that makes the clean 20/20 zigzag to starboard lose ``loss`` of its approach speed
    (lowest u / U0 = 1 - loss), by bisection on the noise-free truth."""
    def drop(x):
        t = Truth(ship=ship, effects=Effects(x_vr=x))
        f = simulate(t, Zigzag(20, 20, "starboard", duration), seed=0, noise=False)
        return 1.0 - f["u"].min() / ship.u0_m_s

    lo, hi = 0.0, 1.0
    while drop(hi) < loss:
        hi *= 2.0
        if hi > 1e3:
            raise ValueError("cannot reach that speed loss")
    for _ in range(18):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if drop(mid) < loss else (lo, mid)
    return 0.5 * (lo + hi)
