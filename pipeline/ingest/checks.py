"""Physical checks at ingest: units, signs, spikes and scale that cannot be right (docs/contract.md).

Every check works on a run already in canonical names and at model scale (after Froude scaling),
and refuses with one line (:class:`pipeline.errors.InputError`) naming file, row or column.  The
thresholds (:class:`pipeline.config.IngestChecks`, each with its unit and reason there) and
the checks:

Yaw rate against heading (``r = d(psi)/dt``, docs/contract.md#run-data)
    The heading change is regressed on the time integral of r, with an offset and a linear drift
    term (a rate-gyro bias integrates to a ramp): ``psi - psi0 = s * int(r dt) + a + b t``.  The
    integral removes the measurement noise that a numerical derivative would amplify.  On every
    run we hold (6 virtual-tank runs, 13 HSVA runs, the MARIN fixture) ``s`` is within 0.5 % of 1.
    Accepted: ``|s - 1| <= r_tolerance`` (10 %: a rate sensor and a heading sensor calibrated
    within a few per cent each).  ``s`` near pi/180 means psi in rad with r in deg/s, near 180/pi r in rad/s
    with psi in deg, near -1 a reversed sign: each is named.  Skipped when neither signal moves by
    ``min_excitation_deg`` (nothing to compare).

Heading amplitude against the test
    A zigzag's heading must pass its heading trigger (that is what triggers the rudder): once the
    rudder has been reversed, the heading change before the reversal must reach half the stated
    trigger, or ``min_zigzag_heading_deg`` when no trigger is stated.  A turning circle turns on:
    at least ``min_turn_heading_deg``.  Heading and yaw rate both in radians pass the r-psi test but
    fail this one.

Rudder range and units
    Beyond +-``IngestConfig.max_abs_rudder`` (90 deg) no rudder is.  A rudder that never exceeds
    ``rad_rudder_max`` (0.7, i.e. 40 deg read as radians) while the ship turns at more than
    ``turning_rate_deg_s`` deg/s and changes heading by ``min_zigzag_heading_deg`` cannot be in
    degrees: no ship turns like that on less than a degree of rudder.

Rudder sign (docs/contract.md#run-data: positive delta makes r positive)
    Over every phase where the rudder is held beyond half its largest angle on one side, the yaw
    rate must change toward that side (the first-order response of any course-stable or mildly
    unstable ship to a held rudder).  The changes are summed with the rudder's sign; a sum below
    zero, larger than ``sign_noise_factor`` times the noise of r, with most phases against the
    convention, is refused with the hint ``--rudder-sign -1``.

Spikes (docs/contract.md#bad-input: the run is refused, naming the row)
    A sample of psi or r that departs from the straight line through its two neighbours by more
    than ``spike_mad_factor`` robust standard deviations of that departure, and by more than a
    physical floor (``spike_floor_psi_deg``: 2 deg in one step, which at the 0.05-0.1 s steps of
    tank logging would take a yaw acceleration above 400 deg/s^2; ``spike_floor_r_deg_s`` 2 deg/s),
    is a spike.  Refused rather than removed: a sample the logger got wrong may have neighbours that
    are wrong too, and the user should see the file.  In a format that writes few significant digits
    (MARIN: 3) the rounding alone moves a sample's departure by up to one unit of the last digit
    (half a unit at the sample, half from its neighbours' mean; two at the run's ends), so that is
    added to the threshold: a heading beyond 999 deg is written to 10 deg, and a turning circle's third turn
    flickering across a rounding boundary is the format, not the ship.

Steady approach (docs/dataset.md, "The start of a run")
    A test starts from a steady straight approach; a logger may start earlier (the model
    accelerating from rest, the helmsman's rudder before the test).  The first rudder execute is
    where the rudder starts its swing into the first held rudder phase (``rudder_phases``, half the
    largest angle): back from the phase for as long as every step moves the rudder toward that side.
    A record that starts less than ``approach_window`` (2 s) before it is taken as it is (tank files
    often start at the execute).  Otherwise the approach values are the mean surge speed and median
    rudder over the last ``approach_window`` before the execute.  When the record's start departs
    from them (the speed, averaged over ``speed_smooth_s``, by more than ``steady_speed_share`` = 3 %
    of the approach speed: a model held at constant propeller rpm keeps its approach speed to about
    1 %, a model accelerating from rest departs by up to 100 %; or the rudder by more than
    ``quiet_rudder_share`` = 10 % of the test's largest angle: a course-keeping trim of 1-2 deg stays
    inside 10 % of a 10-35 deg test), the run is trimmed to start at the first sample after the last
    departure.  At least ``approach_window`` of steady approach must remain (what the approach speed
    is measured over), otherwise the run is refused, naming why.  A run that starts steady is not
    touched.

Scale
    With the model length L (from the dataset's Lpp over the scale, the file, or a known ship) the
    approach Froude number Fn = U / sqrt(g L) must be in ``froude_band`` (0.05-0.45: displacement
    ships are tested for manoeuvring at Fn 0.1-0.3, KVLCC2 0.142, KCS 0.26; below 0.05 the rudder
    force is too small to test, above 0.45 a displacement hull is beyond its hump speed).  The model
    itself must be a model: L in ``model_lpp_band_m`` (1-15 m; free-running models are 2-12 m).
    Without L the approach speed must be in ``model_speed_band_m_s`` (0.15-5 m/s: the Froude band over
    1-12 m models).  A file that states itself model scale (a model scale in its header) is refused
    when a further scale is given (double scaling).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from pipeline.config import IngestChecks, IngestConfig
from pipeline.errors import InputError
from pipeline.units import G

#: the thresholds of every check, with their units and reasons, are in one place: pipeline/config.py
DEFAULT_CHECKS = IngestChecks()


def _row(lines: np.ndarray, k: int) -> int | None:
    return int(lines[k]) if lines is not None and 0 <= k < len(lines) else None


# ------------------------------------------------------------------ rudder pattern
def rudder_phases(t: np.ndarray, delta: np.ndarray, level: float = 0.5) -> list[tuple[int, int, int]]:
    """Phases where |delta| is at least ``level`` times its largest value: (start, end, sign)."""
    peak = float(np.max(np.abs(delta))) if delta.size else 0.0
    if peak <= 0:
        return []
    on = np.abs(delta) >= level * peak
    sgn = np.where(on, np.sign(delta), 0).astype(int)
    # runs of equal non-zero sign, found with array operations (runs are long: a held rudder)
    edges = np.flatnonzero(np.diff(sgn)) + 1
    starts = np.concatenate([[0], edges])
    ends = np.concatenate([edges - 1, [len(sgn) - 1]])
    phases = [(int(a), int(b), int(sgn[a])) for a, b in zip(starts, ends, strict=True) if sgn[a] != 0]
    # merge flickers of the same sign split by a sample or two below the level
    merged: list[tuple[int, int, int]] = []
    for ph in phases:
        if merged and merged[-1][2] == ph[2]:
            merged[-1] = (merged[-1][0], ph[1], ph[2])
        else:
            merged.append(ph)
    return merged


def infer_test_from_rudder(t: np.ndarray, delta: np.ndarray, psi: np.ndarray, *,
                           checks: IngestChecks = DEFAULT_CHECKS) -> dict[str, Any]:
    """What the rudder signal says the test is, when the title does not.

    Zigzag: at least two held phases of alternating side; rudder = median of their largest angles;
    heading trigger = median heading change from the start of the first held phase to the executes
    after it (the last sample of each held phase still at its held angle).
    Turning: rudder held to one side only while the heading turns through 90 deg or more.
    Returns ``{"kind", "rudder_deg", "heading_deg", "first_side"}`` (kind 'other' when neither).
    """
    out: dict[str, Any] = {"kind": "other", "rudder_deg": None, "heading_deg": None, "first_side": None}
    if delta.size < 5 or np.max(np.abs(delta)) < checks.min_infer_rudder_deg:
        return out
    ph = [p for p in rudder_phases(t, delta) if t[p[1]] - t[p[0]] >= checks.min_held_phase_s]
    if not ph:
        return out
    out["first_side"] = "starboard" if ph[0][2] > 0 else "port"
    amp = float(np.median([np.max(np.abs(delta[a:b + 1])) for a, b, _ in ph]))
    out["rudder_deg"] = float(np.round(amp))
    signs = [s for _, _, s in ph]
    if len(ph) >= 2 and all(signs[i] != signs[i + 1] for i in range(len(signs) - 1)):
        out["kind"] = "zigzag"
        # the heading at each execute: the last sample of a held phase where the rudder is still at
        # its held angle (within 5 % of the largest), before it swings to the other side
        peak = float(np.max(np.abs(delta)))
        execs = []
        for a, b, _ in ph[:-1]:
            held = float(np.median(delta[a:b + 1]))
            at = np.flatnonzero(np.abs(delta[a:b + 1] - held) <= checks.held_rudder_share * peak)
            execs.append(a + int(at[-1]) if at.size else b)
        psi0 = psi[ph[0][0]]
        trig = [abs(psi[k] - psi0) for k in execs]
        out["heading_deg"] = float(np.round(np.median(trig))) if trig else None
    elif len(set(signs)) == 1 and np.ptp(psi[ph[0][0]:ph[-1][1] + 1]) >= checks.turning_min_heading_deg:
        out["kind"] = "turning"         # one side held while the ship turns through 90 deg or more
    return out


# ------------------------------------------------------------------ spikes
def last_digit_unit(x: np.ndarray, digits: int) -> np.ndarray:
    """Unit of the last of ``digits`` significant digits of each value of ``x`` (its units; 0 at 0):
    10^(floor(log10|x|) - digits + 1), e.g. 10 for 1.23E+03 written with 3 digits."""
    ax = np.abs(np.asarray(x, dtype=float))
    out = np.zeros_like(ax)
    nz = ax > 0
    out[nz] = 10.0 ** (np.floor(np.log10(ax[nz])) - digits + 1)
    return out


def check_spikes(frame: pd.DataFrame, lines: np.ndarray, name: str,
                 logged: pd.DataFrame | None = None, digits: int | None = None, *,
                 checks: IngestChecks = DEFAULT_CHECKS) -> None:
    """Refuse a one-sample jump of psi or r that no ship can make (module docstring).

    ``frame`` is the run with heading unwrapped; ``logged`` (same rows) gives the value as the file
    has it, for the message and, with ``digits`` (the significant digits the file writes), for the
    rounding unit added to the threshold, brought to the frame's scale."""
    floors = (("psi", checks.spike_floor_psi_deg, "deg"), ("r", checks.spike_floor_r_deg_s, "deg/s"))
    for col, floor, unit in floors:
        x = frame[col].to_numpy(dtype=float)
        if x.size < 5:
            continue
        d = np.empty_like(x)
        d[1:-1] = x[1:-1] - 0.5 * (x[:-2] + x[2:])
        d[0] = x[0] - (2 * x[1] - x[2])
        d[-1] = x[-1] - (2 * x[-2] - x[-3])
        inner = d[1:-1]
        mad = 1.4826 * float(np.median(np.abs(inner - np.median(inner))))
        thr = np.full(x.size, max(floor, checks.spike_mad_factor * mad))
        if digits and logged is not None and col in logged:
            raw = logged[col].to_numpy(dtype=float)
            # the file's unit at the frame's scale: psi is scale-free (and may differ from the file's
            # by whole turns, unwrapped), r scales by sqrt(lambda)
            ratio = np.abs(x[raw != 0] / raw[raw != 0]) if col == "r" else np.ones(1)
            q = np.pad(last_digit_unit(raw, digits) * (float(np.median(ratio)) if ratio.size else 1.0), 1,
                       mode="edge")
            # rounding bound of the departure: one unit inside (half at the sample, half from the
            # neighbours' mean), two at the ends (the line through the next two samples)
            near = np.maximum(q[1:-1], np.maximum(q[:-2], q[2:]))
            near[[0, -1]] *= 2.0
            thr = thr + near
        big = np.flatnonzero(np.abs(d) > thr)
        if big.size:
            k = int(big[np.argmax(np.abs(d[big]) - thr[big])])
            shown = float(logged[col].iloc[k]) if logged is not None and col in logged else x[k]
            raise InputError(f"spike: {shown:.6g} {unit} departs by {d[k]:+.4g} {unit} from its neighbours "
                             f"(more than the {thr[k]:.3g} {unit} a ship can change in one step)", file=name,
                             row=_row(lines, k), column=col)


