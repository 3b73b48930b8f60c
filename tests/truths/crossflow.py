"""A sixth ship and model family: a twin-rudder ferry model whose hull is Clarke's regression
derivatives plus Hoerner's cross-flow drag, logged by a tank at 20 Hz as canonical CSV at model scale.

Model (speed held, as in a tank run at constant carriage-matched speed): sway and yaw

    (m - Y_vd) v' - Y_rd r'            = Y_v v + (Y_r - m U) r + Y_R + Y_cf + Y_ext
    -N_vd v' + (I_z - N_rd) r'          = N_v v + N_r r + N_R + N_cf + N_ext

- the linear hull: the regression of Clarke, Gedling & Hine (1983), "The application of manoeuvring
  criteria in hull design using linear theory", Trans. RINA 125:45-68, on the main particulars
  (S = pi (T/L)^2): Y'_v = -S (1 + 0.40 Cb B/T), Y'_r = -S (-1/2 + 2.2 B/L - 0.080 B/T),
  N'_v = -S (1/2 + 2.4 T/L), N'_r = -S (1/4 + 0.039 B/T - 0.56 B/L), Y'_vd = -S (1 + 0.16 Cb B/T
  - 5.1 (B/L)^2), Y'_rd = -S (0.67 B/L - 0.0033 (B/T)^2), N'_vd = -S (1.1 B/L - 0.041 B/T),
  N'_rd = -S (1/12 + 0.017 Cb B/T - 0.33 B/L) (as carried by Fossen's Marine Systems Simulator);
- the rudders: the normal force -1/2 rho A_R U_R^2 C_La alpha_R, C_La = 6.13 Lambda / (Lambda + 2.25)
  (Fujii), alpha_R = delta + gamma_R (v + x_R r) / U_R (the hull straightens the flow at the rudder),
  the hull's share a_H acting at x_H: linear in the rudder angle, no stall (the logged rudder is the
  measured one: no servo effect is hidden);
- form ``"crossflow"``: the hull's nonlinearity as Hoerner's cross-flow drag, strip theory over the
  length, Y_cf = -1/2 rho T C_D(B/2T) integral (v + x r)|v + x r| dx, N_cf = the same with x inside,
  integrated in closed form (not in strips).  The integral is no candidate's formula: it mixes
  v|v|, r|r| and the |.| cross forms, by a weight that moves with where along the hull the
  cross-flow changes sign;
- form ``"linear"``: the same ship without the cross-flow drag (the baseline's own family, the
  truth "none").

Sensors, not written as the pipeline writes them: heading and yaw rate with AR(1) noise (lag-1
correlation 0.9 at 20 Hz: an optical tracker's filtered output), sway and surge with white noise,
the rudder angle quantised to 0.1 deg by its encoder.  Fresh tank water (1000 kg/m^3).

Signs: docs/contract.md#run-data (positive rudder turns to starboard, r > 0, the ship drifting to port,
v < 0):
checked by :func:`check_signs`.
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

#: Hoerner's 2-D cross-flow drag coefficient against B / (2 T), as digitised in Fossen's MSS
HOERNER_B2T = (0.0109, 0.1766, 0.3530, 0.4519, 0.4728, 0.4929, 0.4933, 0.5585, 0.6464, 0.8336,
               0.9880, 1.3081, 1.6392, 1.8600, 2.3129, 2.6000, 3.0088, 3.4508, 3.7379, 4.0031)
HOERNER_CD = (1.9661, 1.9657, 1.8976, 1.7872, 1.5837, 1.2786, 1.2108, 1.0836, 0.9986, 0.8796,
              0.8284, 0.7599, 0.6914, 0.6571, 0.6307, 0.5962, 0.5868, 0.5859, 0.5599, 0.5593)


@dataclass(frozen=True)
class Ferry:
    """A 4 m tank model of a 160 m twin-screw, twin-rudder ferry (1:40).  Lengths m, speed m/s,
    rudder limits deg and deg/s, servo s, water density kg/m^3."""

    form: str = "crossflow"     # "crossflow" | "linear"
    L: float = 4.0
    B: float = 0.64
    T: float = 0.16
    Cb: float = 0.58
    U: float = 1.25             # Froude number 0.20
    rho: float = 1000.0
    r66: float = 0.25           # yaw radius of gyration / L
    A_R: float = 0.016          # both rudders, m^2 (L T / 40)
    Lambda: float = 1.5         # rudder aspect ratio
    x_R: float = -0.48          # / L
    gamma_R: float = 0.45       # flow straightening at the rudders
    uR_ratio: float = 1.15      # rudder inflow / U (slipstream of the two propellers)
    a_H: float = 0.25           # hull's share of the rudder force
    x_H: float = -0.45          # / L, where the hull's share acts
    rudder_max: float = 35.0
    rudder_rate: float = 15.0   # deg/s at model scale (2.4 deg/s full scale)
    servo_tau: float = 0.05

    def __post_init__(self):
        if self.form not in ("crossflow", "linear"):
            raise ValueError(f"form must be crossflow or linear, not {self.form!r}")


@functools.lru_cache(maxsize=8)
def _dimensional(s: Ferry) -> dict:
    """Dimensional derivatives (SI) of the linear hull and rudder, the mass matrix and the cross-flow
    constant, from Clarke's regression (module docstring)."""
    L, B, T, Cb, U, rho = s.L, s.B, s.T, s.Cb, s.U, s.rho
    S = math.pi * (T / L) ** 2
    h = 0.5 * rho
    prime = {
        "Yv": -S * (1 + 0.40 * Cb * B / T), "Yr": -S * (-0.5 + 2.2 * B / L - 0.080 * B / T),
        "Nv": -S * (0.5 + 2.4 * T / L), "Nr": -S * (0.25 + 0.039 * B / T - 0.56 * B / L),
        "Yvd": -S * (1 + 0.16 * Cb * B / T - 5.1 * (B / L) ** 2),
        "Yrd": -S * (0.67 * B / L - 0.0033 * (B / T) ** 2),
        "Nvd": -S * (1.1 * B / L - 0.041 * B / T),
        "Nrd": -S * (1.0 / 12.0 + 0.017 * Cb * B / T - 0.33 * B / L),
    }
    m = rho * Cb * L * B * T
    Iz = m * (s.r66 * L) ** 2
    d = {
        "m": m, "Iz": Iz,
        "Yv": h * L ** 2 * U * prime["Yv"], "Yr": h * L ** 3 * U * prime["Yr"],
        "Nv": h * L ** 3 * U * prime["Nv"], "Nr": h * L ** 4 * U * prime["Nr"],
        "Yvd": h * L ** 3 * prime["Yvd"], "Yrd": h * L ** 4 * prime["Yrd"],
        "Nvd": h * L ** 4 * prime["Nvd"], "Nrd": h * L ** 5 * prime["Nrd"],
    }
    d["M"] = np.array([[m - d["Yvd"], -d["Yrd"]], [-d["Nvd"], Iz - d["Nrd"]]])
    d["Minv"] = np.linalg.inv(d["M"])
    d["CLa"] = 6.13 * s.Lambda / (s.Lambda + 2.25)
    d["UR"] = s.uR_ratio * U
    d["cf"] = 0.5 * rho * T * float(np.interp(B / (2 * T), HOERNER_B2T, HOERNER_CD))
    return d


