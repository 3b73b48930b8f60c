"""Quick characteristic figures of virtual-tank runs, to check the model against its reference.

Deliberately simple (for noise-free runs of this tank, execute at t = 0, psi(0) = 0); the full
ITTC analysis of any run belongs to :mod:`pipeline.indices`.  Angles deg, lengths in ship lengths.
"""

from __future__ import annotations

import numpy as np

from pipeline.io import Run

#: Reference behaviour of the coefficient set (docs/results.md#the-virtual-tank), first execute to starboard
#: except the 'port' turning entries.
REFERENCE = {
    "zigzag 10/10": {"overshoots": (6.3, 12.7, 9.8), "min_speed": 0.89},
    "zigzag 20/20": {"overshoots": (14.5, 17.5, 14.5), "min_speed": 0.74},
    "turning 35 starboard": {"advance": 3.18, "transfer": 1.53, "tactical": 3.26, "steady_speed": 0.56},
    "turning 35 port": {"advance": 3.07, "transfer": 1.43, "tactical": 3.04, "steady_speed": 0.53},
}


def _speed(run: Run) -> np.ndarray:
    return np.hypot(run.col("u"), run.col("v"))


def zigzag_figures(run: Run, heading_deg: float) -> dict:
    """Overshoot angles and the lowest speed ratio of a zigzag.

    The speed ratio is the lowest total speed sqrt(u^2 + v^2) over the approach speed (u at t = 0).

    Parameters
    ----------
    run : Run
        A zigzag from the tank (time s, psi deg, delta deg, u v m/s).
    heading_deg : float
        The heading trigger, deg.

    Returns
    -------
    dict
        {"overshoots": overshoot angles at each heading extremum after the first (deg),
        "extreme_times": their times (s), "min_speed": the lowest total-speed ratio and "min_u" the
        lowest surge ratio (dimensionless)}.
    """
    psi = run.col("psi") * np.sign(run.col("delta")[np.argmax(np.abs(run.col("delta")) > 1.0)])
    r = np.gradient(psi, run.col("time"))
    ext = [i for i in range(1, len(psi) - 1) if r[i - 1] * r[i + 1] < 0 and abs(psi[i]) > heading_deg]
    # keep one extremum per swing (sign alternates)
    swings: list[int] = []
    for i in ext:
        if swings and np.sign(psi[swings[-1]]) == np.sign(psi[i]):
            if abs(psi[i]) > abs(psi[swings[-1]]):
                swings[-1] = i
            continue
        swings.append(i)
    u0 = run.col("u")[0]
    return {
        "overshoots": [float(abs(psi[i]) - heading_deg) for i in swings],
        "extreme_times": [float(run.col("time")[i]) for i in swings],
        "min_speed": float(_speed(run).min() / u0),
        "min_u": float(run.col("u").min() / u0),
    }


def turning_figures(run: Run) -> dict:
    """The figures of a turning circle, positions of midship from the execute (t = 0).

    Parameters
    ----------
    run : Run
        A turning circle from the tank (time s, x0 y0 m, psi deg, u v m/s; meta "lpp" m).

    Returns
    -------
    dict
        {"advance", "transfer" (at 90 deg of heading), "tactical" (at 180 deg): in ship lengths;
        "heading_change": total heading change, deg; "steady_speed": the speed ratio over the last
        360 deg of heading; "steady_diameter" (ship lengths) over the same, when the run turns
        540 deg or more}.
    """
    lpp = float(run.meta["lpp"])
    psi = np.abs(run.col("psi"))
    x, y = run.col("x0"), run.col("y0")
    u0 = run.col("u")[0]

    def at(angle, arr):
        return float(np.interp(angle, psi, arr))

    out = {"advance": at(90.0, x) / lpp, "transfer": abs(at(90.0, y)) / lpp,
           "tactical": abs(at(180.0, y)) / lpp, "heading_change": float(psi[-1])}
    last = psi >= psi[-1] - 360.0
    if psi[-1] >= 540.0:
        out["steady_diameter"] = float(max(np.ptp(x[last]), np.ptp(y[last])) / lpp)
    out["steady_speed"] = float(_speed(run)[last].mean() / u0)
    return out
