"""Checks of the data themselves, not of the ship: what a sensor set-up can do to the diagnosis.

:func:`approach_drift`: the drift angle of the straight approach before the first rudder execute.
A ship running straight at constant rudder has next to no drift angle; a heading reference set off
the model's centreline shows as one in every run, with one sign.  Where v is formed from the track
and the heading (a MARIN file's earth-fixed velocities), that misalignment biases v by
u sin(misalignment) in every sample, and the output-error fit bends to follow it: measured on the
Van Berlekom tanker (tests/test_diagnose_generalise.py, ``test_tanker_heading_misalignment``) at
0.3 deg a side-swap fold of the published model cut the held-out heading error by 23 % instead of
80 %, at 1 deg the offset was missed.  The catalogue's sensor effect heading_misalignment fits the
bias and is named when that predicts the held-out runs better; the check says what the straight
runs show whatever the selection does (a search can miss the effect beside a large hull misfit).

:func:`rate_bias`: the yaw rate against the heading's own derivative.  docs/contract.md#run-data defines r =
d(psi)/dt, so over a run the integral of r must equal the heading's change; a rate gyro's constant bias (a
MEMS sensor's is 0.003-0.1 deg/s) breaks that in every sample.  The heading is taken as the reference: a
tank's heading comes from an optical tracking system or a compass, absolute, which does not drift,
and it is what the diagnosis predicts and judges.  Measured on the KVLCC2 stand-in of MARIN's files
(tests/test_diagnose_generalise.py, test_kvlcc2_rate_gyro_bias_beside_a_misalignment; the check's
known answers in tests/test_diagnose_datacheck.py): uncorrected, a 0.1 deg/s bias beside a 1 deg
heading misalignment has a false misalignment of -5.3 / -3.4 deg named as the cause (the true one
+1 deg), the fit buying the r channel's constant with a sway-reading bias; with r corrected by each
run's bias (read within 0.002 deg/s) both folds give what the misaligned files without the bias
give.  The correction is a calibration read without any model, not an effect: nothing is judged on
held-out runs, and a run whose bias is not significant is left as it was (its bytes unchanged).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import stats

from pipeline.diagnose.fit import Series

#: deg: a median approach drift angle at least this large is reported as a possible misalignment:
#: three times the 0.1 deg a tank's optical tracking resolves heading to (the rudder offset's floor
#: has the same reason), and the size at which a fold of the misaligned tanker lost its cut
MISALIGNMENT_FLOOR_DEG = 0.3
#: deg: the rudder has been executed once it leaves its first logged angle by more than this (ten
#: times a 0.1 deg encoder step: no logging noise moves it so far)
EXECUTE_DEG = 1.0
#: fewest approach samples whose mean drift is read (fewer: the approach is not in the run)
MIN_APPROACH_SAMPLES = 5


def approach_drift(series: list[Series]) -> dict:
    """Drift angle (deg, atan2(mean v, mean u), positive = v to starboard) of each run's approach:
    the samples before the rudder first leaves its starting angle by ``EXECUTE_DEG``.

    Returns ``{"per_run": {run: deg}, "median_deg": float | None, "warning": str | None}``; runs
    without u or v, or with fewer than ``MIN_APPROACH_SAMPLES`` approach samples, are left out.  The
    warning is given when the median is at least ``MISALIGNMENT_FLOOR_DEG`` and every run's drift
    has its sign (a sensor offset is the same in every run)."""
    per = {}
    for s in series:
        if s.u is None or s.v is None:
            continue
        moved = np.flatnonzero(np.abs(s.delta - s.delta[0]) > EXECUTE_DEG)
        n = int(moved[0]) if moved.size else s.t.size
        if n < MIN_APPROACH_SAMPLES:
            continue
        per[s.name] = math.degrees(math.atan2(float(np.mean(s.v[:n])), float(np.mean(s.u[:n]))))
    if not per:
        return {"per_run": per, "median_deg": None, "warning": None}
    vals = np.array(list(per.values()))
    med = float(np.median(vals))
    warning = None
    if abs(med) >= MISALIGNMENT_FLOOR_DEG and np.all(np.sign(vals) == np.sign(med)):
        u = float(np.mean([s.approach_speed() for s in series if s.u is not None]))
        warning = (
            f"Data check: the straight approach drifts {med:+.2f} deg in every run (median of {vals.size}, "
            f"one sign; floor {MISALIGNMENT_FLOOR_DEG} deg), where a ship running straight has next to "
            f"none: the heading reference may be misaligned with the track.  A sway velocity formed "
            f"from the track and the heading then carries u sin({med:+.2f} deg) = "
            f"{u * math.sin(math.radians(med)):+.4f} m/s in every sample, which bends every fit that does "
            f"not carry it: see the finding of the sensor effect heading_misalignment."
        )
    return {"per_run": per, "median_deg": med, "warning": warning}


#: a run's rate bias is read in this many equal blocks (:func:`rate_bias`): each a tenth of the run,
#: 12 s of a two-minute tank run, long against a gyro's or a tracker's noise correlation (under a
#: second), so the block slopes are independent; 9 degrees of freedom for the t-test
RATE_BIAS_BLOCKS = 10
#: two-sided level of the rate bias's t-test: 0.27 % (three sigma of a normal), so a run whose r
#: agrees with its heading is left as it was in all but one run in 370 (and then moved by noise)
RATE_BIAS_ALPHA = 0.0027


def rate_bias(series: list[Series]) -> dict:
    """Each run's yaw-rate bias (deg/s, at the data's scale), read without a model: the disagreement
    d(t) = integral of r dt (trapezoid rule) - (psi(t) - psi(0)), the heading unwrapped, holds no ship
    motion at all when r = d(psi)/dt, only noise, and grows as b t with a bias b.  b is the mean of
    the least-squares slopes of d in ``RATE_BIAS_BLOCKS`` equal blocks, its standard error their
    spread / sqrt(blocks) (batch means: valid for coloured noise of correlation time short against a
    block, no noise model needed); t-test with blocks - 1 degrees of freedom (few blocks: t, not z).

    Returns ``{"per_run": {run: {"bias_deg_s", "se_deg_s", "corrected"}}, "warning": str | None}``;
    ``corrected`` when the two-sided p-value is below ``RATE_BIAS_ALPHA`` (the warning then names
    those runs).  Runs of fewer than 4 samples a block are not read (``per_run`` leaves them out)."""
    per = {}
    crit = float(stats.t.ppf(1.0 - RATE_BIAS_ALPHA / 2.0, RATE_BIAS_BLOCKS - 1))
    for s in series:
        n = s.t.size // RATE_BIAS_BLOCKS
        if n < 4:
            continue
        psi = np.unwrap(s.psi, period=360.0)  # ingest unwraps; a run made elsewhere may not be
        d = np.concatenate([[0.0], np.cumsum(0.5 * (s.r[1:] + s.r[:-1]) * np.diff(s.t))]) - (psi - psi[0])
        slopes = np.array([np.polyfit(s.t[k * n:(k + 1) * n], d[k * n:(k + 1) * n], 1)[0]
                           for k in range(RATE_BIAS_BLOCKS)])
        b = float(np.mean(slopes))
        se = float(np.std(slopes, ddof=1) / math.sqrt(RATE_BIAS_BLOCKS))
        per[s.name] = {"bias_deg_s": b, "se_deg_s": se, "corrected": bool(abs(b) > crit * max(se, 1e-12))}
    fixed = [k for k, x in per.items() if x["corrected"]]
    warning = None
    if fixed:
        bs = np.array([per[k]["bias_deg_s"] for k in fixed])
        warning = (
            f"Data check: the yaw rate disagrees with the heading's own change (r = d(psi)/dt) by "
            f"{np.min(bs):+.4f} to {np.max(bs):+.4f} deg/s in {len(fixed)} of {len(per)} runs (t-test "
            f"over {RATE_BIAS_BLOCKS} blocks a run, level {RATE_BIAS_ALPHA:.2%}): a rate gyro's bias.  "
            f"The heading is the reference: r of those runs was corrected by its own bias before every "
            f"fit ({', '.join(fixed)})."
        )
    return {"per_run": per, "warning": warning}


def correct_rate_bias(series: list[Series], check: dict) -> list[Series]:
    """``series`` with r of every run that :func:`rate_bias` marks ``corrected`` minus its bias (deg/s);
    the others are the same objects."""
    out = []
    for s in series:
        x = check["per_run"].get(s.name)
        out.append(dataclasses.replace(s, r=s.r - x["bias_deg_s"]) if x and x["corrected"] else s)
    return out
