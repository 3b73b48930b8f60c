"""Zigzag and turning-circle analysis against runs simulated with known dynamics.

The simulators here are deliberately small and independent of the code under test:
``simulate_zigzag`` integrates a first-order Nomoto ship (T r' + r = K delta) exactly over fine
sub-steps, with a rate-limited rudder and the ITTC zigzag logic (counter-rudder when the heading
deviation reaches the trigger), and records the true execute instants and heading extrema;
``simulate_circle`` is a straight approach followed by a turn at constant rate.  test_graphical.py
imports ``simulate_zigzag`` from here.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from pipeline.errors import InputError
from pipeline.indices import imo_check, overshoot_limits, turning_metrics, zigzag_metrics
from pipeline.io import Run


def simulate_zigzag(K=0.5, T=6.0, rudder=20.0, trigger=20.0, first_side=1, rate=14.28, dt=0.08,
                    sub=16, duration=120.0, t_approach=5.0, speed=1.5, noise=0.0, seed=0,
                    rudder_offset=0.0, lpp=6.0, trigger_delay=0.0):
    """First-order Nomoto zigzag.  Returns (Run, truth) with truth = {"executes", "peaks"}.

    Exact integration for a constant rudder over each sub-step (rudder taken at the sub-step
    midpoint); zigzag logic on the true heading at every sub-step; ``rate`` deg/s (inf: step
    rudder).  The counter-rudder is commanded ``trigger_delay`` s after the heading reaches the
    trigger.  ``rudder_offset`` deg is added to the effective rudder (not to the logged one).
    Noise (one sigma, deg or deg/s) on the logged psi, r, delta, seeded.
    """
    h = dt / sub
    n_log = int(round(duration / dt)) + 1
    e = math.exp(-h / T)
    psi = r = dlt = 0.0
    x = y = 0.0
    cmd = 0.0
    side = first_side
    executes, peaks = [], []
    rows = []
    started = False
    pending = None
    r_prev = 0.0
    for k in range(n_log):
        t0 = k * dt
        rows.append((t0, x, y, psi, r, dlt))
        for j in range(sub):
            t = t0 + j * h
            if not started and t >= t_approach - 1e-12:
                started = True
                cmd = side * rudder
                executes.append(t)
            elif started and side * psi >= trigger:
                if pending is None:
                    pending = t + trigger_delay
                if t >= pending - 1e-12:
                    pending = None
                    side = -side
                    cmd = side * rudder
                    executes.append(t)
            step = h * rate if math.isfinite(rate) else abs(cmd - dlt)
            d_new = dlt + float(np.clip(cmd - dlt, -step, step))
            d_eff = 0.5 * (dlt + d_new) + rudder_offset
            kd = K * d_eff
            r_new = kd + (r - kd) * e
            psi_new = psi + kd * h + (r - kd) * T * (1 - e)
            a = math.radians(psi)
            x += speed * math.cos(a) * h
            y += speed * math.sin(a) * h
            if started and r_prev != 0 and np.sign(r_new) != np.sign(r) and r != 0:
                tz = t + h * r / (r - r_new)
                peaks.append((tz, psi + r * (tz - t) * 0.5))      # r ~ linear near zero
            r_prev = r_new
            psi, r, dlt = psi_new, r_new, d_new
    arr = np.array(rows)
    rng = np.random.default_rng(seed)
    frame = pd.DataFrame({"time": arr[:, 0], "x0": arr[:, 1], "y0": arr[:, 2],
                          "psi": arr[:, 3], "u": speed, "v": 0.0, "r": arr[:, 4], "delta": arr[:, 5]})
    if noise:
        for c in ("psi", "r", "delta"):
            frame[c] = frame[c] + noise * rng.standard_normal(len(frame))
    meta = {"run_id": "sim", "kind": "zigzag", "rudder_deg": rudder, "heading_deg": trigger,
            "lpp": lpp, "approach_speed": speed, "test_name": f"zigzag {rudder:g}/{trigger:g}"}
    return Run(frame=frame, meta=meta), {"executes": np.array(executes), "peaks": peaks}


def simulate_circle(radius=9.0, speed=1.2, turn_speed=None, t_exec=10.0, duration=120.0, dt=0.08,
                    side=1, rudder=35.0, rudder_rate=14.28, lpp=6.0, heading0=30.0):
    """Straight approach at ``speed`` then a circle of ``radius`` m at ``turn_speed`` m/s
    (instantaneous), heading0 deg initial heading, side +1 starboard.  The rudder starts its ramp
    (rudder_rate deg/s) at t_exec."""
    ts = turn_speed or speed
    t = np.arange(0.0, duration + dt / 2, dt)
    rate = ts / radius                          # rad/s
    a0 = math.radians(heading0)
    psi = np.where(t < t_exec, a0, a0 + side * rate * (t - t_exec))
    xe, ye = speed * t_exec * math.cos(a0), speed * t_exec * math.sin(a0)
    x = np.where(t < t_exec, speed * t * math.cos(a0), 0.0)
    y = np.where(t < t_exec, speed * t * math.sin(a0), 0.0)
    m = t >= t_exec
    # centre of the circle lies to the turning side of the track at the execute point
    xc = xe - side * radius * math.sin(a0)
    yc = ye + side * radius * math.cos(a0)
    x[m] = xc + side * radius * np.sin(psi[m])
    y[m] = yc - side * radius * np.cos(psi[m])
    frame = pd.DataFrame({"time": t, "x0": x, "y0": y, "psi": np.degrees(psi),
                          "u": np.where(m, ts, speed), "v": 0.0,
                          "r": np.where(m, side * math.degrees(rate), 0.0),
                          "delta": side * np.clip(rudder_rate * (t - t_exec), 0.0, rudder)})
    return Run(frame=frame, meta={"run_id": "circle", "kind": "turning", "lpp": lpp,
                                  "rudder_deg": rudder, "test_name": "turning circle"}), {}


# ------------------------------------------------------------------------------------------ zigzag

def _analytic_overshoot(K, T, rudder, r1):
    """First-order Nomoto, step counter-rudder of size `rudder` when the yaw rate is r1 (same sign
    as the turn): time to r = 0 and extra heading."""
    kd = K * rudder
    tc = T * math.log((abs(r1) + kd) / kd)
    return tc, -kd * tc + T * abs(r1)


def test_step_rudder_zigzag_matches_closed_form():
    K, T, rud, trig = 0.4, 8.0, 10.0, 10.0
    run, truth = simulate_zigzag(K=K, T=T, rudder=rud, trigger=trig, rate=math.inf, duration=150)
    zz = zigzag_metrics(run)
    ex = np.array([e["time_s"] for e in zz["executes"]])
    np.testing.assert_allclose(ex[: truth["executes"].size], truth["executes"][: ex.size], atol=0.041)
    # initial turning time: K d (t - T (1 - exp(-t/T))) = trig
    from scipy.optimize import brentq
    t_init = brentq(lambda t: K * rud * (t - T * (1 - math.exp(-t / T))) - trig, 1e-3, 200)
    assert zz["initial_turning_time_s"] == pytest.approx(t_init, abs=0.05)
    # first overshoot: the yaw rate at the counter execute is K d (1 - exp(-t_init/T))
    r1 = K * rud * (1 - math.exp(-t_init / T))
    tc, ov = _analytic_overshoot(K, T, rud, r1)
    assert zz["first_overshoot_deg"] == pytest.approx(ov, abs=0.03)
    assert zz["time_to_check_yaw_s"] == pytest.approx(tc, abs=0.05)
    assert zz["first_side"] == "starboard"
    assert zz["period_s"] == pytest.approx(truth["executes"][2] - truth["executes"][0], abs=0.05)


@pytest.mark.parametrize("first_side", [1, -1])
@pytest.mark.parametrize("noise", [0.0, 0.05])
def test_rate_limited_noisy_zigzag_either_side(first_side, noise):
    run, truth = simulate_zigzag(K=0.5, T=6.0, rudder=20, trigger=20, first_side=first_side, rate=5.0,
                                 noise=noise, seed=3)
    zz = zigzag_metrics(run)
    assert zz["first_side"] == ("starboard" if first_side == 1 else "port")
    ex = np.array([e["time_s"] for e in zz["executes"]])
    n = min(ex.size, truth["executes"].size)
    assert n >= 5
    np.testing.assert_allclose(ex[:n], truth["executes"][:n], atol=0.03 if noise == 0 else 0.08)
    # true extrema from the fine simulation
    peaks = truth["peaks"]
    for o in zz["overshoots"][:4]:
        tp, pp = min(peaks, key=lambda p: abs(p[0] - o["t_peak_s"]))
        assert o["t_peak_s"] == pytest.approx(tp, abs=0.1 if noise == 0 else 0.3)
        assert o["peak_dev_deg"] == pytest.approx(pp, abs=0.02 if noise == 0 else 0.08)
        side = 1 if o["side"] == "starboard" else -1
        assert o["angle_deg"] == pytest.approx(side * pp - 20.0, abs=0.02 if noise == 0 else 0.08)
        assert o["check_time_s"] == pytest.approx(tp - o["t_execute_s"], abs=0.3)
    # port and starboard are grouped by the side of the turn
    first = zz["overshoots"][0]
    assert first["side"] == zz["first_side"]
    assert zz["by_side"][zz["first_side"]]["first_overshoot_deg"] == first["angle_deg"]
    other = "port" if zz["first_side"] == "starboard" else "starboard"
    assert zz["by_side"][other]["first_overshoot_deg"] == zz["second_overshoot_deg"]


def test_trigger_delay_is_measured_and_overshoot_is_referred_to_the_trigger():
    run, truth = simulate_zigzag(trigger_delay=0.4, noise=0.05, seed=9)
    zz = zigzag_metrics(run)
    assert zz["mean_trigger_delay_s"] == pytest.approx(0.4, abs=0.05)
    o = zz["overshoots"][0]
    # the heading at the (late) execute is beyond the trigger: overshoot beyond the execute is smaller
    assert o["angle_deg"] - o["beyond_execute_deg"] == pytest.approx(
        zz["executes"][1]["heading_dev_deg"] - 20.0, abs=1e-9)
    assert o["angle_deg"] - o["beyond_execute_deg"] > 0.5
    run0, _ = simulate_zigzag(trigger_delay=0.0)
    assert abs(zigzag_metrics(run0)["mean_trigger_delay_s"]) < 0.05


def test_execute_of_an_accelerating_servo():
    """Servo that accelerates (0.5 s) before its rate limit, logged at 0.05 s with 0.01 deg steps
    (like the HSVA logs): the execute is where the rudder starts to move, not where the straight
    ramp extrapolates to."""
    from pipeline.indices.executes import find_executes
    t = np.arange(0.0, 40.0, 0.05)
    starts = [5.03, 17.52]
    levels = [20.0, -20.0]
    d = np.zeros_like(t)
    prev = 0.0
    for ts, lv in zip(starts, levels, strict=True):
        tau = np.clip(t - ts, 0, None)
        acc, rate = 32.0, 16.0                       # deg/s^2, deg/s: full rate after 0.5 s
        move = np.where(tau < rate / acc, 0.5 * acc * tau**2, rate**2 / (2 * acc) + rate * (tau - rate / acc))
        seg = prev + np.sign(lv - prev) * np.minimum(move, abs(lv - prev))
        d = np.where(t >= ts, seg, d)
        prev = lv
    d = np.round(d, 2)
    ex = find_executes(t, d)
    # the straight ramp extrapolates to 0.25 s after the start (rate / (2 acc)); the departure
    # bracket brings it back to where the movement becomes visible (0.01 deg logging) <= 0.08 s
    np.testing.assert_allclose(ex.times, starts, atol=0.081)
    assert np.all(ex.times >= np.array(starts))
    assert list(ex.sides) == [1, -1]


def test_neutral_rudder_follows_the_configured_share():
    """A rudder held at 3 deg before the first execute of a 20 deg zigzag: the default neutral band
    (a quarter of the amplitude, 5 deg) takes 3 deg as the neutral and measures the plateaus from
    it; a band of a tenth (2 deg) does not, and the neutral is 0."""
    from dataclasses import replace

    from pipeline.config import ManoeuvreConfig
    from pipeline.indices.executes import find_executes
    t = np.arange(0.0, 40.0, 0.05)
    d = np.where(t < 5.0, 3.0, np.where(t < 17.5, 23.0, -17.0))
    ex = find_executes(t, d)
    assert ex.neutral == pytest.approx(3.0) and ex.amplitude == pytest.approx(20.0)
    narrow = find_executes(t, d, config=replace(ManoeuvreConfig(), neutral_share=0.1))
    assert narrow.neutral == 0.0
    np.testing.assert_allclose(ex.levels, [23.0, -17.0])


def test_mirror_runs_give_same_overshoots():
    a = zigzag_metrics(simulate_zigzag(first_side=1)[0])
    b = zigzag_metrics(simulate_zigzag(first_side=-1)[0])
    for k in ("first_overshoot_deg", "second_overshoot_deg", "initial_turning_time_s", "period_s"):
        assert a[k] == pytest.approx(b[k], abs=1e-6)


def test_rudder_offset_makes_sides_differ():
    zz = zigzag_metrics(simulate_zigzag(rudder_offset=2.0, duration=150)[0])
    s, p = zz["by_side"]["starboard"], zz["by_side"]["port"]
    # a starboard rudder offset makes starboard swings overshoot more than port ones
    assert s["mean_overshoot_deg"] > p["mean_overshoot_deg"] + 0.5


def test_not_a_zigzag_is_refused():
    t = np.arange(0, 30, 0.08)
    run = Run(pd.DataFrame({"time": t, "psi": 0.1 * t, "r": 0.1 + 0 * t, "delta": np.where(t > 5, 10.0, 0)}),
              {"run_id": "step"})
    with pytest.raises(InputError, match="no counter-rudder"):
        zigzag_metrics(run)
    still = Run(pd.DataFrame({"time": t, "psi": 0 * t, "r": 0 * t, "delta": 0 * t}), {"run_id": "still"})
    with pytest.raises(InputError, match="never moves"):
        zigzag_metrics(still)
    bad = Run(pd.DataFrame({"time": t, "psi": np.where(t > 3, np.nan, 0), "r": 0 * t, "delta": 0 * t}),
              {"run_id": "nan"})
    with pytest.raises(InputError, match="column 'psi'"):
        zigzag_metrics(bad)


# ------------------------------------------------------------------------------------------ turning

@pytest.mark.parametrize("side", [1, -1])
def test_constant_rate_circle(side):
    R, lpp = 9.0, 6.0
    run, _ = simulate_circle(radius=R, speed=1.2, turn_speed=0.6, side=side, lpp=lpp)
    m = turning_metrics(run)
    assert m["side"] == ("starboard" if side == 1 else "port")
    assert m["advance_m"] == pytest.approx(R, rel=2e-3)
    assert m["transfer_m"] == pytest.approx(R, rel=2e-3)
    assert m["tactical_diameter_m"] == pytest.approx(2 * R, rel=2e-3)
    assert m["steady_diameter_m"] == pytest.approx(2 * R, rel=1e-6)
    assert m["tactical_diameter_L"] == pytest.approx(2 * R / lpp, rel=2e-3)
    assert m["steady_speed_ratio"] == pytest.approx(0.5, rel=1e-6)
    assert m["approach_speed_m_s"] == pytest.approx(1.2)
    assert m["steady_yaw_rate_deg_s"] == pytest.approx(side * math.degrees(0.6 / R))


def test_short_turn_is_refused():
    run, _ = simulate_circle(duration=15.0)
    with pytest.raises(InputError, match="90 deg"):
        turning_metrics(run)


# ------------------------------------------------------------------------------------------ IMO

def test_overshoot_limits_follow_msc137():
    assert overshoot_limits(5.0) == (10.0, 25.0)
    assert overshoot_limits(20.0) == (15.0, 32.5)
    assert overshoot_limits(35.0) == (20.0, 40.0)


def test_imo_check_uses_full_scale_l_over_v():
    # KCS-like: L/V = 6.07/2.006 = 3.03 s model, x sqrt(37.89) = 18.6 s full scale -> 14.3 deg limit
    meta = {"lpp": 6.0702, "approach_speed": 2.006, "model_scale": 37.89, "rudder_deg": 10, "heading_deg": 10}
    res = imo_check("zigzag", {"first_overshoot_deg": 12.0, "second_overshoot_deg": 20.0}, meta)
    lv = 6.0702 / 2.006 * math.sqrt(37.89)
    assert res["l_over_v_s"] == pytest.approx(lv)
    first = res["criteria"][0]
    assert first["limit"] == pytest.approx(5 + 0.5 * lv)
    assert first["pass"] and res["pass"]
    res = imo_check("zigzag", {"first_overshoot_deg": 26.0}, {**meta, "rudder_deg": 20, "heading_deg": 20})
    assert res["criteria"][0]["limit"] == 25.0 and res["pass"] is False
    res = imo_check("zigzag", {"first_overshoot_deg": 3.0}, {**meta, "rudder_deg": 20, "heading_deg": 10})
    assert not res["applicable"] and res["pass"] is None
    res = imo_check("turning", {"advance_L": 4.6, "tactical_diameter_L": 4.0}, {**meta, "rudder_deg": 35})
    assert [c["pass"] for c in res["criteria"]] == [False, True] and res["pass"] is False


def test_zigzag_feeds_imo_check():
    run, _ = simulate_zigzag(K=0.5, T=6.0, rudder=10, trigger=10, speed=1.5, lpp=6.0)
    run.meta["model_scale"] = 40.0
    zz = zigzag_metrics(run)
    res = imo_check("zigzag", zz, run.meta)
    names = [c["name"] for c in res["criteria"]]
    assert names[:2] == ["first overshoot", "second overshoot"]
    reach = [c for c in res["criteria"] if c["name"].startswith("initial turning")][0]
    # constant speed: reach = speed x (execute -> trigger time)
    assert reach["value"] == pytest.approx(1.5 * zz["initial_turning_time_s"] / 6.0, rel=1e-3)


# ------------------------------------------------------------------------------------------ measured

@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("stem,side,trig", [("HSVA_CPMC_KVLCC2_Z_10_10_P", "port", 10.0),
                                            ("HSVA_CPMC_KVLCC2_Z_20_10_S", "starboard", 10.0)])
def test_measured_hsva_zigzags_are_read_consistently(hsva_dir, stem, side, trig):
    """Real KVLCC2 zigzags: the analysis must agree with what the tank operator did.  The side
    detected from the logged rudder is the one in the file name; every counter-rudder execute comes
    just after the heading deviation reaches the trigger (a short operator/servo delay, never
    before); overshoots are positive; the 10/10 IMO limits use the full-scale L/V (>= 30 s here)."""
    from pipeline import ingest

    run = ingest.ingest_file(hsva_dir / f"{stem}.dat")
    zz = zigzag_metrics(run)
    assert zz["first_side"] == side
    assert zz["heading_deg"] == trig
    for e in zz["executes"][1:]:
        assert 0.0 <= e["trigger_delay_s"] <= 0.5
        assert trig <= abs(e["heading_dev_deg"]) <= trig + 2.0
    assert all(o["angle_deg"] > 0 for o in zz["overshoots"])
    assert zz["by_side"][side]["first_overshoot_deg"] == zz["first_overshoot_deg"]
    res = imo_check("zigzag", zz, run.meta)
    if stem.endswith("10_10_P"):
        assert res["l_over_v_s"] > 30 and res["criteria"][0]["limit"] == 20.0
    else:
        assert not res["applicable"]
