"""Closed-loop course-keeping simulation: CGSA autopilot, rudder servo limits, wind and waves.

Plants share one stepping interface (that of :class:`pipeline.tank.KCSShip`): ``reset()`` and
``step(delta_cmd_deg, dt, disturbance_deg=0.0) -> dict(time s, psi deg, r deg/s, delta deg)``, where
``delta`` is the actual rudder after the servo's angle and rate limits and ``disturbance_deg`` is an
equivalent rudder angle added to the actual rudder (wind + waves).

* :class:`NomotoShip`: the linear Nomoto model (first or second order), discretised exactly for a
  rudder held over each step (zero-order hold; the servo moves the rudder at the start of the step
  by at most rate * dt toward the command, clipped at +-rudder_max).
* The nonlinear virtual-tank KCS (pipeline.tank.KCSShip), when that package is present.

Sampling: at t_k the autopilot reads psi_k and r_k (noise-free), commands
delta_cmd_k = sat(Kp (psi_ref - psi_k) - H r_k), and the plant is advanced to t_{k+1}.  The rate path H
is static (first-order design) or its exact ZOH discretisation (second-order design).
"""

from __future__ import annotations

import control as ct
import numpy as np
import pandas as pd
from scipy.linalg import expm

from pipeline.config import TankConfig
from pipeline.control.autopilot import PIDDesign, make_controller
from pipeline.control.design import CGSADesign
from pipeline.errors import ModelError


class NomotoShip:
    """Linear Nomoto ship psi/delta = K (1 + T3 s)/(s (1 + T1 s)(1 + T2 s)) (T2 = T3 = 0: first order).

    Units: K 1/s, time constants s, psi deg, r deg/s, delta deg.  T3 may be negative.  ``rudder_max`` deg and
    ``rudder_rate`` deg/s limit the servo (None: no limit).  ``dead_time`` s (whole steps) delays the
    servo angle reaching the hull and ``servo_time_constant`` s lags it (first order, discretised
    exactly with the hull); ``delta`` is the servo's commanded angle after its angle and rate limits.
    """

    def __init__(self, K: float, T1: float, T2: float = 0.0, T3: float = 0.0, *,
                 rudder_max: float | None = TankConfig.rudder_max,
                 rudder_rate: float | None = TankConfig.rudder_rate,
                 servo_time_constant: float = 0.0, dead_time: float = 0.0):
        if not (np.isfinite(K) and K > 0):
            raise ModelError(f"K = {K} must be > 0 (1/s)")
        if not (np.isfinite(T1) and T1 > 0) or not (np.isfinite(T2) and T2 >= 0) or not np.isfinite(T3):
            raise ModelError(f"time constants T1 = {T1}, T2 = {T2}, T3 = {T3} s: need T1 > 0, T2 >= 0, "
                             "T3 finite")
        if T2 == 0 and T3 != 0:
            raise ModelError("T3 needs T2 > 0 (first-order plant: T2 = T3 = 0)")
        if not (np.isfinite(servo_time_constant) and servo_time_constant >= 0
                and np.isfinite(dead_time) and dead_time >= 0):
            raise ModelError(f"servo time constant {servo_time_constant} s and dead time {dead_time} s "
                             "must be finite and >= 0")
        den = np.polymul([T1, 1.0], [T2, 1.0]) if T2 > 0 else np.array([T1, 1.0])
        rsys = ct.ss(ct.tf([K * T3, K] if T3 != 0 else [K], den))     # delta -> r, strictly proper
        ar, br, cr = (np.asarray(m, dtype=float) for m in (rsys.A, rsys.B, rsys.C))
        n = ar.shape[0]
        tau = float(servo_time_constant)
        m = n + 1 + (tau > 0)
        # state z = (x_r, psi[, servo lag x_s]): psi' = C_r x_r; x_s' = (u - x_s)/tau; the hull sees
        # x_s (or u without lag) plus the disturbance.  Inputs: column 0 the servo angle u, 1 the disturbance.
        self._a = np.zeros((m, m))
        self._a[:n, :n] = ar
        self._a[n, :n] = cr[0]
        self._b = np.zeros((m, 2))
        self._b[:n, 1] = br[:, 0]
        if tau > 0:
            self._a[:n, n + 1] = br[:, 0]
            self._a[n + 1, n + 1] = -1.0 / tau
            self._b[n + 1, 0] = 1.0 / tau
        else:
            self._b[:n, 0] = br[:, 0]
        self._cr = np.zeros(m)
        self._cr[:n] = cr[0]
        self._npsi = n
        self.K, self.T1, self.T2, self.T3 = float(K), float(T1), float(T2), float(T3)
        self.rudder_max = rudder_max
        self.rudder_rate = rudder_rate
        self.servo_time_constant = tau
        self.dead_time = float(dead_time)
        self._cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self.reset()

    def _disc(self, dt: float):
        """Exact discretisation for inputs held over dt s: (Ad, Bd with the two input columns)."""
        if dt not in self._cache:
            m = self._a.shape[0]
            big = np.zeros((m + 2, m + 2))
            big[:m, :m] = self._a * dt
            big[:m, m:] = self._b * dt
            e = expm(big)
            self._cache[dt] = (e[:m, :m], e[:m, m:])
        return self._cache[dt]

    def reset(self) -> dict:
        self._z = np.zeros(self._a.shape[0])
        self.time = 0.0
        self.delta = 0.0
        self._line: list[float] = []
        return self._out()

    def _out(self) -> dict:
        return {"time": self.time, "psi": float(self._z[self._npsi]), "r": float(self._cr @ self._z),
                "delta": self.delta}

    def step(self, delta_cmd_deg: float, dt: float, disturbance_deg: float = 0.0) -> dict:
        """Move the servo toward the command, then hold the rudder (plus disturbance) over dt s."""
        cmd = float(delta_cmd_deg)
        if self.rudder_max is not None:
            cmd = float(np.clip(cmd, -self.rudder_max, self.rudder_max))
        if self.rudder_rate is not None:
            cmd = self.delta + float(np.clip(cmd - self.delta, -self.rudder_rate * dt, self.rudder_rate * dt))
        self.delta = cmd
        # dead time: whole steps of dt (round(dead_time/dt)) between the servo angle and the hull
        self._line.append(self.delta)
        acting = self._line.pop(0) if len(self._line) > int(round(self.dead_time / dt)) else 0.0
        ad, bd = self._disc(float(dt))
        self._z = ad @ self._z + bd @ np.array([acting, float(disturbance_deg)])
        self.time += dt
        out = self._out()
        out["delta"] = self.delta
        return out


