"""CGSA autopilot: design identities, loop figures, disturbances, limits, metrics, the stage."""

from __future__ import annotations

import math
from dataclasses import replace

import control as ct
import numpy as np
import pytest
from scipy import optimize, signal

from pipeline.cli import main
from pipeline.config import ControlConfig
from pipeline.control.design import (
    design_first_order,
    design_second_order,
    is_proper,
    loop_analysis,
    nomoto_tf,
    open_loop,
    setpoint_response_tf,
)
from pipeline.control.disturbance import (
    wave_filter,
    wave_sequence,
    wave_variance_discrete,
    wave_variance_theory,
    wind_equivalent_rudder,
    wind_from_config,
)
from pipeline.control.metrics import course_metrics, rudder_reversals, seed_statistics
from pipeline.control.simulate import NomotoShip, make_kcs_ship, simulate_course
from pipeline.control.stage import run_control
from pipeline.errors import InputError, ModelError
from pipeline.io import read_frame, read_json, write_json
from pipeline.model import PAPER_GRAPHICAL, PAPER_TABLE7

K, T, TW = PAPER_TABLE7["K"], PAPER_TABLE7["T"], 3.0
T1, T2, T3 = PAPER_TABLE7["T1"], PAPER_TABLE7["T2"], PAPER_TABLE7["T3"]


def _indices(provenance="measured", builtin_tank=None):
    """Indices of a dataset; ``builtin_tank`` (default: provenance virtual) as the indices stage
    writes it (pipeline.catalog.is_builtin_tank)."""
    builtin = provenance == "virtual" if builtin_tank is None else builtin_tank
    return {"dataset": "t", "provenance": provenance, "builtin_tank": builtin,
            "control_model": {"source": "test", **PAPER_TABLE7},
            "graphical_model": {"source": "test", **PAPER_GRAPHICAL}}


FAST = replace(ControlConfig(), seeds=2, duration=60.0, steady_start=40.0, bode_points=20)


# ------------------------------------------------------------------------------------------ design
def test_first_order_gains():
    d = design_first_order(K, T, TW)
    assert d.Kp == pytest.approx(1 / (K * TW), rel=1e-15)
    assert d.Kd == pytest.approx(T / (K * TW), rel=1e-15)


def test_first_order_closed_loop_is_exactly_first_order():
    """CGSA target: L/(1+L) on the design model = 1/(Tw s + 1), step response 1 - exp(-t/Tw)."""
    d = design_first_order(K, T, TW)
    tcl = setpoint_response_tf(d, derivative_on="error")
    num = np.trim_zeros(np.asarray(tcl.num[0][0], float), "f")
    den = np.trim_zeros(np.asarray(tcl.den[0][0], float), "f")
    assert num.size == 1 and den.size == 2
    np.testing.assert_allclose(np.r_[num, den] / den[-1], [1.0, TW, 1.0], rtol=1e-12)
    t = np.linspace(0, 30, 601)
    y = ct.step_response(tcl, t).outputs
    np.testing.assert_allclose(y, 1 - np.exp(-t / TW), atol=1e-10)
    # The loop is the pure integrator 1/(Tw s): crossover 1/Tw, PM 90 deg, bandwidth 1/Tw, Ms 1.
    la = loop_analysis(open_loop(d))
    assert la["gain_crossover"] == pytest.approx(1 / TW, rel=1e-9)
    assert la["phase_margin_deg"] == pytest.approx(90.0, abs=1e-9)
    assert la["bandwidth"] == pytest.approx(1 / TW, rel=1e-6)
    assert la["gain_margin"] == math.inf
    assert la["Ms"] == pytest.approx(1.0, abs=1e-6)


def test_no_kick_setpoint_response_is_two_lags():
    """Derivative on the measured rate: set point -> psi = 1/((T s + 1)(Tw s + 1)) exactly."""
    d = design_first_order(K, T, TW)
    t = np.linspace(0, 40, 801)
    y = ct.step_response(setpoint_response_tf(d), t).outputs
    expected = 1 - (T * np.exp(-t / T) - TW * np.exp(-t / TW)) / (T - TW)
    np.testing.assert_allclose(y, expected, atol=1e-10)


