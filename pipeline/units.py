"""Unit conversions and Froude scaling: the one place where they happen.

Canonical units (docs/contract.md#run-data): s, m, m/s, deg, deg/s, 1/min.
"""

from __future__ import annotations

import numpy as np

DEG = np.pi / 180.0
"""One degree in radians."""

G = 9.81
"""Acceleration of gravity, m/s^2 (the Froude number's g)."""

KNOT = 1852.0 / 3600.0
"""One international knot in m/s (a nautical mile of 1852 m per hour)."""


def deg2rad(x):
    """Degrees (or deg/s) to radians (or rad/s).

    Parameters
    ----------
    x : float or array
        Angle in deg (or rate in deg/s).

    Returns
    -------
    float or array
        The same in rad (rad/s).

    Examples
    --------
    >>> deg2rad(180.0)
    3.141592653589793
    >>> deg2rad([90.0, -90.0]).round(4).tolist()
    [1.5708, -1.5708]
    """
    return np.asarray(x, dtype=float) * DEG if np.ndim(x) else float(x) * DEG


def rad2deg(x):
    """Radians (or rad/s) to degrees (or deg/s).

    Parameters
    ----------
    x : float or array
        Angle in rad (or rate in rad/s).

    Returns
    -------
    float or array
        The same in deg (deg/s).

    Examples
    --------
    >>> rad2deg(np.pi / 2)
    90.0
    """
    return np.asarray(x, dtype=float) / DEG if np.ndim(x) else float(x) / DEG


# Froude scaling with geometric scale factor lam = L_full / L_model.
# Quantity      full -> model
# length        / lam
# time          / sqrt(lam)
# velocity      / sqrt(lam)
# angle         unchanged
# angular rate  * sqrt(lam)
# rev rate      * sqrt(lam)
FROUDE_EXPONENT = {
    "length": -1.0,
    "time": -0.5,
    "velocity": -0.5,
    "angle": 0.0,
    "rate": 0.5,
    "frequency": 0.5,
    "force": -3.0,
    "moment": -4.0,
}


def froude_to_model(value, kind: str, scale: float):
    """Bring a full-scale quantity to model scale by Froude similarity.

    Parameters
    ----------
    value : float or array
        Full-scale value(s), SI units (angles deg, rates deg/s).
    kind : str
        One of ``FROUDE_EXPONENT`` ('length', 'time', 'velocity', 'angle', 'rate', 'frequency',
        'force', 'moment').
    scale : float
        Geometric scale factor lambda = L_full / L_model (> 0), e.g. 37.89.

    Returns
    -------
    float or array
        ``value * scale ** FROUDE_EXPONENT[kind]``, the model-scale value in the same units.

    Raises
    ------
    ValueError
        For an unknown ``kind`` or a scale that is not positive.

    Examples
    --------
    The KCS's 230 m Lpp and a 10 s full-scale interval at the SIMMAN scale 1:37.89:

    >>> round(float(froude_to_model(230.0, "length", 37.89)), 4)     # m
    6.0702
    >>> round(float(froude_to_model(10.0, "time", 37.89)), 4)        # s
    1.6246
    >>> froude_to_model(1.0, "weight", 37.89)
    Traceback (most recent call last):
    ...
    ValueError: unknown Froude quantity kind 'weight'
    """
    if kind not in FROUDE_EXPONENT:
        raise ValueError(f"unknown Froude quantity kind {kind!r}")
    if not scale > 0:
        raise ValueError(f"scale factor must be positive, got {scale}")
    return np.asarray(value, dtype=float) * scale ** FROUDE_EXPONENT[kind]


def body_velocities(dx0, dy0, psi_deg):
    """Earth-fixed velocities and heading to body-fixed u, v (v to starboard).

    Parameters
    ----------
    dx0, dy0 : float or array
        Earth-fixed velocity components, m/s (x0 north, y0 east).
    psi_deg : float or array
        Heading, deg.

    Returns
    -------
    tuple
        (u, v), m/s.

    Examples
    --------
    A ship heading east (psi 90 deg) while moving north at 1 m/s drifts to port (v < 0):

    >>> u, v = body_velocities(1.0, 0.0, 90.0)
    >>> round(float(u), 12), round(float(v), 12)
    (0.0, -1.0)
    """
    p = np.asarray(psi_deg, dtype=float) * DEG
    dx0 = np.asarray(dx0, dtype=float)
    dy0 = np.asarray(dy0, dtype=float)
    u = dx0 * np.cos(p) + dy0 * np.sin(p)
    v = -dx0 * np.sin(p) + dy0 * np.cos(p)
    return u, v