#: a second hull from the same regression: a full-form bulk carrier model (1:40, 160 m full scale),
#: slow and close to course-unstable (its slow linear pole -0.011 1/s: a time constant of 18 L/U)
BULKER = {"Cb": 0.82, "B": 0.72, "T": 0.26, "U": 0.8, "A_R": 0.026}


def hull(name: str, form: str = "crossflow") -> Ferry:
    """The ``"ferry"`` (the class's defaults) or the ``"bulker"`` (:data:`BULKER`) in ``form``."""
    return Ferry(form=form, **({"ferry": {}, "bulker": BULKER}[name]))


def crossflow_integrals(v: float, r: float, L: float) -> tuple[float, float]:
    """(integral of w|w| dx, integral of x w|w| dx) over x in [-L/2, L/2], w = v + x r (m^3/s^2,
    m^4/s^2), in closed form: d|w|^3/dx = 3 r w|w| and d(w|w|^3)/dx = 4 r |w|^3, so with x = (w - v)/r
    the second is (1/r) (integral |w|^3 dx - v integral w|w| dx).  For r L tiny against |v| the
    expansion to first order in r."""
    a, b = v - 0.5 * L * r, v + 0.5 * L * r
    if abs(r) * L <= 1e-9 * max(abs(v), 1e-12):
        return v * abs(v) * L, 2.0 * abs(v) * r * L ** 3 / 12.0
    i1 = (abs(b) ** 3 - abs(a) ** 3) / (3.0 * r)
    i3 = (b * abs(b) ** 3 - a * abs(a) ** 3) / (4.0 * r)
    return i1, (i3 - v * i1) / r