@pytest.mark.parametrize("dt", [0.02, 0.01])
def test_simulator_matches_continuous_without_limits(dt):
    """Sampled loop, no limits, no disturbance, first-order plant -> continuous answer to O(dt)."""
    d = design_first_order(K, T, TW)
    ship = NomotoShip(K, T, rudder_max=None, rudder_rate=None)
    fr = simulate_course(d, ship, setpoint=10.0, duration=30.0, dt=dt, rudder_max=None)
    t = fr["time"].to_numpy()
    expected = 10 * (1 - (T * np.exp(-t / T) - TW * np.exp(-t / TW)) / (T - TW))
    err = np.max(np.abs(fr["psi"].to_numpy() - expected))
    assert err < 2.0 * dt                      # deg, first-order convergence in dt for a 10 deg step
    assert err > 0.05 * dt                     # and it really is a sampled loop (not a copy of the formula)


def test_margins_of_a_hand_computed_loop():
    """L = k/(s (s+1)^2): phase -180 deg at w = 1, |L(j1)| = k/2 -> GM = 2/k."""
    k = 0.5
    loop = ct.tf([k], np.polymul([1, 0], np.polymul([1, 1], [1, 1])))
    la = loop_analysis(loop)
    assert la["phase_crossover"] == pytest.approx(1.0, rel=1e-6)
    assert la["gain_margin"] == pytest.approx(2 / k, rel=1e-6)
    wc = optimize.brentq(lambda w: k / (w * (1 + w * w)) - 1, 1e-3, 10)
    assert la["gain_crossover"] == pytest.approx(wc, rel=1e-6)
    assert la["phase_margin_deg"] == pytest.approx(90 - 2 * math.degrees(math.atan(wc)), abs=1e-6)
    res = optimize.minimize_scalar(lambda w: abs(1 + k / (1j * w * (1 + 1j * w) ** 2)),
                                   bounds=(0.1, 3), method="bounded", options={"xatol": 1e-10})
    assert la["Ms"] == pytest.approx(1 / res.fun, rel=1e-3)
    assert la["stable"]
    assert not loop_analysis(ct.tf([3.0], np.polymul([1, 0], np.polymul([1, 1], [1, 1]))))["stable"]


def test_second_order_design_is_proper_and_shapes_the_loop():
    tf_ = 0.3
    d = design_second_order(K, T1, T2, T3, TW, tf_)
    assert is_proper(d.controller)
    hnum = np.trim_zeros(np.asarray(d.rate_filter.num[0][0], float), "f")
    hden = np.trim_zeros(np.asarray(d.rate_filter.den[0][0], float), "f")
    assert hnum.size < hden.size                                   # H strictly proper
    s = np.array([0.01j, 0.3j, 2j, 10j, 0.5 + 1j])
    # Feedback path Kp + s H(s) is exactly Kc_f(s).
    np.testing.assert_allclose(d.Kp + s * d.rate_filter(s), d.controller(s), rtol=1e-12)
    # On its own model L = 1/(Tw s (Tf s + 1)).
    loop = open_loop(d)
    np.testing.assert_allclose(loop(s), 1 / (TW * s * (tf_ * s + 1)), rtol=1e-9)
    # Hand-computed crossover and phase margin of that loop.
    x = (-TW ** 2 + math.sqrt(TW ** 4 + 4 * tf_ ** 2 * TW ** 2)) / (2 * tf_ ** 2 * TW ** 2)
    wc = math.sqrt(x)
    la = loop_analysis(loop)
    assert la["gain_crossover"] == pytest.approx(wc, rel=1e-6)
    assert la["phase_margin_deg"] == pytest.approx(90 - math.degrees(math.atan(wc * tf_)), abs=1e-6)
    # As the filter pole goes to zero the controller tends to the ideal Kc at a fixed frequency.
    ideal = (1 + T1 * 0.3j) * (1 + T2 * 0.3j) / (K * TW * (1 + T3 * 0.3j))
    err = [abs(design_second_order(K, T1, T2, T3, TW, f).controller(0.3j) - ideal)
           for f in (0.1, 0.01, 0.001)]
    assert err[0] > err[1] > err[2] and err[2] < 1e-3 * abs(ideal)


@pytest.mark.parametrize("bad", [dict(K=0.0), dict(K=-1.0), dict(T=0.0), dict(T=-2.0), dict(Tw=0.0),
                                 dict(Tw=-3.0), dict(K=float("nan"))])
