"""The project's course autopilot: PID with anti-windup behind a third-order reference model.

This is the heading autopilot of Fossen (Handbook of Marine Craft Hydrodynamics and Motion Control,
2011, ch. 15), designed on the first-order Nomoto model psi/delta = K/(s (T s + 1)) (K 1/s, T s,
heading and rudder deg).  docs/control.md states the design and why each setting.

Control law at sample k (heading psi and yaw rate r measured, deg and deg/s):

    delta_cmd = (T a_d + r_d)/K  +  Kp (psi_d - psi)  +  Kd (r_d - r)  +  Ki z,     z_{k+1} = z_k + h e_k

with (psi_d, r_d, a_d) from the reference model, e = psi_d - psi, and the command saturated at
+-rudder_max.  Gains by pole placement (closed loop of the model without feedforward
s^3 + ... with a double pole at -wn and the integrator's pole a decade lower):

    Kp = T wn^2 / K,   Kd = (2 zeta wn T - 1)/K,   Ki = wn Kp / ki_ratio,   wn = 1/Tw.

Kd is clipped at 0 when 2 zeta wn T < 1 (a ship faster than the loop needs no damping added).

Anti-windup by conditional integration (clamping): the integrator holds when the command is
saturated and the error would drive it further into saturation; it integrates otherwise.

Reference model (Fossen's third-order filter with a rate limit):

    psi_d/psi_r = wr^3 / ((s + wr)(s^2 + 2 zr wr s + wr^2)),

state (psi_d, r_d, a_d), integrated at the control step h by forward Euler, the rate r_d clipped at
+-r_max (and a_d zeroed when it pushes the rate beyond the limit).
"""

from __future__ import annotations

from dataclasses import dataclass

import control as ct
import numpy as np

from pipeline.control.design import CGSADesign, _positive
from pipeline.errors import ModelError


@dataclass(frozen=True)
class PIDDesign:
    """PID gains and reference model of the autopilot.

    Kp deg/deg, Kd deg/(deg/s), Ki deg/(deg s); K 1/s and T s of the design model; wn, wr rad/s;
    r_max deg/s (the reference model's yaw-rate limit); ``kd_clipped`` when 2 zeta wn T < 1.
    """

    name: str
    K: float
    T: float
    Kp: float
    Kd: float
    Ki: float
    wn: float
    zeta: float
    wr: float
    zr: float
    r_max: float
    kd_clipped: bool = False

    def summary(self) -> dict:
        return {"name": self.name, "structure": "PID + 3rd-order reference model, conditional integration",
                "K": self.K, "T": self.T, "Kp": self.Kp, "Kd": self.Kd, "Ki": self.Ki, "wn": self.wn,
                "zeta": self.zeta, "wr": self.wr, "zr": self.zr, "r_max": self.r_max,
                "kd_clipped": self.kd_clipped}

    def feedback_tf(self, dt: float | None = None) -> tuple[ct.TransferFunction, ct.TransferFunction]:
        """(C_psi, C_r): the feedback parts delta = -(C_psi psi + C_r r) of the loop.

        Continuous (``dt`` None): C_psi = Kp + Ki/s.  Sampled at ``dt`` s: C_psi = Kp + Ki dt/(z - 1),
        the implementation's forward-Euler integrator.  C_r = Kd.
        """
        if dt is None:
            return ct.tf([self.Kp, self.Ki], [1.0, 0.0]), ct.tf([self.Kd], [1.0])
        return (ct.tf([self.Kp, self.Ki * dt - self.Kp], [1.0, -1.0], dt),
                ct.tf([self.Kd], [1.0], dt))


def design_pid(K: float, T: float, Tw: float, *, rudder_max: float, zeta: float = 1.0,
               ki_ratio: float = 10.0, ref_wn_ratio: float = 1.0, ref_zeta: float = 1.0,
               ref_rate_share: float = 0.25, name: str = "pid") -> PIDDesign:
    """Pole-placement PID on K/(s (T s + 1)) with wn = 1/Tw (module docstring).

    K 1/s, T s, Tw s, rudder_max deg (all > 0, ModelError otherwise).  The reference model's
    r_max = ref_rate_share K rudder_max deg/s.
    """
    K, T, Tw = _positive("K", K), _positive("T", T), _positive("Tw", Tw)
    rudder_max = _positive("rudder_max", rudder_max)
    for nm, v in (("zeta", zeta), ("ki_ratio", ki_ratio), ("ref_wn_ratio", ref_wn_ratio),
                  ("ref_zeta", ref_zeta), ("ref_rate_share", ref_rate_share)):
        _positive(nm, v)
    wn = 1.0 / Tw
    kp = T * wn ** 2 / K
    kd_raw = (2.0 * zeta * wn * T - 1.0) / K
    return PIDDesign(name=name, K=K, T=T, Kp=kp, Kd=max(kd_raw, 0.0), Ki=wn * kp / ki_ratio, wn=wn,
                     zeta=float(zeta), wr=ref_wn_ratio * wn, zr=float(ref_zeta),
                     r_max=ref_rate_share * K * rudder_max, kd_clipped=kd_raw < 0)