# ------------------------------------------------------------------ units
def _integral(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(t))])


def r_psi_ratio(t: np.ndarray, psi: np.ndarray, r: np.ndarray, *,
                checks: IngestChecks = DEFAULT_CHECKS) -> float | None:
    """Slope s of ``psi - psi0 = s int(r dt) + a + b t`` (None when neither signal moves)."""
    ir = _integral(t, r)
    tt = t - t[0]
    a = np.column_stack([np.ones_like(tt), tt])
    res_psi = psi - psi[0] - a @ np.linalg.lstsq(a, psi - psi[0], rcond=None)[0]
    res_ir = ir - a @ np.linalg.lstsq(a, ir, rcond=None)[0]
    if max(np.std(res_psi), np.std(res_ir)) < checks.min_excitation_deg:
        return None
    den = float(np.dot(res_ir, res_ir))
    if den <= 1e-300:
        return 0.0
    return float(np.dot(res_ir, res_psi) / den)


def check_units(frame: pd.DataFrame, lines: np.ndarray, meta: dict, name: str, config: IngestConfig,
                declared: dict[str, str] | None = None) -> None:
    """Values that cannot be in the units of docs/contract.md#run-data (module docstring)."""
    checks = config.checks
    declared = declared or {}
    t = frame["time"].to_numpy(dtype=float)
    psi = frame["psi"].to_numpy(dtype=float)
    r = frame["r"].to_numpy(dtype=float)
    delta = frame["delta"].to_numpy(dtype=float)
    k = int(np.argmax(np.abs(delta)))
    if abs(delta[k]) > config.max_abs_rudder:
        raise InputError(f"rudder angle {delta[k]:.4g} deg is beyond +-{config.max_abs_rudder:g} deg: "
                         "units cannot be right", file=name, row=_row(lines, k), column="delta")
    k = int(np.argmax(np.abs(r)))
    if abs(r[k]) > config.max_abs_rate:
        raise InputError(f"yaw rate {r[k]:.4g} deg/s is beyond +-{config.max_abs_rate:g} deg/s at model "
                         "scale: units (or --scale) cannot be right", file=name, row=_row(lines, k),
                         column="r")
    if len(t) >= 5:
        s = r_psi_ratio(t, psi, r, checks=checks)
        if s is not None and abs(s - 1.0) > checks.r_tolerance:
            deg = 180.0 / np.pi
            hint = " (declare the unit in the header, e.g. 'psi [rad]', or convert)"
            if abs(s * deg - 1.0) <= checks.unit_factor_tolerance:
                raise InputError(f"heading looks like radians while r is in deg/s (the heading changes "
                                 f"{s:.3g} times the integral of r, 1/57.3 expected for radians){hint}",
                                 file=name, column="psi")
            if abs(s / deg - 1.0) <= checks.unit_factor_tolerance:
                hint_r = " (declare the unit in the header, e.g. 'r [rad/s]', or convert)"
                raise InputError(f"yaw rate looks like rad/s while psi is in deg (the heading changes "
                                 f"{s:.3g} times the integral of r){hint_r}", file=name, column="r")
            if abs(s + 1.0) <= checks.unit_factor_tolerance:
                raise InputError("yaw rate has the opposite sign of d(psi)/dt (r must be d(psi)/dt, "
                                 "positive to starboard)", file=name, column="r")
            raise InputError(f"yaw rate is not d(psi)/dt: the heading changes {s:.3g} times the integral "
                             f"of r (accepted within {checks.r_tolerance:.0%}); units or columns cannot be "
                             "right",
                             file=name, column="r")
    change = float(np.max(np.abs(psi - psi[0]))) if psi.size else 0.0
    kind = meta.get("kind")
    rud = meta.get("rudder_deg")
    amax = float(np.max(np.abs(delta))) if delta.size else 0.0
    if "delta" not in declared:
        if (rud and rud >= checks.min_test_rudder_deg and amax < checks.rad_rudder_share * rud
                and amax <= checks.rad_rudder_max):
            raise InputError(f"rudder looks like radians (largest {amax:.3g} for a {rud:g} deg test): "
                             "declare 'delta [rad]' in the header or convert", file=name, column="delta")
        if (0 < amax <= checks.rad_rudder_max and change >= checks.min_zigzag_heading_deg
                and np.max(np.abs(r)) >= checks.turning_rate_deg_s):
            raise InputError(f"rudder looks like radians (largest {amax:.3g} while the ship turns at up "
                             f"to {np.max(np.abs(r)):.3g} deg/s): declare 'delta [rad]' in the header or "
                             "convert", file=name, column="delta")
    phases = rudder_phases(t, delta) if amax > 0 else []
    reversed_once = len(phases) >= 2 and phases[0][2] != phases[1][2]
    if kind == "zigzag" and reversed_once:
        # the rudder was reversed, so the heading reached the trigger before the reversal
        trig = meta.get("heading_deg") if meta.get("test_from") != "rudder signal" else None
        need = 0.5 * trig if trig else checks.min_zigzag_heading_deg
        change = float(np.max(np.abs(psi[: phases[1][0] + 1] - psi[0])))
        if change < need:
            raise InputError(f"heading changes by only {change:.3g} during a zigzag that needs {need:g} deg "
                             "to trigger its rudder: heading (and yaw rate) probably in radians; declare "
                             "'psi [rad]' in the header or convert", file=name, column="psi")
    elif (kind == "turning" and amax >= checks.min_test_rudder_deg and change < checks.min_turn_heading_deg
          and t[-1] - t[0] > checks.min_turn_check_s):
        raise InputError(f"heading changes by only {change:.3g} during a turning circle (at least "
                         f"{checks.min_turn_heading_deg:g} deg expected): heading probably in radians",
                         file=name, column="psi")