def test_bad_design_inputs_raise_model_error(bad):
    args = {"K": K, "T": T, "Tw": TW, **bad}
    with pytest.raises(ModelError):
        design_first_order(args["K"], args["T"], args["Tw"])


def test_bad_second_order_inputs_raise_model_error():
    with pytest.raises(ModelError):
        design_second_order(K, T1, T2, T3, TW, 0.0)
    with pytest.raises(ModelError):
        design_second_order(K, -T1, T2, T3, TW, 0.3)
    with pytest.raises(ModelError):
        nomoto_tf(K, T1=T1, T2=T2, T3=float("nan"))


# ------------------------------------------------------------------------------------- disturbance
def test_wave_variance_matches_theory():
    """Seeded sample variance within 4 standard errors of the exact discrete variance.

    Standard error from Bartlett's formula var(s^2) ~ (2 sigma^4 / N) sum_k rho_k^2, with rho_k the
    exact autocorrelation of the discretised filter (A^k P C^T); and the exact discrete variance
    itself is within 0.5 % of the continuous b^2/(2 a1) at dt = 0.08 s.
    """
    dt, n = 0.08, 60000
    theory = 0.2386 ** 2 / (2 * 0.3593)
    assert wave_variance_theory() == pytest.approx(theory, rel=1e-10)
    vd = wave_variance_discrete(dt)
    assert vd == pytest.approx(theory, rel=5e-3)
    sysd = wave_filter((0.2386, 0.0), (1.0, 0.3593, 0.8067), dt)
    a, b, c = (np.asarray(m, float) for m in (sysd.A, sysd.B, sysd.C))
    p = ct.dlyap(a, b @ b.T / dt)
    rho, ak = [], np.eye(a.shape[0])
    for _ in range(2000):
        rho.append(float((c @ ak @ p @ c.T)[0, 0]) / vd)
        ak = a @ ak
    se = vd * math.sqrt(2.0 / n * (2 * np.sum(np.square(rho)) - 1))
    x = wave_sequence(n + 500, dt, seed=12345)[500:]              # drop the start-up transient
    assert abs(x.var() - vd) < 4 * se
    assert se < 0.05 * vd                                          # the test can actually resolve 5 %


def test_wave_spectrum_matches_filter():
    """Welch PSD averaged over bands vs 2 |G(j 2 pi f)|^2 (one-sided, unit white noise), within 10 %."""
    dt = 0.08
    x = wave_sequence(100000, dt, seed=99)
    f, pxx = signal.welch(x, fs=1 / dt, nperseg=2048)
    w = 2 * np.pi * f
    g2 = np.abs(0.2386 * 1j * w / (-(w ** 2) + 0.3593j * w + 0.8067)) ** 2
    for lo, hi in [(0.05, 0.1), (0.1, 0.2), (0.2, 0.4)]:
        m = (f >= lo) & (f < hi)
        assert np.mean(pxx[m]) == pytest.approx(np.mean(2 * g2[m]), rel=0.10)


def test_wave_seeded_and_filter_checks():
    a = wave_sequence(500, 0.08, 3)
    np.testing.assert_array_equal(a, wave_sequence(500, 0.08, 3))
    assert not np.array_equal(a, wave_sequence(500, 0.08, 4))
    with pytest.raises(ModelError):
        wave_filter((1.0,), (1.0, -0.1, 1.0), 0.08)                # unstable
    with pytest.raises(ModelError):
        wave_filter((1.0,), (1.0, 1.0), 0.0)


def test_wind_equation_14_form():
    assert wind_equivalent_rudder(0.8, 1.5, 30.0) == pytest.approx(0.8 * 2.25 * 0.5, rel=1e-12)
    assert wind_from_config(ControlConfig()) == 2.0
    cfg = replace(ControlConfig(), wind_model="eq14", wind_kw=1.0, wind_speed_ratio=2.0, wind_angle=90.0)
    assert wind_from_config(cfg) == pytest.approx(4.0)
    with pytest.raises(ModelError):
        wind_equivalent_rudder(1.2, 1.0, 90.0)
    with pytest.raises(ModelError):
        wind_from_config(replace(ControlConfig(), wind_model="gusty"))