def forces(s: Ferry, v: float, r: float, d: float) -> tuple[float, float]:
    """(Y N, N N m) on the hull and rudders at sway v m/s, yaw rate r rad/s and rudder d rad (the
    centripetal -m U r included)."""
    c = _dimensional(s)
    L = s.L
    xR, xH = s.x_R * L, s.x_H * L
    alpha = d + s.gamma_R * (v + xR * r) / c["UR"]
    F = -0.5 * s.rho * s.A_R * c["UR"] ** 2 * c["CLa"] * alpha
    Y = c["Yv"] * v + (c["Yr"] - c["m"] * s.U) * r + (1.0 + s.a_H) * F
    N = c["Nv"] * v + c["Nr"] * r + (xR + s.a_H * xH) * F
    if s.form == "crossflow":
        i1, ix = crossflow_integrals(v, r, L)
        Y -= c["cf"] * i1
        N -= c["cf"] * ix
    return Y, N


def derivatives(s: Ferry, v: float, r: float, d: float, n_ext: float = 0.0) -> tuple[float, float]:
    """(dv m/s^2, dr rad/s^2); ``n_ext`` an external yaw acceleration (rad/s^2) added."""
    Y, N = forces(s, v, r, d)
    Minv = _dimensional(s)["Minv"]
    return Minv[0, 0] * Y + Minv[0, 1] * N, Minv[1, 0] * Y + Minv[1, 1] * N + n_ext


def linear_poles(s: Ferry | None = None) -> np.ndarray:
    """The two sway-yaw poles (1/s) of the linear part, by central differences."""
    s = Ferry(form="linear") if s is None else Ferry(**{**s.__dict__, "form": "linear"})
    e = 1e-7
    A = np.empty((2, 2))
    for j in range(2):
        x = [0.0, 0.0]
        x[j] = e
        hi = derivatives(s, x[0], x[1], 0.0)
        x[j] = -e
        lo = derivatives(s, x[0], x[1], 0.0)
        A[:, j] = (np.array(hi) - np.array(lo)) / (2 * e)
    return np.linalg.eigvals(A)


def ar1(n: int, sigma: float, phi: float, rng: np.random.Generator) -> np.ndarray:
    """Stationary AR(1) noise of standard deviation ``sigma`` and lag-1 correlation ``phi``."""
    e = rng.normal(0.0, sigma * math.sqrt(1.0 - phi * phi), n)
    out = np.empty(n)
    out[0] = rng.normal(0.0, sigma)
    for i in range(1, n):
        out[i] = phi * out[i - 1] + e[i]
    return out


