"""ITTC 7.5-04-02-01 zigzag analysis of a run (docs/indices.md; units s, deg, deg/s; positive delta =
starboard).

Definitions used (documented choices where the procedure leaves room):

* original heading psi0: heading at the first execute (straight line fitted to psi over
  ``heading_window`` s before it, so noise and a slow drift do not bias it);
* heading trigger psi_t: the run's ``heading_deg`` metadata, else the median |psi - psi0| at the
  counter-rudder executes;
* execute times: :func:`pipeline.indices.executes.find_executes` (start of each rudder ramp);
* overshoot angle n (n = 1 first, 2 second, ...): after counter-rudder execute n (execute n+1
  overall), the peak heading deviation beyond the trigger, side*(psi_peak - psi0) - psi_t, where
  side is the direction the ship was turning (+1 starboard, -1 port);
  (``beyond_execute_deg`` is the heading change after the execute itself; with a trigger delay
  the two differ, e.g. in the HSVA runs the rudder starts moving ~0.15-0.3 s after the trigger);
* trigger delay: from the heading crossing psi_t to the counter-rudder execute;
* time to check yaw: from that counter-rudder execute to the heading extremum (r = 0);
* initial turning time: from the first execute until the heading deviation first reaches psi_t;
* period: from an execute to the second next one (one full cycle); ``period`` is the first;
* heading extrema: cubic fitted to psi around the raw extremum (robust to noise; a cubic, unlike
  a parabola, follows the asymmetric turn-back and does not bias the time of r = 0);
* port and starboard: overshoots grouped by the side the ship was turning when it overshot.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pipeline.config import IndicesConfig
from pipeline.errors import InputError
from pipeline.indices.executes import _crossing_time, extremum, find_executes, heading_at
from pipeline.io import Run

SIDE_NAME = {1: "starboard", -1: "port"}


def _signals(run: Run) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t, psi, delta = run.col("time"), run.col("psi"), run.col("delta")
    for name, a in (("time", t), ("psi", psi), ("delta", delta)):
        if not np.all(np.isfinite(a)):
            raise InputError("NaN or infinite value", file=run.name, column=name)
    if t.size < 10 or np.any(np.diff(t) <= 0):
        raise InputError("time must increase and the run needs at least 10 samples", file=run.name,
                         column="time")
    return t, psi, delta


def zigzag_metrics(run: Run, *, config: IndicesConfig | None = None) -> dict[str, Any]:
    """Zigzag metrics of a run (see the module docstring for the definitions).

    Parameters
    ----------
    run : Run
        A zigzag: time s, psi deg, delta deg (x0, y0 m for the reach).
    config : IndicesConfig, optional
        The heading and peak windows and the execute thresholds.

    Returns
    -------
    dict
        rudder_deg (amplitude), heading_deg (trigger), first_side, psi0_deg,
        executes [{"time_s", "side", "rudder_deg", "heading_dev_deg", "trigger_delay_s"}],
        mean_trigger_delay_s, overshoots [{"n", "side", "angle_deg", "check_time_s", "t_execute_s",
        "t_peak_s", "peak_dev_deg", "beyond_execute_deg"}], first_overshoot_deg,
        second_overshoot_deg, third_overshoot_deg, initial_turning_time_s, reach_at_trigger_m (track
        length from the first execute until the trigger heading; needs x0, y0),
        time_to_check_yaw_s (first), period_s (first full cycle), periods_s, mean_period_s, by_side
        {"starboard"|"port": {"overshoots_deg", "check_times_s", "first_overshoot_deg",
        "mean_overshoot_deg", "mean_check_time_s"}}.  Times in s, angles in deg.

    Raises
    ------
    InputError
        When the run has no counter-rudder.
    """
    cfg = config or IndicesConfig()
    t, psi, delta = _signals(run)
    ex = find_executes(t, delta, level_fraction=cfg.level_fraction, ramp_band=cfg.ramp_band,
                       config=cfg.manoeuvre)
    if ex.times.size < 2:
        raise InputError("not a zigzag: no counter-rudder execute found", file=run.name, column="delta")
    psi0 = heading_at(t, psi, ex.times[0], cfg.heading_window)
    dev = psi - psi0
    idx = np.searchsorted(t, ex.times)
    dev_at_ex = np.array([np.interp(te, t, dev) for te in ex.times])
    trig = run.meta.get("heading_deg")
    trig = float(trig) if trig else float(np.median(np.abs(dev_at_ex[1:])))
    first = int(ex.sides[0])

    # initial turning time
    t_init = _crossing_time(t, first * dev, trig, int(idx[0]), int(idx[1]) if idx.size > 1 else t.size - 1)
    if t_init is None:
        t_init = _crossing_time(t, first * dev, trig, int(idx[0]), t.size - 1)
    overs = []
    for n in range(1, ex.times.size):
        side = int(ex.sides[n - 1])              # direction the ship was turning
        i0 = int(idx[n])
        i1 = int(idx[n + 1]) if n + 1 < idx.size else t.size - 1
        gap = t[i1] - t[i0]
        win = min(cfg.peak_window, cfg.manoeuvre.peak_window_share * gap) if gap > 0 else cfg.peak_window
        tp, pp, complete = extremum(t, psi, i0, i1, side, win)
        if not complete:
            continue
        overs.append({"n": n, "side": SIDE_NAME[side],
                      "angle_deg": side * (pp - psi0) - trig,
                      "check_time_s": tp - ex.times[n], "t_execute_s": float(ex.times[n]),
                      "t_peak_s": tp, "peak_dev_deg": pp - psi0,
                      "beyond_execute_deg": side * (pp - psi0 - dev_at_ex[n])})
    reach = None
    if t_init is not None and "x0" in run.frame.columns and "y0" in run.frame.columns:
        tt = np.linspace(ex.times[0], t_init, 200)
        xs, ys = np.interp(tt, t, run.col("x0")), np.interp(tt, t, run.col("y0"))
        reach = float(np.sum(np.hypot(np.diff(xs), np.diff(ys))))
    # how long after the heading reached the trigger the rudder started moving (counter executes)
    delays: list[float | None] = [None]
    for n in range(1, ex.times.size):
        side = int(ex.sides[n - 1])
        lo = int(idx[n - 1])
        tc = _crossing_time(t, side * dev, trig, lo, min(int(idx[n]) + 1, t.size - 1))
        delays.append(None if tc is None else float(ex.times[n] - tc))
    periods = [float(ex.times[i + 2] - ex.times[i]) for i in range(ex.times.size - 2)]

    def nth(k):
        return overs[k]["angle_deg"] if len(overs) > k and overs[k]["n"] == k + 1 else None

    by_side = {}
    for s in ("starboard", "port"):
        o = [x for x in overs if x["side"] == s]
        by_side[s] = {
            "overshoots_deg": [x["angle_deg"] for x in o],
            "check_times_s": [x["check_time_s"] for x in o],
            "first_overshoot_deg": o[0]["angle_deg"] if o else None,
            "mean_overshoot_deg": float(np.mean([x["angle_deg"] for x in o])) if o else None,
            "mean_check_time_s": float(np.mean([x["check_time_s"] for x in o])) if o else None,
        }
    return {
        "rudder_deg": ex.amplitude, "rudder_neutral_deg": ex.neutral, "heading_deg": trig,
        "first_side": SIDE_NAME[first], "psi0_deg": psi0,
        "executes": [{"time_s": float(te), "side": SIDE_NAME[int(s)], "rudder_deg": float(lv),
                      "heading_dev_deg": float(dv), "trigger_delay_s": dl}
                     for te, s, lv, dv, dl in zip(ex.times, ex.sides, ex.levels, dev_at_ex, delays,
                                                  strict=True)],
        "mean_trigger_delay_s": float(np.mean([d for d in delays if d is not None]))
        if any(d is not None for d in delays) else None,
        "overshoots": overs,
        "first_overshoot_deg": nth(0), "second_overshoot_deg": nth(1), "third_overshoot_deg": nth(2),
        "initial_turning_time_s": None if t_init is None else float(t_init - ex.times[0]),
        "reach_at_trigger_m": reach,
        "time_to_check_yaw_s": overs[0]["check_time_s"] if overs and overs[0]["n"] == 1 else None,
        "period_s": periods[0] if periods else None, "periods_s": periods,
        "mean_period_s": float(np.mean(periods)) if periods else None,
        "by_side": by_side,
    }