# ------------------------------------------------------------------------------------ limits
def _check_limits(fr, dt, dmax=35.0, rate=14.28):
    d = fr["delta"].to_numpy()
    assert np.max(np.abs(d)) <= dmax + 1e-9
    steps = np.abs(np.diff(np.r_[0.0, d]))
    assert np.max(steps) <= rate * dt + 1e-9
    return d, steps


def test_rudder_saturation_and_rate_limit_nomoto():
    d = design_first_order(K, T, TW)
    ship = NomotoShip(K, T1, T2, T3, rudder_max=35.0, rudder_rate=14.28)
    fr = simulate_course(d, ship, setpoint=60.0, duration=40.0, dt=0.08, wind=2.0,
                         wave=wave_sequence(501, 0.08, 1))
    delta, steps = _check_limits(fr, 0.08)
    assert np.max(fr["delta_cmd"].abs()) == pytest.approx(35.0)     # command saturated
    assert np.max(steps) == pytest.approx(14.28 * 0.08)              # rate limit reached
    # Without limits the same loop asks for far more rudder.
    free = simulate_course(d, NomotoShip(K, T1, T2, T3, rudder_max=None, rudder_rate=None),
                           setpoint=60.0, duration=40.0, dt=0.08, rudder_max=None)
    assert np.max(np.abs(free["delta"])) > 50


def test_rudder_limits_kcs():
    d = design_first_order(K, T, TW)
    fr = simulate_course(d, make_kcs_ship(35.0, 14.28), setpoint=60.0, duration=20.0, dt=0.08, wind=2.0)
    _check_limits(fr, 0.08)
    assert fr["psi"].iloc[-1] > 30                                     # it does turn toward the set course


# ------------------------------------------------------------------------------------ metrics
def test_metrics_on_exponential_course():
    dt, tau = 0.01, 5.0
    t = np.arange(0, 150 + dt / 2, dt)
    psi = 60 * (1 - np.exp(-t / tau))                                   # 1 - exp(-30) < 1 in float64
    delta = np.where(t >= 100, -2.0, 10.0)
    m = course_metrics(t, psi, delta, 60.0, band=0.05, steady_start=100.0)
    assert m["rise_time"] == pytest.approx(tau * math.log(20), abs=dt)
    assert m["rise_time_10_90"] == pytest.approx(tau * math.log(9), abs=2 * dt)
    assert math.isnan(m["reach_time"])                                  # never quite reaches 60
    assert m["max_deviation"] == pytest.approx(3.0, abs=1e-3)          # so from the rise time: 5 % of 60
    assert m["steady_mae"] == pytest.approx(60 * np.mean(np.exp(-t[t >= 100] / tau)), rel=1e-9)
    assert m["max_rudder"] == 10.0
    assert m["steady_rudder_min"] == m["steady_rudder_max"] == m["mean_rudder"] == -2.0
    assert m["rudder_energy"] == pytest.approx(4.0 * 50.0, rel=1e-3)
    assert m["rudder_reversals"] == 0


def test_metrics_on_oscillating_course():
    dt = 0.05
    t = np.arange(0, 200, dt)
    psi = np.where(t < 10, 6 * t, 60 + 1.5 * np.sin(2 * np.pi * t / 20))    # period 20 s
    delta = np.where(t < 10, 20.0, -1.7 + 2 * np.sin(2 * np.pi * t / 10))   # period 10 s
    m = course_metrics(t, psi, delta, 60.0, steady_start=100.0)
    assert m["rise_time"] == pytest.approx(9.5, abs=dt)                     # 6 t = 57
    assert m["reach_time"] == pytest.approx(10.0, abs=dt)
    assert m["max_deviation"] == pytest.approx(1.5, abs=1e-3)               # after reaching: the swell
    assert m["steady_mae"] == pytest.approx(1.5 * 2 / np.pi, rel=1e-3)     # mean |sin| = 2/pi
    assert m["steady_rudder_min"] == pytest.approx(-3.7, abs=1e-3)
    assert m["steady_rudder_max"] == pytest.approx(0.3, abs=1e-3)
    assert m["mean_rudder"] == pytest.approx(-1.7, abs=1e-3)
    assert m["rudder_reversals"] == 20                  # 10 periods x 2 extremes in [100, 200)