class ReferenceModel:
    """Fossen's third-order reference model with a yaw-rate limit (module docstring).

    ``step(psi_r, h)`` advances h s toward the commanded course psi_r (deg) and returns
    (psi_d deg, r_d deg/s, a_d deg/s^2) at the start of the step.
    """

    def __init__(self, wr: float, zr: float, r_max: float, psi0: float = 0.0):
        self.wr, self.zr, self.r_max = _positive("wr", wr), _positive("zr", zr), _positive("r_max", r_max)
        self.x = np.array([float(psi0), 0.0, 0.0])

    def step(self, psi_r: float, h: float) -> tuple[float, float, float]:
        psi_d, r_d, a_d = (float(v) for v in self.x)
        w, z = self.wr, self.zr
        jerk = w ** 3 * (psi_r - psi_d) - (2 * z + 1) * w ** 2 * r_d - (2 * z + 1) * w * a_d
        psi_n = psi_d + h * r_d
        r_n = r_d + h * a_d
        a_n = a_d + h * jerk
        if abs(r_n) >= self.r_max:
            r_n = float(np.sign(r_n)) * self.r_max
            if a_n * r_n > 0:
                a_n = 0.0
        self.x = np.array([psi_n, r_n, a_n])
        return psi_d, r_d, a_d


class PIDController:
    """Sampled PID autopilot (``command(psi_ref, psi, r)`` deg, deg, deg/s -> rudder command deg)."""

    def __init__(self, design: PIDDesign, dt: float, rudder_max: float | None, psi0: float = 0.0):
        self.design, self.dt, self.rudder_max = design, _positive("dt", dt), rudder_max
        self.ref = ReferenceModel(design.wr, design.zr, design.r_max, psi0)
        self.z = 0.0
        self.saturated = 0          # steps at which the integrator was held

    def command(self, psi_ref: float, psi: float, r: float) -> float:
        d = self.design
        psi_d, r_d, a_d = self.ref.step(psi_ref, self.dt)
        e = psi_d - psi
        u = (d.T * a_d + r_d) / d.K + d.Kp * e + d.Kd * (r_d - r) + d.Ki * self.z
        cmd = u
        if self.rudder_max is not None:
            cmd = min(max(u, -self.rudder_max), self.rudder_max)
        if cmd != u and e * u > 0:           # saturated and the error would wind it further
            self.saturated += 1
        else:
            self.z += self.dt * e
        return cmd


class CGSAController:
    """The paper's CGSA law, sampled: delta_cmd = Kp (psi_ref - psi) - H r (pipeline.control.design)."""

    def __init__(self, design: CGSADesign, dt: float, rudder_max: float | None):
        self.design, self.rudder_max = design, rudder_max
        h = design.rate_filter
        den = np.trim_zeros(np.asarray(h.den[0][0], dtype=float), "f")
        if den.size <= 1:
            self.gain, self._a = float(np.asarray(h.num[0][0], dtype=float)[-1] / den[0]), None
        else:
            sysd = ct.c2d(ct.ss(h), _positive("dt", dt), method="zoh")
            self._a, self._b, self._c, self._d = (np.asarray(m, dtype=float)
                                                  for m in (sysd.A, sysd.B, sysd.C, sysd.D))
            self._x = np.zeros(self._a.shape[0])

    def rate_path(self, r: float) -> float:
        if self._a is None:
            return self.gain * r
        y = float(self._c[0] @ self._x + self._d[0, 0] * r)
        self._x = self._a @ self._x + self._b[:, 0] * r
        return y

    def command(self, psi_ref: float, psi: float, r: float) -> float:
        cmd = self.design.Kp * (psi_ref - psi) - self.rate_path(r)
        if self.rudder_max is not None:
            cmd = min(max(cmd, -self.rudder_max), self.rudder_max)
        return cmd


def make_controller(design, dt: float, rudder_max: float | None, psi0: float = 0.0):
    """A fresh controller (state at rest) for a CGSA or PID design."""
    if isinstance(design, CGSADesign):
        return CGSAController(design, dt, rudder_max)
    if isinstance(design, PIDDesign):
        return PIDController(design, dt, rudder_max, psi0)
    raise ModelError(f"unknown autopilot design {type(design).__name__}")
