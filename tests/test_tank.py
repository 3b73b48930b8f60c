"""Virtual KCS tank: dynamics against the reference behaviour of the coefficient set, IMO criteria,
signs, mirroring, effect injection, seeded noise, the CSV layout and the command line.

Reference figures (docs/results.md#the-virtual-tank) come from an independent RK4 simulation of the same
coefficient set with the full-scale rpm (115.5 rpm x sqrt(37.89) = 710.96 rpm at model scale) and
the full-scale rudder rate 2.32 deg/s.  Both are Froude-equivalent to ours: the MMG model is
non-dimensional, our trimmed rpm is 711.03 (0.01 % away; checked below) and 2.32 x sqrt(37.89) =
14.28 deg/s.  So not re-trimming changes nothing measurable here; the differences that remain come
from modelling choices the coefficient list does not fix (wake in manoeuvring, the variable that
switches gamma_R, the folding of the mass terms into the surge equation, x_G) and from our
zigzag logic acting on the 12.5 Hz logged heading (a counter-rudder up to 0.08 s late, about 0.4 deg
of heading at 5 deg/s).  Tolerances: overshoots +-2 deg, lowest zigzag speed +-0.06 of the approach
speed (surge is the least constrained part of the set), turning advance/transfer/tactical diameter
+-8 %.  The steady turning speed is NOT within a reference tolerance (0.44 vs 0.56;
docs/results.md#the-virtual-tank): it is only checked for plausibility.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pipeline import tank
from pipeline.cli import main
from pipeline.config import TankConfig
from pipeline.errors import InputError
from pipeline.io import CANONICAL_COLUMNS
from pipeline.runinfo import parse_test_name
from pipeline.tank.figures import REFERENCE, turning_figures, zigzag_figures
from pipeline.units import body_velocities

CLEAN = TankConfig(noise=False)
OVERSHOOT_TOL = 2.0
SPEED_TOL = 0.06
TURN_TOL = 0.08


@pytest.fixture(scope="module")
def clean_runs():
    """The default set, noise-free, keyed by file stem."""
    return {m.file_stem: tank.simulate(m, CLEAN) for m in tank.default_set()}


@pytest.fixture(scope="module")
def noisy_runs():
    return {m.file_stem: tank.simulate(m, TankConfig()) for m in tank.default_set()[:2]}


# ------------------------------------------------------------------ trim, signs, kinematics

def test_straight_run_holds_speed_and_course():
    run = tank.simulate(tank.straight(60.0), CLEAN)
    u = run.col("u")
    assert np.max(np.abs(u / CLEAN.approach_speed - 1)) < 0.01
    assert np.max(np.abs(run.col("psi"))) < 1e-6
    assert run.col("x0")[-1] == pytest.approx(60.0 * CLEAN.approach_speed, rel=0.01)


def test_trimmed_rpm_is_the_froude_scaled_full_scale_rpm():
    rpm = 60 * tank.trim_rps()
    assert rpm == pytest.approx(115.5 * np.sqrt(37.89), rel=0.005)
    # and a faster approach speed needs more rpm
    assert 60 * tank.trim_rps(dataclasses.replace(CLEAN, approach_speed=2.2)) > rpm + 10


def test_linearised_indices_match_reference():
    lin = tank.linearise()
    assert lin["K'"] == pytest.approx(7.33, rel=0.03)
    assert lin["T1'"] == pytest.approx(12.9, rel=0.03)
    assert lin["T2'"] == pytest.approx(0.30, rel=0.05)
    assert lin["T3'"] == pytest.approx(0.73, rel=0.03)
    assert lin["T'"] == pytest.approx(12.4, rel=0.03)
    assert lin["K"] == pytest.approx(2.42, rel=0.03)


def test_positive_rudder_turns_to_starboard_with_consistent_kinematics(clean_runs):
    run = clean_runs["kcs_turning_35_S"]
    t, psi, r = run.col("time"), run.col("psi"), run.col("r")
    late = t > 20
    assert np.all(run.col("delta")[late] == pytest.approx(35.0))
    assert np.all(r[late] > 0) and psi[-1] > 400
    assert run.col("y0")[t < 15][-1] > 0                     # moves toward +y0 (starboard of x0)
    assert np.all(run.col("v")[late] < 0)                    # midship drifts to port in a starboard turn
    # r = dpsi/dt, and u, v are the body components of the track velocity
    np.testing.assert_allclose(np.gradient(psi, t)[5:-5], r[5:-5], atol=0.02)
    dx, dy = np.gradient(run.col("x0"), t), np.gradient(run.col("y0"), t)
    ub, vb = body_velocities(dx, dy, psi)
    np.testing.assert_allclose(ub[5:-5], run.col("u")[5:-5], atol=2e-3)
    np.testing.assert_allclose(vb[5:-5], run.col("v")[5:-5], atol=2e-3)


def test_servo_respects_rate_and_angle_limits(clean_runs):
    run = clean_runs["kcs_zigzag_20_20_S"]
    d = run.col("delta")
    rate = np.abs(np.diff(d)) / CLEAN.log_dt
    assert rate.max() <= CLEAN.rudder_rate + 1e-6
    assert rate.max() > 0.95 * CLEAN.rudder_rate                # it does move at the limit
    turn = tank.simulate(tank.turning_circle(40.0, duration=10.0), CLEAN)
    assert np.abs(turn.col("delta")).max() == pytest.approx(CLEAN.rudder_max)


# ------------------------------------------------------------------ reference behaviour and IMO

@pytest.mark.parametrize("amp", [10, 20])
def test_zigzag_overshoots_and_speed_loss_match_reference(clean_runs, amp):
    run = clean_runs[f"kcs_zigzag_{amp}_{amp}_S"]
    fig = zigzag_figures(run, amp)
    ref = REFERENCE[f"zigzag {amp}/{amp}"]
    np.testing.assert_allclose(fig["overshoots"][:3], ref["overshoots"], atol=OVERSHOOT_TOL)
    assert fig["min_speed"] == pytest.approx(ref["min_speed"], abs=SPEED_TOL)
    # IMO MSC.137(76): L/U = 3.0 s < 10 s, so the 10/10 first overshoot limit is 10 deg
    assert CLEAN.lpp / CLEAN.approach_speed < 10
    if amp == 10:
        assert fig["overshoots"][0] <= 10 and fig["overshoots"][1] <= 25
    else:
        assert fig["overshoots"][0] <= 25


@pytest.mark.parametrize("side", ["starboard", "port"])
def test_turning_circle_matches_reference_and_imo(clean_runs, side):
    run = clean_runs[f"kcs_turning_35_{side[0].upper()}"]
    fig = turning_figures(run)
    ref = REFERENCE[f"turning 35 {side}"]
    for key in ("advance", "transfer", "tactical"):
        assert fig[key] == pytest.approx(ref[key], rel=TURN_TOL), key
    assert fig["advance"] <= 4.5 and fig["tactical"] <= 5.0           # IMO
    assert fig["heading_change"] >= 400                                # a steady turn is reached
    assert 0.3 < fig["steady_speed"] < 0.7


def test_zigzag_default_duration_covers_identification_and_validation(clean_runs):
    for amp in (10, 20):
        run = clean_runs[f"kcs_zigzag_{amp}_{amp}_S"]
        assert len(run.frame) > 585 + 900
        fig = zigzag_figures(run, amp)
        # heading extrema every half period; at least 4 full periods in the record
        assert len(fig["overshoots"]) >= 8


# ------------------------------------------------------------------ port / starboard

def test_port_and_starboard_mirror_exactly_with_symmetric_coefficients():
    sym = dataclasses.replace(tank.KCSCoefficients(), gamma_minus=tank.KCSCoefficients().gamma_plus)
    s = tank.simulate(tank.zigzag(20, 20, "starboard", duration=60), CLEAN, coeffs=sym)
    p = tank.simulate(tank.zigzag(20, 20, "port", duration=60), CLEAN, coeffs=sym)
    for c in ("psi", "r", "v", "y0", "delta"):
        np.testing.assert_allclose(p.col(c), -s.col(c), atol=1e-9)
    for c in ("u", "x0"):
        np.testing.assert_allclose(p.col(c), s.col(c), atol=1e-9)


def test_port_and_starboard_runs_mirror_each_other_approximately(clean_runs):
    # the only asymmetry is gamma_R (propeller side effect): small but present
    for amp in (10, 20):
        s = zigzag_figures(clean_runs[f"kcs_zigzag_{amp}_{amp}_S"], amp)
        p = zigzag_figures(clean_runs[f"kcs_zigzag_{amp}_{amp}_P"], amp)
        assert s["min_speed"] == pytest.approx(p["min_speed"], abs=0.01)
        period_s = np.diff(s["extreme_times"][1:])[::2].sum()
        period_p = np.diff(p["extreme_times"][1:])[::2].sum()
        assert period_s == pytest.approx(period_p, rel=0.05)
        assert np.abs(np.array(s["overshoots"][:4]) - np.array(p["overshoots"][:4])).max() < 3.5
        # each run does start to its own side
        assert clean_runs[f"kcs_zigzag_{amp}_{amp}_S"].col("psi")[50] > 0
        assert clean_runs[f"kcs_zigzag_{amp}_{amp}_P"].col("psi")[50] < 0
    ts, tp = (turning_figures(clean_runs[f"kcs_turning_35_{x}"]) for x in "SP")
    assert ts["tactical"] == pytest.approx(tp["tactical"], rel=0.12)
    assert ts["tactical"] != pytest.approx(tp["tactical"], rel=1e-3)      # asymmetry is real


# ------------------------------------------------------------------ effect injection

def _steady_rudder(cfg: TankConfig, seconds: float = 120.0) -> float:
    """Mean actual rudder over the last 40 s of course keeping (PD on heading) with KCSShip."""
    ship = tank.KCSShip(cfg)
    ship.reset()
    out, dt = [], 0.08
    st = ship.state()
    for _ in range(int(seconds / dt)):
        st = ship.step(-2.0 * st["psi"] - 8.0 * st["r"], dt)
        out.append(st["delta"])
    return float(np.mean(out[-int(40 / dt):]))


def test_rudder_offset_shifts_the_steady_rudder_needed():
    base = _steady_rudder(CLEAN)
    off = _steady_rudder(dataclasses.replace(CLEAN, rudder_offset=2.0))
    assert abs(base) < 1e-6
    assert off == pytest.approx(-2.0, abs=0.05)
    # in an open-loop straight run the logged rudder stays at zero but the ship turns to starboard
    run = tank.simulate(tank.straight(20.0), dataclasses.replace(CLEAN, rudder_offset=2.0))
    assert np.all(run.col("delta") == 0) and run.col("psi")[-1] > 5


def test_rudder_delay_shifts_the_response_not_the_logged_rudder(clean_runs):
    delay = 0.48                                      # 6 logging steps
    run = tank.simulate(tank.zigzag(20, 20, duration=150), dataclasses.replace(CLEAN, rudder_delay=delay))
    ref = clean_runs["kcs_zigzag_20_20_S"]
    k = int(round(delay / CLEAN.log_dt))
    first_check = np.argmax(ref.col("psi") >= 20.0)    # before the first counter-rudder
    np.testing.assert_allclose(run.col("delta")[:first_check], ref.col("delta")[:first_check], atol=1e-12)
    np.testing.assert_allclose(run.col("psi")[k:first_check], ref.col("psi")[:first_check - k], atol=1e-9)
    # a dead time in the loop makes the overshoots larger
    assert zigzag_figures(run, 20)["overshoots"][0] > zigzag_figures(ref, 20)["overshoots"][0] + 0.5


@pytest.mark.parametrize("side, factor", [("starboard", 1.15), ("port", 0.85)])
def test_rudder_asymmetry_is_a_scaled_rudder_on_each_side(side, factor):
    """Known answer: an asymmetry a scales the angle the forces see by 1 + a to starboard and 1 - a
    to port, so until the first counter-rudder the tank with a = 0.15 is the clean tank with the
    rudder and its rate scaled by that factor (the servo ramp scales exactly), to rounding."""
    asym = tank.simulate(tank.zigzag(10, 10, side, duration=30),
                         dataclasses.replace(CLEAN, rudder_asymmetry=0.15))
    scaled = dataclasses.replace(CLEAN, rudder_rate=CLEAN.rudder_rate * factor)
    ref = tank.simulate(tank.zigzag(10 * factor, 10, side, duration=30), scaled)
    k = np.argmax(np.abs(ref.col("psi")) >= 10.0)     # the first counter-rudder decision
    assert k > 20
    for c in ("psi", "r", "v", "u"):
        np.testing.assert_allclose(asym.col(c)[:k], ref.col(c)[:k], atol=1e-9, err_msg=c)
    np.testing.assert_allclose(asym.col("delta")[:k] * factor, ref.col("delta")[:k], atol=1e-9)


def test_rudder_stall_and_lag_act_as_they_say(clean_runs):
    """A tanh stall (stall 25 deg) turns at steady state as the clean tank with the rudder at
    stall tanh(20 / stall); a first-order servo lag of 0.5 s leaves the logged servo angle alone and
    moves the response far closer to a 0.5 s dead time than it is to no lag."""
    stall = 25.0
    run = tank.simulate(tank.turning_circle(20, duration=60),
                        dataclasses.replace(CLEAN, rudder_stall_deg=stall))
    eq = tank.simulate(tank.turning_circle(stall * np.tanh(20 / stall), duration=60), CLEAN)
    full = tank.simulate(tank.turning_circle(20, duration=60), CLEAN)
    r_end = [x.col("r")[-25:].mean() for x in (run, eq, full)]
    assert r_end[0] == pytest.approx(r_end[1], rel=1e-4)   # measured 4e-6: the ramps differ, not the turn
    assert abs(r_end[2] - r_end[0]) > 20 * abs(r_end[1] - r_end[0])   # the stall itself is large
    ref = clean_runs["kcs_zigzag_20_20_S"]
    lag = tank.simulate(tank.zigzag(20, 20), dataclasses.replace(CLEAN, rudder_lag=0.5))
    dead = tank.simulate(tank.zigzag(20, 20), dataclasses.replace(CLEAN, rudder_delay=0.5))
    k = np.argmax(ref.col("psi") >= 20.0)
    np.testing.assert_allclose(lag.col("delta")[:k], ref.col("delta")[:k], atol=1e-12)
    psi_lag, psi_dead, psi0 = (x.col("psi")[:k] for x in (lag, dead, ref))
    assert np.max(np.abs(psi_lag - psi_dead)) < 0.2 * np.max(np.abs(psi_lag - psi0))
    assert lag.meta["effects"]["rudder_lag"] == 0.5 and "rudder_lag" not in ref.meta["effects"]


def test_extra_yaw_damping_cuts_the_yaw_rate(clean_runs):
    ref = clean_runs["kcs_zigzag_20_20_S"]
    damped = tank.simulate(tank.zigzag(20, 20), dataclasses.replace(CLEAN, extra_yaw_damping=-0.1))
    undamped = tank.simulate(tank.zigzag(20, 20), dataclasses.replace(CLEAN, extra_yaw_damping=+0.02))
    amp = [np.abs(x.col("r")).max() for x in (damped, ref, undamped)]
    assert amp[0] < 0.95 * amp[1] < 0.95 * amp[2]
    assert zigzag_figures(damped, 20)["overshoots"][0] < zigzag_figures(ref, 20)["overshoots"][0]


def test_hold_speed_keeps_u_constant(clean_runs):
    held = tank.simulate(tank.zigzag(20, 20), dataclasses.replace(CLEAN, hold_speed=True))
    np.testing.assert_allclose(held.col("u"), CLEAN.approach_speed, atol=1e-12)
    assert clean_runs["kcs_zigzag_20_20_S"].col("u").min() < 0.8 * CLEAN.approach_speed
    assert held.meta["hold_speed"] is True and held.meta["effects"]["hold_speed"] is True


# ------------------------------------------------------------------ KCSShip

@pytest.mark.parametrize("effects", [{}, {"rudder_delay": 0.3, "rudder_lag": 0.4, "rudder_asymmetry": -0.1,
                                             "rudder_stall_deg": 30.0, "rudder_offset": 0.5}])
def test_kcs_ship_reproduces_simulate(effects):
    """The stepping simulator (closed loop) and the kernel (open loop) are two copies of the servo
    path: the same trajectory, with and without every servo effect."""
    cfg = dataclasses.replace(CLEAN, **effects)
    run = tank.simulate(tank.turning_circle(35, "port", duration=20), cfg)
    ship = tank.KCSShip(cfg)
    st = ship.reset()
    assert st["u"] == CLEAN.approach_speed and st["psi"] == 0 and st["delta"] == 0
    rows = [st] + [ship.step(-35.0, 0.08) for _ in range(len(run.frame) - 1)]
    for c in ("psi", "r", "u", "v", "x0", "y0", "delta"):
        np.testing.assert_allclose([s[c] for s in rows], run.col(c), atol=1e-8, err_msg=c)
    assert rows[-1]["time"] == pytest.approx(run.col("time")[-1])


def test_kcs_ship_disturbance_acts_as_rudder():
    a, b = tank.KCSShip(CLEAN), tank.KCSShip(CLEAN)
    for _ in range(100):
        sa = a.step(0.0, 0.08, disturbance_deg=3.0)
        sb = b.step(3.0, 0.08)
    assert sa["delta"] == 0.0 and sb["delta"] == pytest.approx(3.0)
    assert sa["psi"] > 5                                            # it turned
    assert sa["psi"] == pytest.approx(sb["psi"], abs=0.3)            # only the servo ramp differs


# ------------------------------------------------------------------ noise, metadata, CSV, CLI

def test_noise_is_seeded_reproducible_and_of_the_configured_size(noisy_runs, clean_runs):
    stem = "kcs_zigzag_20_20_S"
    again = tank.simulate(tank.zigzag(20, 20), TankConfig())
    assert noisy_runs[stem].frame.equals(again.frame)
    other = tank.simulate(tank.zigzag(20, 20), dataclasses.replace(TankConfig(), seed=1))
    assert not np.allclose(other.col("psi"), again.col("psi"))
    # noise of the stated size (first 4 s, before any counter-rudder decision can differ)
    n = 50
    cfg = TankConfig()
    for c, sd in (("psi", cfg.noise_psi), ("r", cfg.noise_r), ("u", cfg.noise_u), ("v", cfg.noise_v),
                  ("x0", cfg.noise_xy), ("delta", cfg.noise_delta)):
        e = noisy_runs[stem].col(c)[:n] - clean_runs[stem].col(c)[:n]
        assert np.std(e) == pytest.approx(sd, rel=0.35), c
    # different runs get different noise seeds, derived from the seed and the name
    assert noisy_runs[stem].meta["noise_seed"] != noisy_runs["kcs_zigzag_20_20_P"].meta["noise_seed"]
    assert noisy_runs[stem].meta["noise_seed"] == tank.noise_seed(cfg.seed, "zigzag 20/20 starboard")


def test_metadata(noisy_runs):
    run = noisy_runs["kcs_zigzag_20_20_S"]
    m = run.meta
    assert m["provenance"] == "virtual" and run.is_virtual
    assert m["test_name"] == "zigzag 20/20 starboard" and m["ship"] == "KCS"
    assert m["lpp"] == 6.0702 and m["model_scale"] == 37.89 and m["dt"] == 0.08
    assert m["seed"] == TankConfig().seed
    assert m["effects"] == {"rudder_offset": 0.0, "rudder_delay": 0.0, "extra_yaw_damping": 0.0,
                            "hold_speed": False}
    assert parse_test_name(m["test_name"]) == {"kind": "zigzag", "rudder_deg": 20.0, "heading_deg": 20.0,
                                               "first_side": "starboard"}
    assert parse_test_name(tank.turning_circle(35, "port").test_name)["first_side"] == "port"
    assert list(run.frame.columns) == list(CANONICAL_COLUMNS)
    np.testing.assert_allclose(np.diff(run.col("time")), 0.08, atol=1e-12)


def test_csv_layout_and_values(tmp_path, noisy_runs):
    run = noisy_runs["kcs_zigzag_20_20_S"]
    path = tank.write_csv(tmp_path / "kcs_zigzag_20_20_S.csv", run)
    lines = path.read_text().splitlines()
    assert lines[:8] == [
        "# ship: KCS", "# provenance: virtual", "# test: zigzag 20/20 starboard", "# lpp: 6.0702",
        "# scale: 37.89", "# dt: 0.08", f"# seed: {TankConfig().seed}",
        "# note: virtual tank (MMG model of the KCS, SIMMAN 2020 model scale); not measured data"]
    assert lines[8] == "time,x0,y0,psi,u,v,r,delta,rpm"
    assert lines[9].startswith("0.000,")
    data = np.loadtxt(path, delimiter=",", comments="#", skiprows=9)
    assert data.shape == (len(run.frame), 9)
    expect = run.frame[list(CANONICAL_COLUMNS)].to_numpy()
    np.testing.assert_allclose(data[:, :8], expect[:, :8], atol=6e-5)     # 4-5 decimals written
    np.testing.assert_allclose(data[:, 8], expect[:, 8], atol=6e-3)       # rpm with 2 decimals
    assert [p.name for p in tmp_path.iterdir()] == ["kcs_zigzag_20_20_S.csv"]    # no temp file left


def test_csv_note_names_injected_effects(tmp_path):
    run = tank.simulate(tank.straight(2.0), dataclasses.replace(CLEAN, rudder_offset=1.5))
    text = tank.write_csv(tmp_path / "x.csv", run).read_text()
    assert "injected effects: rudder_offset=1.5" in text and "noise-free" in text


def test_pull_out_returns_the_rudder_and_the_turn_decays():
    """A turning circle with a pull-out (IMO MSC/Circ.1053): the rudder is commanded back to midships
    at pull_out_s, the servo gets there at its rate, and the yaw rate decays.  Decay: the KCS's slow yaw
    pole is about -0.05 1/s, so 60 s after a starboard pull-out a linear decay leaves e^-3 = 5 % of the
    steady rate; less than 10 % is asserted.  (To port the default KCS decays more slowly, -0.42 deg/s
    left 160 s after a 20 deg pull-out, measured: its propeller asymmetry, the residual turn the
    pull-out test is made to show.)  The title still parses as a turning circle of its rudder angle,
    and the indices find the pull-out where it was made."""
    m = tank.turning_circle(20, "starboard", duration=100.0, pull_out_s=40.0)
    assert m.test_name == "turning circle 20 starboard with pull-out"
    assert m.file_stem == "kcs_turning_20_S_pullout40"
    assert parse_test_name(m.test_name) == {"kind": "turning", "rudder_deg": 20.0, "heading_deg": None,
                                            "first_side": "starboard"}
    run = tank.simulate(m, CLEAN)
    t, d, r = run.col("time"), run.col("delta"), run.col("r")
    assert run.meta["pull_out_s"] == 40.0
    ramp = 20.0 / CLEAN.rudder_rate                                   # s, the servo from 20 deg to 0
    assert np.all(np.abs(d[(t > 10.0) & (t < 40.0)] - 20.0) < 1e-6)    # held until the pull-out
    assert abs(d[np.searchsorted(t, 40.0 + ramp + 0.2)]) < 1e-6        # amidships after the ramp
    steady = float(np.mean(r[(t > 30.0) & (t < 40.0)]))
    assert steady > 3.0                                                # turning to starboard (deg/s)
    assert abs(r[-1]) < 0.1 * steady
    from pipeline.indices.turning import turning_metrics
    # the indices date the pull-out where the rudder has left half its plateau: half the ramp later
    assert turning_metrics(run)["pull_out_s"] == pytest.approx(40.0 + ramp / 2, abs=2 * CLEAN.log_dt)
    # without a pull-out the rudder stays where it was put
    plain = tank.simulate(tank.turning_circle(20, "starboard", duration=100.0), CLEAN)
    assert "pull_out_s" not in plain.meta and plain.frame["delta"].iloc[-1] == pytest.approx(20.0)


def test_bad_manoeuvres_are_refused():
    for call in (lambda: tank.zigzag(-10, 10), lambda: tank.zigzag(10, 0),
                 lambda: tank.zigzag(10, 10, "left"), lambda: tank.turning_circle(35, duration=-1),
                 lambda: tank.turning_circle(float("nan")),
                 lambda: tank.turning_circle(35, duration=60.0, pull_out_s=60.0),
                 lambda: tank.turning_circle(35, duration=60.0, pull_out_s=-1.0)):
        with pytest.raises(InputError):
            call()
    for bad in ({"rudder_delay": -0.1}, {"rudder_rate": 0.0}, {"approach_speed": -2.0}, {"rudder_lag": -1.0},
                {"rudder_asymmetry": 1.0}, {"rudder_stall_deg": -5.0}):
        with pytest.raises(InputError, match=next(iter(bad))):
            tank.simulate(tank.straight(1.0), dataclasses.replace(CLEAN, **bad))


def test_cli_writes_pull_outs_and_refuses_one_outside_the_record(tmp_path, capsys):
    out = tmp_path / "raw"
    assert main(["tank", "--out", str(out), "--no-noise", "--pull-out", "45"]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert "kcs_turning_35_S_pullout45.csv" in names and "kcs_turning_35_P_pullout45.csv" in names
    assert "kcs_turning_25_S_pullout45.csv" in names
    assert "kcs_zigzag_20_20_S.csv" in names and len(names) == 9
    text = (out / "kcs_turning_35_S_pullout45.csv").read_text()
    assert "# test: turning circle 35 starboard with pull-out" in text
    delta = np.loadtxt([ln for ln in text.splitlines() if ln and ln[0].isdigit()], delimiter=",")[:, 7]
    assert delta[-1] == pytest.approx(0.0, abs=1e-3) and delta.max() == pytest.approx(35.0, abs=1e-3)
    bad = tmp_path / "bad"
    capsys.readouterr()
    assert main(["tank", "--out", str(bad), "--pull-out", "120"]) != 0
    err = capsys.readouterr().err
    assert "pull-out time must be inside the record (0, 90) s" in err, err
    assert len(err.strip().splitlines()) == 1, err
    assert not bad.exists() or not any(bad.iterdir())       # refused before anything is written


def test_cli_writes_the_default_set(tmp_path, capsys):
    out = tmp_path / "raw"
    assert main(["tank", "--out", str(out), "--no-noise", "--seed", "5"]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(["kcs_zigzag_20_20_S.csv", "kcs_zigzag_20_20_P.csv", "kcs_zigzag_10_10_S.csv",
                            "kcs_zigzag_10_10_P.csv", "kcs_turning_35_S.csv", "kcs_turning_35_P.csv",
                            "kcs_zigzag_15_15_S.csv", "kcs_zigzag_15_15_P.csv", "kcs_turning_25_S.csv"])
    text = (out / "kcs_turning_35_P.csv").read_text()
    assert "# test: turning circle 35 port" in text and "# seed: 5" in text and "noise-free" in text


def test_the_default_set_is_six_selection_runs_and_three_test_runs():
    """The diagnosis's design rule (pipeline.diagnose.design) on the tank's default runs: the 20/20 and
    10/10 zigzags and the 35 deg circles are crossed twins (one of each trains, one validates), the
    15/15 zigzags and the 25 deg circle are test runs, and the circle alone is named extrapolated (no
    selection circle at 25 deg)."""
    from pipeline.diagnose.design import extrapolated, pick_catalog_runs

    entries = [{"run_id": m.file_stem, "kind": m.kind, "rudder_deg": m.rudder_deg,
                "heading_deg": m.heading_deg, "first_side": m.side} for m in tank.default_set()]
    train, val, test = pick_catalog_runs(entries)
    assert sorted(train + val) == sorted(m.file_stem for m in tank.selection_set())
    assert sorted(test) == sorted(m.file_stem for m in tank.held_out_set())
    assert sorted(test) == ["kcs_turning_25_S", "kcs_zigzag_15_15_P", "kcs_zigzag_15_15_S"]
    for a, b in (("kcs_zigzag_20_20_S", "kcs_zigzag_20_20_P"), ("kcs_zigzag_10_10_S", "kcs_zigzag_10_10_P"),
                 ("kcs_turning_35_S", "kcs_turning_35_P")):
        assert (a in train) != (b in train) and (a in val) != (b in val)
    assert extrapolated(entries, train + val, test) == ["kcs_turning_25_S"]


# ---------------------------------------------------------------- sizing injected effects


def test_extra_damping_for_cut_gives_that_cut():
    from pipeline.tank.effects import extra_damping_for_cut, yaw_rate_amplitude_20_20

    cfg = dataclasses.replace(TankConfig(), hold_speed=True)
    extra = extra_damping_for_cut(0.25, cfg)
    assert extra < 0.0
    amp0 = yaw_rate_amplitude_20_20(cfg)
    amp = yaw_rate_amplitude_20_20(dataclasses.replace(cfg, extra_yaw_damping=extra))
    assert 1.0 - amp / amp0 == pytest.approx(0.25, abs=1e-4)
    with pytest.raises(ValueError, match="cut must be a fraction"):
        extra_damping_for_cut(1.5, cfg)


def test_n_rrr_equivalent_is_cubic_linear_and_matches_the_mmg_formula():
    """The injected N'_rrr in the diagnosis's units: independent of r (exactly cubic at zero drift),
    linear in N'_rrr, negative for more damping, and equal to the hand-derived
    (M^-1)_rr (rho/2) L^2 d U^2 N'_rrr (L/U)^3 (pi/180)^2 with the tank's mass matrix."""
    import math

    from pipeline.tank import kcs
    from pipeline.tank.effects import n_rrr_equivalent

    cfg = dataclasses.replace(TankConfig(), hold_speed=True)
    n1 = n_rrr_equivalent(-0.2, cfg)
    assert n1 < 0.0
    assert n_rrr_equivalent(-0.2, cfg, r_deg_s=4.0) == pytest.approx(n1, rel=1e-9)
    assert n_rrr_equivalent(-0.4, cfg) == pytest.approx(2.0 * n1, rel=1e-9)
    c = tank.KCSCoefficients()
    p = kcs.param_vector(cfg, c, kcs.trim_rps(cfg, c))
    m, my, iz, xg = p[kcs.I_M], p[kcs.I_MY], p[kcs.I_IZ], p[kcs.I_XG]
    inv_rr = (m + my) / ((m + my) * iz - (xg * m) ** 2)
    L, d, U = cfg.lpp, c.draft, cfg.approach_speed
    expected = inv_rr * 0.5 * c.rho * L**2 * d * U**2 * -0.2 * (L / U) ** 3 * (math.pi / 180.0) ** 2
    assert n1 == pytest.approx(expected, rel=1e-6)