def test_reversals_hysteresis_and_errors():
    tri = np.r_[np.linspace(0, 1, 11), np.linspace(1, -1, 21)[1:], np.linspace(-1, 1, 21)[1:]]
    assert rudder_reversals(tri, 0.1) == 2
    assert rudder_reversals(tri * 0.04, 0.1) == 0                          # swings below the threshold
    with pytest.raises(InputError):
        rudder_reversals(tri, 0.0)
    with pytest.raises(InputError):
        course_metrics([0, 1, 2], [0, np.nan, 1], [0, 0, 0], 1.0, steady_start=0)
    with pytest.raises(InputError):
        course_metrics([0, 1, 2], [0, 1, 1], [0, 0], 1.0, steady_start=0)
    with pytest.raises(InputError):
        course_metrics([0, 1, 2], [0, 1, 1], [0, 0, 0], 1.0, steady_start=5)


def test_seed_statistics_worst_direction():
    rows = [{"rise_time": 10.0, "steady_rudder_min": -3.0, "mean_rudder": -1.0},
            {"rise_time": 12.0, "steady_rudder_min": -4.0, "mean_rudder": -2.5},
            {"rise_time": 11.0, "steady_rudder_min": -2.0, "mean_rudder": 1.0}]
    s = seed_statistics(rows)
    assert s["rise_time"]["mean"] == pytest.approx(11.0) and s["rise_time"]["std"] == pytest.approx(1.0)
    assert s["rise_time"]["worst"] == 12.0
    assert s["steady_rudder_min"]["worst"] == -4.0
    assert s["mean_rudder"]["worst"] == -2.5


# ------------------------------------------------------------------------------------- stage
def test_run_control_reproducible_and_paired():
    doc1, ts1 = run_control(_indices(), FAST, progress=False)
    doc2, ts2 = run_control(_indices(), FAST, progress=False)
    assert ts1.equals(ts2)
    assert doc1["seeds"] == doc2["seeds"] and len(doc1["seeds"]) == 2
    _, ts3 = run_control(_indices(), replace(FAST, seed=FAST.seed + 1), progress=False)
    assert not np.array_equal(ts1["wave"].to_numpy(), ts3["wave"].to_numpy())
    # Every design on a plant sees the same waves for a given seed (paired comparison).
    w = ts1[ts1.plant == "nomoto"].pivot_table(index=["seed", "time"], columns="design", values="wave")
    assert np.all((w.max(axis=1) - w.min(axis=1)).to_numpy() == 0)
    assert set(ts1.columns) == {"plant", "design", "seed", "time", "psi_ref", "psi", "r", "delta_cmd",
                                "delta", "wave", "wind"}
    assert set(doc1["designs"]) == {"identified", "identified-2nd", "graphical", "autopilot"}
    assert doc1["plants"]["kcs"]["used"] is False                        # measured provenance
    diff = doc1["identification_value"]["nomoto"]["metrics"]["rise_time"]["mean"]
    res = {(r["plant"], r["design"]): r for r in doc1["results"]}
    assert diff == pytest.approx(res[("nomoto", "identified")]["stats"]["rise_time"]["mean"]
                                 - res[("nomoto", "graphical")]["stats"]["rise_time"]["mean"])


def test_run_control_bad_indices():
    bad = _indices()
    del bad["control_model"]["T1"]
    with pytest.raises(InputError, match="control_model.T1"):
        run_control(bad, FAST, progress=False)
    bad = _indices()
    bad["control_model"]["K"] = -0.4
    with pytest.raises(ModelError):
        run_control(bad, FAST, progress=False)


