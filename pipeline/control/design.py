"""CGSA (closed-loop gain shaping) course-keeping autopilot: design and loop analysis.

Units at the edges: K in 1/s (deg/s of yaw rate per deg of rudder, so psi/delta in deg/deg), time
constants in s, heading psi and rudder delta in deg, frequencies in rad/s.  The transfer functions are
unit-consistent in deg (psi/delta is deg/deg), so no degree/radian conversion is needed here.

Design rule (docs/control.md): shape the complementary sensitivity directly, T(s) = 1/(Tw s + 1).

* First order, plant G1 = K / (s (T s + 1)):  Kc = (T s + 1)/(K Tw), a PD controller with
  Kp = 1/(K Tw) (deg/deg), Kd = T/(K Tw) (deg per deg/s).  Then L = Kc G1 = 1/(Tw s) exactly.
* Second order, plant G2 = K (1 + T3 s) / (s (1 + T1 s)(1 + T2 s)):
  Kc = (1 + T1 s)(1 + T2 s) / (K Tw (1 + T3 s)) is improper (two zeros, one pole).  It is made proper
  (biproper) with one filter pole: Kc_f = Kc / (1 + Tf s), Tf = ``ControlConfig.filter_tau``; then
  L = 1/(Tw s (1 + Tf s)), which tends to 1/(Tw s) as Tf -> 0.

Implementation ("derivative on the measured yaw rate", no kick on a set-point step): the control law
is  delta = Kp (psi_ref - psi) - H(s) r,  with H = Kd for the first order and, for the second order,
H(s) = (Kc_f(s) - Kp)/s, which is strictly proper because Kc_f(0) = Kp.  Since r = s psi, the feedback
path is exactly Kc(s) psi: the loop L, margins, sensitivity and disturbance rejection are those of
the CGSA design.  Only the set-point path differs: the response to a course step is
Kp G / (1 + L) = T(s) Kp / Kc(s), e.g. 1/((T s + 1)(Tw s + 1)) for the first order on its own
model, instead of 1/(Tw s + 1) (which is what a derivative on the error would give, at the price of an
impulse of rudder at the step).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import control as ct
import numpy as np

from pipeline.errors import ModelError

HALF_POWER_DB = 20.0 * np.log10(np.sqrt(0.5))
"""-3.0103 dB: the bandwidth is the half-power frequency (1/Tw exactly for 1/(Tw s + 1))."""


def _positive(name: str, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{name} = {value!r} is not a number") from None
    if not np.isfinite(x) or not x > 0:
        raise ModelError(f"{name} = {value!r} must be finite and > 0 (units: K 1/s, time constants s)")
    return x


def nomoto_tf(K: float, T: float | None = None, *, T1: float | None = None, T2: float | None = None,
              T3: float | None = None) -> ct.TransferFunction:
    """Nomoto plant psi/delta (deg/deg).

    First order ``nomoto_tf(K, T)``: K / (s (T s + 1)).  Second order ``nomoto_tf(K, T1=, T2=, T3=)``:
    K (1 + T3 s) / (s (1 + T1 s)(1 + T2 s)).  T2 = T3 = 0 is the first-order model with T = T1.

    Parameters
    ----------
    K : float
        Gain, 1/s (> 0).
    T : float, optional
        First-order time constant, s (> 0).
    T1, T2, T3 : float, optional
        Second-order time constants, s: T1 > 0, T2 >= 0, T3 any finite number (negative:
        non-minimum-phase).

    Returns
    -------
    control.TransferFunction
        psi(s)/delta(s), deg/deg.

    Raises
    ------
    ModelError
        K, T or T1 not positive, T2 negative, a value not finite.
    """
    K = _positive("K", K)
    if T1 is None:
        T = _positive("T", T)
        return ct.tf([K], [T, 1.0, 0.0])
    T1 = _positive("T1", T1)
    T2 = float(T2 or 0.0)
    T3 = float(T3 or 0.0)
    if not np.isfinite(T2) or T2 < 0:
        raise ModelError(f"T2 = {T2!r} must be finite and >= 0 s")
    if not np.isfinite(T3):
        raise ModelError(f"T3 = {T3!r} must be finite (s)")
    if T2 == 0 and T3 != 0:
        raise ModelError("T3 needs T2 > 0 (first-order model: T2 = T3 = 0)")
    den = np.polymul([T1, 1.0], [T2, 1.0])
    return ct.tf([K * T3, K], np.polymul(den, [1.0, 0.0]))


@dataclass
class CGSADesign:
    """A CGSA autopilot.  Gains: Kp deg/deg, Kd deg/(deg/s); time constants s.

    ``controller`` is Kc(s) (psi error -> rudder), ``rate_filter`` is H(s) (measured yaw rate ->
    rudder, deg per deg/s) used by the no-kick implementation, ``model`` the plant model designed for.
    """

    name: str
    order: int
    K: float
    T: float
    Tw: float
    Kp: float
    Kd: float
    T1: float | None = None
    T2: float | None = None
    T3: float | None = None
    filter_tau: float | None = None
    controller: ct.TransferFunction = field(repr=False, default=None)
    rate_filter: ct.TransferFunction = field(repr=False, default=None)
    model: ct.TransferFunction = field(repr=False, default=None)

    def summary(self) -> dict:
        out = {"name": self.name, "order": self.order, "K": self.K, "T": self.T, "Tw": self.Tw,
               "Kp": self.Kp, "Kd": self.Kd}
        if self.order == 2:
            out.update({"T1": self.T1, "T2": self.T2, "T3": self.T3, "filter_tau": self.filter_tau})
        return out


def design_first_order(K: float, T: float, Tw: float, *, name: str = "cgsa1") -> CGSADesign:
    """First-order CGSA: Kp = 1/(K Tw), Kd = T/(K Tw).

    Parameters
    ----------
    K : float
        Nomoto gain, 1/s (> 0).
    T : float
        Nomoto time constant, s (> 0).
    Tw : float
        The closed loop's target time constant, s (> 0).
    name : str
        The design's name.

    Returns
    -------
    CGSADesign
        Kp (deg/deg), Kd (deg/(deg/s)), the controller and the design model.

    Raises
    ------
    ModelError
        A gain or time constant not positive.
    """
    K = _positive("K", K)
    T = _positive("T", T)
    Tw = _positive("Tw", Tw)
    kp = 1.0 / (K * Tw)
    kd = T / (K * Tw)
    return CGSADesign(name=name, order=1, K=K, T=T, Tw=Tw, Kp=kp, Kd=kd,
                      controller=ct.tf([kd, kp], [1.0]), rate_filter=ct.tf([kd], [1.0]),
                      model=nomoto_tf(K, T))


def design_second_order(K: float, T1: float, T2: float, T3: float, Tw: float, filter_tau: float, *,
                        name: str = "cgsa2") -> CGSADesign:
    """Second-order CGSA made proper by a filter pole.

    Kc_f(s) = (1 + T1 s)(1 + T2 s) / (K Tw (1 + T3 s)(1 + Tf s)), Tf = ``filter_tau``.
    Kp = Kc_f(0) = 1/(K Tw); Kd = the derivative gain of the unfiltered Kc at low frequency,
    (T1 + T2 - T3)/(K Tw).  H(s) = (Kc_f(s) - Kp)/s is strictly proper.

    Parameters
    ----------
    K : float
        Nomoto gain, 1/s.
    T1, T2, T3 : float
        Second-order Nomoto time constants, s.
    Tw : float
        The closed loop's target time constant, s (> 0).
    filter_tau : float
        The filter pole's time constant Tf, s (> 0).
    name : str
        The design's name.

    Returns
    -------
    CGSADesign
        Kp (deg/deg), Kd (deg/(deg/s)), the controller Kc_f, the rate filter H and the design model.

    Raises
    ------
    ModelError
        A plant :func:`nomoto_tf` refuses, or Tw, Tf not positive.
    """
    K = _positive("K", K)
    T1 = _positive("T1", T1)
    T2 = _positive("T2", T2)
    T3 = _positive("T3", T3)
    Tw = _positive("Tw", Tw)
    tf_ = _positive("filter_tau", filter_tau)
    kp = 1.0 / (K * Tw)
    num = kp * np.polymul([T1, 1.0], [T2, 1.0])                 # degree 2
    den = np.polymul([T3, 1.0], [tf_, 1.0])                     # degree 2
    # Kc_f - Kp = (num - kp den)/den; the numerator vanishes at s = 0, divide it by s.
    diff = np.polysub(num, kp * den)
    if abs(diff[-1]) > 1e-12 * max(1.0, np.max(np.abs(diff))):
        raise ModelError("internal: Kc_f(0) != Kp")             # cannot happen for valid inputs
    h_num = diff[:-1]
    return CGSADesign(name=name, order=2, K=K, T=T1 + T2 - T3, Tw=Tw, Kp=kp,
                      Kd=(T1 + T2 - T3) / (K * Tw), T1=T1, T2=T2, T3=T3, filter_tau=tf_,
                      controller=ct.tf(num, den), rate_filter=ct.tf(h_num, den),
                      model=nomoto_tf(K, T1=T1, T2=T2, T3=T3))


def is_proper(sys: ct.TransferFunction) -> bool:
    """True when the degree of the numerator does not exceed that of the denominator."""
    num = np.trim_zeros(np.atleast_1d(np.asarray(sys.num[0][0], dtype=float)), "f")
    den = np.trim_zeros(np.atleast_1d(np.asarray(sys.den[0][0], dtype=float)), "f")
    return len(num) <= len(den)


def loop_analysis(loop: ct.TransferFunction, *, omega: np.ndarray | None = None) -> dict:
    """Margins and closed-loop figures of an open loop L(s) (unity feedback).

    Parameters
    ----------
    loop : control.TransferFunction
        The open loop L(s) (:func:`open_loop`).
    omega : ndarray, optional
        The frequency grid (rad/s) Ms and the bandwidth are read on; None: a dense default grid.

    Returns
    -------
    dict
        ``gain_margin`` (absolute, inf when the phase never crosses -180 deg) and ``gain_margin_db``,
        ``phase_margin_deg`` (deg), ``phase_crossover`` and ``gain_crossover`` (rad/s), ``bandwidth``
        (rad/s, -3 dB of the complementary sensitivity L/(1+L)), ``Ms`` = max |1/(1+L)| and its
        frequency ``Ms_omega`` (rad/s), ``stable`` (the closed loop).
    """
    gm, pm, _sm, wpc, wgc, _wms = ct.stability_margins(loop)
    tcl = ct.feedback(loop, 1)
    scl = ct.feedback(1, loop)
    if omega is None:
        omega = np.logspace(-4, 3, 4000)
    resp = ct.frequency_response(scl, omega)
    mag = np.abs(np.asarray(resp.complex).reshape(-1))
    i = int(np.argmax(mag))
    poles = ct.poles(tcl)
    try:
        bw = float(ct.bandwidth(tcl, dbdrop=HALF_POWER_DB))
    except Exception:  # noqa: BLE001 - python-control raises various types for odd systems
        bw = float("nan")
    gm = float(gm)
    return {
        "gain_margin": gm if np.isfinite(gm) else float("inf"),
        "gain_margin_db": float(20 * np.log10(gm)) if np.isfinite(gm) and gm > 0 else float("inf"),
        "phase_margin_deg": float(pm),
        "phase_crossover": float(wpc) if np.isfinite(wpc) else float("nan"),
        "gain_crossover": float(wgc),
        "bandwidth": bw,
        "Ms": float(mag[i]),
        "Ms_omega": float(omega[i]),
        "stable": bool(np.all(np.real(poles) < 0)),
    }


def open_loop(design: CGSADesign, plant: ct.TransferFunction | None = None) -> ct.TransferFunction:
    """The open loop L = Kc G.

    Parameters
    ----------
    design : CGSADesign
        The autopilot (its Kc(s), psi error deg -> rudder deg).
    plant : control.TransferFunction, optional
        The plant G (psi/delta, deg/deg); None: the design's own model.

    Returns
    -------
    control.TransferFunction
        L(s), dimensionless.
    """
    return ct.minreal(design.controller * (design.model if plant is None else plant), verbose=False)


def setpoint_response_tf(design: CGSADesign, plant: ct.TransferFunction | None = None, *,
                         derivative_on: str = "measurement") -> ct.TransferFunction:
    """Course set-point -> heading transfer function.

    Parameters
    ----------
    design : CGSADesign
        The autopilot.
    plant : control.TransferFunction, optional
        The plant G (psi/delta, deg/deg); None: the design's own model.
    derivative_on : str
        ``"error"``: the CGSA target L/(1+L) (= 1/(Tw s + 1) on the design model);
        ``"measurement"`` (what the simulator does): Kp G/(1 + Kc G).

    Returns
    -------
    control.TransferFunction
        psi(s)/psi_set(s), deg/deg.
    """
    g = design.model if plant is None else plant
    loop = design.controller * g
    if derivative_on == "error":
        return ct.minreal(ct.feedback(loop, 1), verbose=False)
    if derivative_on == "measurement":
        return ct.minreal(ct.feedback(design.Kp * g, design.controller / design.Kp), verbose=False)
    raise ValueError(f"derivative_on must be 'error' or 'measurement', not {derivative_on!r}")


def bode_data(loop: ct.TransferFunction, *, n: int = 200, wmin: float = 1e-3, wmax: float = 1e2) -> dict:
    """Bode data of the open loop L.

    Parameters
    ----------
    loop : control.TransferFunction
        The open loop L(s) (:func:`open_loop`).
    n : int
        Frequencies, log-spaced.
    wmin, wmax : float
        Frequency range, rad/s.

    Returns
    -------
    dict
        ``omega`` (rad/s), ``mag_db`` (dB), ``phase_deg`` (deg, unwrapped), arrays of ``n``.
    """
    omega = np.logspace(np.log10(wmin), np.log10(wmax), int(n))
    h = np.asarray(ct.frequency_response(loop, omega).complex).reshape(-1)
    return {"omega": omega, "mag_db": 20 * np.log10(np.abs(h)),
            "phase_deg": np.degrees(np.unwrap(np.angle(h)))}
