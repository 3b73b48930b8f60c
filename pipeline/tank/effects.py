"""Sizing the effects injected into the virtual tank (docs/virtual-tank.md#injected-effects).

An effect's size is stated in physical terms: extra yaw damping that cuts the yaw-rate amplitude of
a 20/20 zigzag by a given share.  These functions translate that into the tank's own parameter
(``TankConfig.extra_yaw_damping``, a non-dimensional N'_rrr) and back into the diagnosis's terms
(``n_rrr`` in s/deg^2 of :mod:`pipeline.diagnose.extended`), so a test can check an estimate
against what was injected.  Units: r in deg/s at the edges, radians inside the MMG model.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.optimize import brentq

from pipeline.config import TankConfig
from pipeline.tank.kcs import DEFAULT_TANK, KCSCoefficients, _forces, initial_state, param_vector, trim_rps
from pipeline.tank.manoeuvres import zigzag
from pipeline.tank.simulate import simulate


def yaw_rate_amplitude_20_20(cfg: TankConfig, coeffs: KCSCoefficients | None = None, *,
                             duration: float = 60.0, skip_s: float = 10.0) -> float:
    """Largest |r| after ``skip_s`` s of a noise-free 20/20 starboard zigzag in the tank.

    Parameters
    ----------
    cfg : TankConfig
        The tank (scale, approach speed, effects).
    coeffs : KCSCoefficients, optional
        The KCS coefficient set (default: the SIMMAN 2020 one).
    duration : float
        Length of the zigzag, s.
    skip_s : float
        The first seconds left out (the first swing builds up), s.

    Returns
    -------
    float
        The yaw-rate amplitude, deg/s.
    """
    run = simulate(zigzag(20, 20, "starboard", duration=duration),
                   dataclasses.replace(cfg, noise=False), coeffs=coeffs)
    f = run.frame
    return float(np.abs(f["r"].to_numpy()[f["time"].to_numpy() >= skip_s]).max())


def extra_damping_for_cut(cut: float, cfg: TankConfig = DEFAULT_TANK,
                          coeffs: KCSCoefficients | None = None) -> float:
    """Extra N'_rrr (negative: more damping) that cuts the 20/20 yaw-rate amplitude by ``cut``.

    The amplitude is measured against the same tank without extra damping (other effects of ``cfg``
    kept; speed held or free as ``cfg`` says).

    Parameters
    ----------
    cut : float
        The share of the amplitude to cut, in (0, 0.9).
    cfg : TankConfig
        The tank (scale, approach speed, effects).
    coeffs : KCSCoefficients, optional
        The KCS coefficient set (default: the SIMMAN 2020 one).

    Returns
    -------
    float
        The ``TankConfig.extra_yaw_damping`` to inject (non-dimensional N'_rrr, negative).

    Raises
    ------
    ValueError
        When ``cut`` is outside (0, 0.9) or no damping up to N'_rrr = -100 reaches it.
    """
    if not 0.0 < cut < 0.9:
        raise ValueError(f"cut must be a fraction in (0, 0.9), got {cut!r}")
    clean = dataclasses.replace(cfg, extra_yaw_damping=0.0)
    amp0 = yaw_rate_amplitude_20_20(clean, coeffs)

    def excess(mag: float) -> float:
        amp = yaw_rate_amplitude_20_20(dataclasses.replace(clean, extra_yaw_damping=-mag), coeffs)
        return (1.0 - amp / amp0) - cut

    hi = 0.5
    while excess(hi) < 0.0:
        hi *= 2.0
        if hi > 100.0:
            raise ValueError(f"no extra damping cuts the 20/20 yaw-rate amplitude by {cut:.0%}")
    return -float(brentq(excess, 0.0, hi, xtol=1e-6))


def n_rrr_equivalent(extra_yaw_damping: float, cfg: TankConfig = DEFAULT_TANK,
                     coeffs: KCSCoefficients | None = None, *, r_deg_s: float = 1.0) -> float:
    """The injected N'_rrr in the diagnosis model's terms: n_rrr with dr/dt += n_rrr r^3.

    The MMG yaw moment gains (rho/2) L^2 d U^2 N'_rrr (r L/U)^3, which through the sway-yaw mass
    matrix adds a yaw acceleration exactly cubic in r at zero drift; evaluated here from the model's
    own derivative at the approach speed (u = U, v = 0, r = ``r_deg_s``), so the conversion shares
    every constant with the simulator.

    Parameters
    ----------
    extra_yaw_damping : float
        The injected non-dimensional N'_rrr (``TankConfig.extra_yaw_damping``).
    cfg : TankConfig
        The tank (scale, approach speed, effects).
    coeffs : KCSCoefficients, optional
        The KCS coefficient set (default: the SIMMAN 2020 one).
    r_deg_s : float
        Yaw rate the derivative is evaluated at, deg/s (the result does not depend on it).

    Returns
    -------
    float
        n_rrr, s/deg^2 (dr/dt in deg/s^2 for r in deg/s).
    """
    coeffs = coeffs or KCSCoefficients()
    rps = trim_rps(cfg, coeffs)
    s = initial_state(cfg)
    s[2] = math.radians(r_deg_s)
    with_extra = param_vector(dataclasses.replace(cfg, extra_yaw_damping=extra_yaw_damping), coeffs, rps)
    without = param_vector(dataclasses.replace(cfg, extra_yaw_damping=0.0), coeffs, rps)
    d_rdot = math.degrees(_forces(s, 0.0, with_extra)[2] - _forces(s, 0.0, without)[2])  # deg/s^2
    return d_rdot / r_deg_s**3