@pytest.mark.slow
def test_cli_writes_outputs_and_refuses_bad_input(tmp_path, capsys):
    base = tmp_path / "proc" / "t"
    write_json(base / "indices" / "indices.json", _indices("virtual"))
    rc = main(["control", "--root", str(tmp_path / "proc"), "--dataset", "t", "--seeds", "2",
               "--no-progress", "--plants", "nomoto"])
    assert rc == 0
    m = read_json(base / "control" / "metrics.json")
    ts, meta = read_frame(base / "control" / "timeseries.parquet")
    assert m["virtual"] is True and meta["provenance"] == "virtual"
    assert {r["design"] for r in m["results"]} == {"identified", "identified-2nd", "graphical", "autopilot"}
    assert ts["seed"].nunique() == 2
    before = (base / "control" / "metrics.json").read_bytes()
    out = capsys.readouterr()                    # no dataset.toml: one notice of the assumed steering gear
    assert sum("does not give" in line for line in out.err.splitlines()) == 1
    # Bad indices: exit 2, one line, earlier outputs untouched.
    write_json(base / "indices" / "indices.json", {"provenance": "measured", "control_model": {"K": 1}})
    rc = main(["control", "--root", str(tmp_path / "proc"), "--dataset", "t", "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err and "indices.json" in err
    assert (base / "control" / "metrics.json").read_bytes() == before
    assert main(["control", "--root", str(tmp_path / "proc"), "--dataset", "absent", "--no-progress"]) == 2
    assert not (tmp_path / "proc" / "absent" / "control").exists()


def test_negative_t3_skips_second_order_design():
    idx = _indices()
    idx["control_model"] = {"source": "test", "K": 0.4, "T1": 4.0, "T2": 0.4, "T3": -0.2, "T": 4.6}
    doc, ts = run_control(idx, replace(FAST, seeds=1), progress=False)
    assert set(doc["designs"]) == {"identified", "graphical", "autopilot"}
    assert any("second-order CGSA skipped" in n for n in doc["notes"])
    assert np.all(np.isfinite(ts["psi"]))


def test_virtual_dataset_uses_the_kcs_plant():
    doc, ts = run_control(_indices("virtual"), replace(FAST, seeds=1), progress=False)
    assert doc["virtual"] is True and doc["plants"]["kcs"]["used"] is True
    assert set(ts["plant"]) == {"nomoto", "kcs"}
    doc2, ts2 = run_control(_indices("measured"), replace(FAST, seeds=1), progress=False)
    assert set(ts2["plant"]) == {"nomoto"} and doc2["plants"]["kcs"]["used"] is False


def test_users_simulated_dataset_is_not_run_on_the_kcs():
    """A user's simulated runs of their own ship (provenance virtual, not the built-in tank's) are
    simulated data, but the KCS is not their ship: the autopilot runs on the identified Nomoto plant
    only, and the document says which (found 2026-11-26 on a bulk carrier's simulated zigzags)."""
    doc, ts = run_control(_indices("virtual", builtin_tank=False), replace(FAST, seeds=1), progress=False)
    assert set(ts["plant"]) == {"nomoto"} and doc["plants"]["kcs"]["used"] is False
    assert doc["virtual"] is True and doc["builtin_tank"] is False


def test_first_order_fallback_control_model():
    """indices falls back to the graphical first-order model as T1 = T, T2 = T3 = 0."""
    idx = _indices()
    idx["control_model"] = {"source": "fallback", "K": 0.576, "T1": 4.816, "T2": 0.0, "T3": 0.0, "T": 4.816}
    doc, ts = run_control(idx, replace(FAST, seeds=1), progress=False)
    assert set(doc["designs"]) == {"identified", "graphical", "autopilot"}
    assert any("first order" in n for n in doc["notes"])
    # Same model and same design: both loops are 1/(Tw s) exactly, and the runs coincide.
    assert doc["designs"]["identified"]["loop_nomoto_plant"]["phase_margin_deg"] == pytest.approx(90.0)
    a = ts[ts.design == "identified"]["psi"].to_numpy()
    b = ts[ts.design == "graphical"]["psi"].to_numpy()
    np.testing.assert_allclose(a, b, rtol=1e-12)


def test_kcs_available_only_for_an_absent_tank(monkeypatch):
    """Absent tank package: False.  A tank package that breaks on import: the error, not a skip."""
    import sys as _sys

    from pipeline.control import simulate as sim

    assert sim.kcs_available() is True
    monkeypatch.setitem(_sys.modules, "pipeline.tank", None)       # as if not installed
    assert sim.kcs_available() is False
    monkeypatch.undo()

    def broken():
        raise ModuleNotFoundError("No module named 'numba_missing'", name="numba_missing")

    monkeypatch.setattr(sim, "_kcs_class", broken)
    with pytest.raises(ModuleNotFoundError, match="numba_missing"):
        sim.kcs_available()