def _kcs_class():
    """pipeline.tank.KCSShip (the virtual tank's stepping KCS simulator)."""
    from pipeline.tank import KCSShip

    return KCSShip


def kcs_available() -> bool:
    """True when the virtual-tank package (an optional part of a slimmed install) is present.

    Only the absence of ``pipeline.tank`` itself counts as "not available"; a tank package that is
    there but fails to import (a bug, a missing dependency of it) raises, so it is never mistaken
    for an optional part that is simply not installed.
    """
    try:
        _kcs_class()
    except ModuleNotFoundError as exc:
        if exc.name in ("pipeline.tank",):
            return False
        raise
    return True


def make_kcs_ship(rudder_max: float, rudder_rate: float, *, dead_time: float = 0.0,
                  servo_time_constant: float = 0.0, speed_share: float = 1.0):
    """The virtual-tank KCS, noise-free, with the autopilot's steering gear (deg, deg/s, s, s) and its
    approach speed scaled by ``speed_share`` (propeller trimmed for it)."""
    from dataclasses import replace

    from pipeline.config import TankConfig

    base = TankConfig()
    cfg = replace(base, rudder_max=rudder_max, rudder_rate=rudder_rate, noise=False, rudder_delay=dead_time,
                  rudder_lag=servo_time_constant, approach_speed=base.approach_speed * float(speed_share))
    return _kcs_class()(cfg=cfg)


def simulate_course(design: CGSADesign | PIDDesign, ship, *, setpoint: float, duration: float, dt: float,
                    rudder_max: float | None = TankConfig.rudder_max, wind: float = 0.0,
                    wave: np.ndarray | None = None) -> pd.DataFrame:
    """Course change 0 -> ``setpoint`` deg at t = 0, then course keeping, for ``duration`` s.

    Parameters
    ----------
    design : the autopilot (the paper's CGSA or the project's PID, pipeline.control.autopilot).
    ship : a plant with ``reset()`` and ``step(delta_cmd_deg, dt, disturbance_deg)`` (see module doc).
    setpoint : deg.  duration, dt : s.
    rudder_max : deg, saturation of the command (None: none; the plant's servo may limit too).
    wind : deg, constant equivalent rudder.  wave : deg, equivalent rudder per step (length >= n).

    Returns
    -------
    Frame with n = round(duration/dt) + 1 rows: time s, psi_ref deg, psi deg, r deg/s (at t_k),
    delta_cmd deg, delta deg (actual rudder over [t_k, t_k+1]), wave deg, wind deg.
    """
    if not dt > 0 or not duration > 0:
        raise ModelError(f"duration = {duration} s and dt = {dt} s must be > 0")
    n = int(round(duration / dt)) + 1
    wave = np.zeros(n) if wave is None else np.asarray(wave, dtype=float)
    if wave.size < n:
        raise ModelError(f"wave sequence has {wave.size} samples, {n} needed")
    state = ship.reset()
    psi, r = float(state["psi"]), float(state["r"])
    ctl = make_controller(design, dt, rudder_max, psi0=psi)
    out = np.empty((n, 8))
    for k in range(n):
        cmd = ctl.command(setpoint, psi, r)
        dist = wind + wave[k]
        st = ship.step(cmd, dt, disturbance_deg=dist)
        out[k] = (k * dt, setpoint, psi, r, cmd, float(st["delta"]), wave[k], wind)
        psi, r = float(st["psi"]), float(st["r"])
    return pd.DataFrame(out, columns=["time", "psi_ref", "psi", "r", "delta_cmd", "delta", "wave", "wind"])