def simulate_zigzag(
    s: Ferry,
    rudder_deg: float,
    heading_deg: float,
    first_side: str = "starboard",
    duration: float = 90.0,
    dt_log: float = 0.05,
    h: float = 0.005,
    seed: int = 0,
    noise: bool = True,
    t_execute: float = 5.0,
    disturbance_deg: float = 0.0,
    disturbance_tau: float = 5.0,
) -> pd.DataFrame:
    """A model-scale zigzag; returns time s, x0, y0 m, psi deg, u, v m/s, r deg/s, delta deg
    (docs/contract.md#run-data signs, the measured rudder quantised to 0.1 deg), logged every ``dt_log`` s;
    RK4 at ``h`` s, counter-rudder on the measured heading.  ``disturbance_deg``: a random yaw moment
    (Ornstein-Uhlenbeck, time constant ``disturbance_tau`` s) as that much rudder's, standard deviation."""
    n = int(round(duration / dt_log)) + 1
    rate, dmax = s.rudder_rate * RAD, s.rudder_max * RAD
    dist = np.zeros(n)
    if disturbance_deg > 0.0:
        per_rad = abs(derivatives(s, 0.0, 0.0, RAD)[1] - derivatives(s, 0.0, 0.0, 0.0)[1]) / RAD
        dist = ornstein_uhlenbeck(n, dt_log, disturbance_tau, seed) * per_rad * disturbance_deg * RAD

    def rhs(x, cmd, n_ext=0.0):
        v, r, psi, _, _, d = x
        dv, dr = derivatives(s, v, r, d, n_ext)
        c = max(-dmax, min(dmax, cmd))
        dd = max(-rate, min(rate, (c - d) / s.servo_tau))
        cp, sp = math.cos(psi), math.sin(psi)
        return (dv, dr, r, s.U * cp - v * sp, s.U * sp + v * cp, dd)

    def row(t, x):
        v, r, psi, x0, y0, d = x
        return (t, x0, y0, psi / RAD, s.U, v, r / RAD, d / RAD)

    rng = np.random.default_rng(seed)
    e = {"psi": ar1(n, 0.05, 0.9, rng), "r": ar1(n, 0.05, 0.9, rng),
         "u": rng.normal(0.0, 0.005, n), "v": rng.normal(0.0, 0.005, n)}
    if not noise:
        e = {k: np.zeros(n) for k in e}
    out = zigzag.run(rhs, [0.0] * 6, row, lambda x: x[2] / RAD, rudder_deg, heading_deg, first_side, n,
                     dt_log, h, t_execute, e["psi"], dist)
    f = zigzag.logged(out, ["time", "x0", "y0", "psi", "u", "v", "r", "delta"], e)
    if noise:
        f["delta"] = np.round(f["delta"].to_numpy() / 0.1) * 0.1
    return f


def check_signs(s: Ferry | None = None) -> dict:
    """Steady response to +10 deg (docs/contract.md#run-data) rudder after 60 s, noise-free:
    r > 0 and v < 0."""
    f = simulate_zigzag(s or Ferry(), 10.0, 1e9, "starboard", duration=60.0, noise=False)
    return {"r_deg_s": float(f["r"].iloc[-1]), "v_m_s": float(f["v"].iloc[-1])}


def free_run(s: Ferry, time_s: np.ndarray, delta_deg: np.ndarray, r0_deg_s: float, psi0_deg: float,
             h: float = 0.005) -> np.ndarray:
    """The heading (deg) of the truth's own equations, no disturbance, driven by a logged rudder
    ``delta_deg`` at the instants ``time_s`` (linear between them), from sway 0, yaw rate ``r0_deg_s``
    and heading ``psi0_deg``: RK4 at about ``h`` s.  The oracle of a disturbed run: what a perfect
    model of the ship predicts in free run, against which a fitted model's held-out gain is judged."""
    t = np.asarray(time_s, dtype=float)
    dl = np.asarray(delta_deg, dtype=float) * RAD
    v, r, p = 0.0, r0_deg_s * RAD, psi0_deg * RAD
    out = np.empty(len(t))
    out[0] = p
    for i in range(len(t) - 1):
        dt = t[i + 1] - t[i]
        n = max(1, int(round(dt / h)))
        hh = dt / n
        for k in range(n):
            d0 = dl[i] + (dl[i + 1] - dl[i]) * k / n
            dm = dl[i] + (dl[i + 1] - dl[i]) * (k + 0.5) / n
            d1 = dl[i] + (dl[i + 1] - dl[i]) * (k + 1) / n
            k1 = derivatives(s, v, r, d0)
            k2 = derivatives(s, v + 0.5 * hh * k1[0], r + 0.5 * hh * k1[1], dm)
            k3 = derivatives(s, v + 0.5 * hh * k2[0], r + 0.5 * hh * k2[1], dm)
            k4 = derivatives(s, v + hh * k3[0], r + hh * k3[1], d1)
            r1 = r + hh / 6.0 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            q1 = r + 0.5 * hh * k1[1]
            q2 = r + 0.5 * hh * k2[1]
            q3 = r + hh * k3[1]
            p += hh / 6.0 * (r + 2 * q1 + 2 * q2 + q3)
            v += hh / 6.0 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            r = r1
        out[i + 1] = p
    return out / RAD