def check_rudder_sign(frame: pd.DataFrame, name: str, *,
                      checks: IngestChecks = DEFAULT_CHECKS) -> dict[str, Any]:
    """Positive delta must make r positive (module docstring); returns the evidence for metadata."""
    t = frame["time"].to_numpy(dtype=float)
    r = frame["r"].to_numpy(dtype=float)
    delta = frame["delta"].to_numpy(dtype=float)
    if delta.size < 10 or np.max(np.abs(delta)) < 2.0:
        return {"rudder_sign_check": "not enough rudder to check"}
    dr2 = r[2:] - 2 * r[1:-1] + r[:-2]
    noise = 1.4826 * float(np.median(np.abs(dr2 - np.median(dr2)))) / np.sqrt(6.0)
    total, agree, against = 0.0, 0, 0
    for a, b, sgn in rudder_phases(t, delta):
        if b - a < 2:
            continue
        w = max(1, min(3, (b - a) // 4))
        change = float(np.mean(r[b - w + 1:b + 1]) - np.mean(r[a:a + w]))
        total += sgn * change
        agree += sgn * change > 0
        against += sgn * change < 0
    evidence = {"rudder_sign_check": f"yaw rate changed toward the rudder in {agree} of {agree + against} "
                                     "held rudder phases"}
    if total < 0 and against > agree and -total > checks.sign_noise_factor * max(noise, 1e-3):
        raise InputError(f"rudder sign is reversed: positive delta gives negative yaw rate in {against} of "
                         f"{agree + against} rudder phases (docs/contract.md#run-data: positive delta makes "
                         "r positive); if the "
                         "file's rudder is positive to port, ingest with --rudder-sign -1 (or "
                         "rudder_sign = -1 in dataset.toml, under [data] or the run's [runs.<id>])",
                         file=name, column="delta")
    return evidence


# ------------------------------------------------------------------ scale
def check_scale(meta: dict, frame: pd.DataFrame, name: str, scale: float, lpp_model: float | None,
                lpp_source: str | None, *, checks: IngestChecks = DEFAULT_CHECKS) -> dict[str, Any]:
    """Froude number and speed plausible for the stated scale (module docstring)."""
    if scale != 1.0 and meta.get("model_scale") and meta.get("file_states_model_scale"):
        raise InputError(f"the file states it is model scale (1:{meta['model_scale']:g}); a scale of "
                         f"{scale:g} would scale it twice: drop --scale (or set [data] scale = 1)", file=name)
    out: dict[str, Any] = {}
    u = None
    t = frame["time"].to_numpy(dtype=float)
    sel = t - t[0] <= 2.0
    if "u" in frame.columns:
        u = float(np.mean(frame["u"].to_numpy(dtype=float)[sel]))
    elif {"x0", "y0"} <= set(frame.columns) and sel.sum() >= 3:
        x, y = frame["x0"].to_numpy(dtype=float), frame["y0"].to_numpy(dtype=float)
        u = float(np.mean(np.hypot(np.gradient(x, t), np.gradient(y, t))[sel]))
    hint_full = ("the files look full scale: give the scale (--scale, or [data] scale in dataset.toml; "
                 "for model-scale files give [data] model_scale)")
    hint_twice = ("the files look scaled twice: they may already be model scale (drop --scale, or "
                  "[data] scale = 1)" if scale != 1.0 else "check the speed column's units")
    if lpp_model is not None:
        lo, hi = checks.model_lpp_band_m
        if not lo <= lpp_model <= hi:
            raise InputError(f"a model of Lpp {lpp_model:.4g} m ({lpp_source}) at scale {scale:g} is not a "
                             f"tank model ({lo:g}-{hi:g} m): {hint_full if lpp_model > hi else hint_twice}",
                             file=name)
    if u is None:
        return out
    out["approach_speed_check"] = u
    if lpp_model is not None:
        fn = u / np.sqrt(G * lpp_model)
        out["froude_number"] = float(fn)
        lo, hi = checks.froude_band
        if not lo <= fn <= hi:
            raise InputError(f"approach speed {u:.3g} m/s at model scale is Froude number {fn:.3g} for a "
                             f"{lpp_model:.3g} m model ({lpp_source}), outside {lo:g}-{hi:g} for a "
                             f"manoeuvring test: {hint_full if fn > hi else hint_twice}", file=name,
                             column="u" if "u" in frame.columns else None)
    else:
        lo, hi = checks.model_speed_band_m_s
        if not lo <= u <= hi:
            raise InputError(f"approach speed {u:.3g} m/s is not a model's ({lo:g}-{hi:g} m/s at scale "
                             f"{scale:g}): {hint_full if u > hi else hint_twice}", file=name,
                             column="u" if "u" in frame.columns else None)
    return out


# ------------------------------------------------------------------ steady approach
def _speed(frame: pd.DataFrame, t: np.ndarray) -> np.ndarray | None:
    """Surge speed (m/s): u, else the speed over ground from x0, y0; None without either."""
    if "u" in frame.columns:
        return frame["u"].to_numpy(dtype=float)
    if {"x0", "y0"} <= set(frame.columns) and len(t) >= 3:
        x, y = frame["x0"].to_numpy(dtype=float), frame["y0"].to_numpy(dtype=float)
        return np.hypot(np.gradient(x, t), np.gradient(y, t))
    return None


def steady_start(frame: pd.DataFrame, name: str, config: IngestConfig) -> tuple[int, str | None]:
    """Where the test's steady approach starts (module docstring): (first sample to keep, a note
    saying what was trimmed, or None when the run starts steady).  Raises :class:`InputError` when
    less than ``config.approach_window`` of steady approach precedes the first execute."""
    checks = config.checks
    t = frame["time"].to_numpy(dtype=float)
    delta = frame["delta"].to_numpy(dtype=float)
    phases = rudder_phases(t, delta)
    if not phases or phases[0][0] == 0:
        return 0, None
    p0, sgn = phases[0][0], phases[0][2]
    peak = float(np.max(np.abs(delta)))
    quiet = checks.quiet_rudder_share * peak
    # the execute: back from the phase along the rudder's swing toward it (each step moving the
    # rudder toward the phase's side) to where the swing starts
    k_e = p0
    while k_e > 0 and sgn * (delta[k_e] - delta[k_e - 1]) > 0:
        k_e -= 1
    if t[k_e] - t[0] < config.approach_window:
        return 0, None                  # the record starts at its test: no pre-test stretch to judge
    app = t[:k_e + 1] >= t[k_e] - config.approach_window
    d_app = float(np.median(delta[:k_e + 1][app]))
    bad_rudder = np.abs(delta[:k_e + 1] - d_app) > quiet
    u = _speed(frame, t)
    bad_speed = np.zeros(k_e + 1, dtype=bool)
    u_app = None
    if u is not None:
        h = float(np.median(np.diff(t)))
        w = max(1, int(round(checks.speed_smooth_s / h)))
        us = np.convolve(u, np.ones(w) / w, mode="same") if len(u) >= w else u
        us[: w // 2] = us[w // 2]                 # the average's edge: take the first full window
        u_app = float(np.mean(u[:k_e + 1][app]))
        bad_speed = np.abs(us[:k_e + 1] - u_app) > checks.steady_speed_share * abs(u_app)
    bad = np.flatnonzero(bad_rudder | bad_speed)
    if not bad.size:
        return 0, None
    start = int(bad[-1]) + 1
    why = ("the speed" if bad_speed[bad[-1]] else "the rudder") + " departs from its approach value"
    steady = t[k_e] - t[start] if start <= k_e else 0.0
    if steady < config.approach_window - 1e-9:
        what = (f"u {u_app:.3g} m/s" if u_app is not None else "") + (
            f"{', ' if u_app is not None else ''}rudder {d_app:.3g} deg")
        raise InputError(f"no steady approach before the first rudder execute at {t[k_e] - t[0]:.4g} s: "
                         f"{why} ({what}; speed within {checks.steady_speed_share:.0%}, rudder within "
                         f"{quiet:.3g} deg), steady for only {steady:.3g} s before it, at least "
                         f"{config.approach_window:g} s needed", file=name)
    note = (f"start trimmed to the steady approach: {t[start] - t[0]:.4g} s removed before the first "
            f"execute at {t[k_e] - t[0]:.4g} s ({why} until then: speed within "
            f"{checks.steady_speed_share:.0%} of {u_app:.3g} m/s and rudder within {quiet:.3g} deg of "
            f"{d_app:.3g} deg kept)"
            if u_app is not None else
            f"start trimmed to the steady approach: {t[start] - t[0]:.4g} s removed before the first "
            f"execute at {t[k_e] - t[0]:.4g} s ({why} until then)")
    return start, note
