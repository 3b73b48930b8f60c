"""The project's autopilot (PID + reference model), the sampled-loop margins, the [control] settings and
the design-model rule: known answers (docs/control.md)."""

from __future__ import annotations

from dataclasses import replace

import control as ct
import numpy as np
import pandas as pd
import pytest

from pipeline.config import ControlConfig
from pipeline.control.autopilot import PIDController, ReferenceModel, design_pid
from pipeline.control.design import design_first_order
from pipeline.control.robust import delay_steps, discrete_margins, loop_tf, sampled_margins, sampled_plant
from pipeline.control.robustness import step_figures
from pipeline.control.settings import apply, parse_control_table, read_dataset_control
from pipeline.control.simulate import NomotoShip, simulate_course
from pipeline.errors import InputError, ModelError
from pipeline.indices.design_model import choose_design_model, graphical_parameters
from pipeline.io import Run
from pipeline.model import simulate

K, T, TW, DT = 0.30, 3.9, 3.0, 0.08


# ------------------------------------------------------------------------- integral action, item 1
@pytest.mark.parametrize("wind", [2.0, -3.5])
def test_integrator_removes_a_constant_disturbance_and_a_pd_does_not(wind):
    """On the linear first-order model without limits, a constant equivalent wind rudder must be
    cancelled by a steady rudder of -wind.  A PD gets it only from a heading error wind/Kp (the steady
    balance K (delta + wind) = 0 with delta = Kp e); the PID's integrator takes the error to zero."""
    ship = NomotoShip(K, T, rudder_max=None, rudder_rate=None)
    pid = design_pid(K, T, TW, rudder_max=35.0)
    fr = simulate_course(pid, ship, setpoint=10.0, duration=900.0, dt=DT, rudder_max=None, wind=wind)
    assert abs(fr["psi"].iloc[-1] - 10.0) < 1e-6
    assert abs(fr["delta"].iloc[-1] + wind) < 1e-6
    pd_ = design_first_order(K, T, TW)
    fr = simulate_course(pd_, NomotoShip(K, T, rudder_max=None, rudder_rate=None), setpoint=10.0,
                         duration=900.0, dt=DT, rudder_max=None, wind=wind)
    assert fr["psi"].iloc[-1] - 10.0 == pytest.approx(wind / pd_.Kp, abs=1e-6)


def test_pole_placement_gains_give_the_placed_poles():
    """Without the integrator the loop of K/(s (T s + 1)) with delta = Kp e - Kd r has the double pole
    -wn (roots of T s^2 + (1 + K Kd) s + K Kp); the integrator adds a slow real pole, between wn/10
    and wn/5 for Ki = wn Kp / 10, and pulls nothing into the right half plane."""
    d = design_pid(K, T, TW, rudder_max=35.0)
    wn = 1 / TW
    two = np.roots([T, 1 + K * d.Kd, K * d.Kp])
    assert np.allclose(two, -wn, atol=1e-6)
    three = np.roots([T, 1 + K * d.Kd, K * d.Kp, K * d.Ki])
    assert np.all(three.real < 0)
    slow = three[np.argmin(np.abs(three))]
    assert abs(slow.imag) < 1e-9 and wn / 10 < -slow.real < wn / 5


def test_kd_clipped_for_a_ship_faster_than_the_loop():
    d = design_pid(K, 1.0, TW, rudder_max=35.0)          # 2 zeta wn T = 0.67 < 1
    assert d.Kd == 0.0 and d.kd_clipped
    with pytest.raises(ModelError):
        design_pid(-1.0, T, TW, rudder_max=35.0)


def test_conditional_integration_holds_the_integrator_in_saturation():
    d = design_pid(K, T, TW, rudder_max=35.0)
    c = PIDController(d, DT, rudder_max=5.0)
    for _ in range(200):                                 # far off course: saturated toward the error
        assert c.command(0.0, -80.0, 0.0) == 5.0
    assert c.z == 0.0 and c.saturated == 200
    c.command(0.0, 1.0, 0.0)                             # error now the other way: integrates
    assert c.z != 0.0


def test_anti_windup_limits_the_overshoot_after_a_saturated_turn():
    """With the rudder saturated for a long turn, a plain integrator winds up and overshoots; the
    conditional one does not wind (the same law with the hold switched off, by subclassing)."""

    class Plain(PIDController):
        def command(self, psi_ref, psi, r):
            d = self.design
            psi_d, r_d, a_d = self.ref.step(psi_ref, self.dt)
            e = psi_d - psi
            u = (d.T * a_d + r_d) / d.K + d.Kp * e + d.Kd * (r_d - r) + d.Ki * self.z
            self.z += self.dt * e
            return min(max(u, -self.rudder_max), self.rudder_max)

    d = replace(design_pid(K, T, TW, rudder_max=5.0), r_max=50.0)   # a reference faster than the ship

    def run(cls):
        ship = NomotoShip(K, T, rudder_max=5.0, rudder_rate=None)
        ctl, st = cls(d, DT, 5.0), ship.reset()
        psi = []
        for _ in range(int(300 / DT)):
            st = ship.step(ctl.command(90.0, st["psi"], st["r"]), DT)
            psi.append(st["psi"])
        return np.max(psi) - 90.0

    assert run(PIDController) < 0.5 * run(Plain)


def test_reference_model_follows_its_transfer_function_and_respects_the_rate_limit():
    wr, zr = 0.4, 1.0
    ref = ReferenceModel(wr, zr, r_max=1e9)
    out = np.array([ref.step(1.0, 0.01) for _ in range(3000)])
    t = np.arange(3000) * 0.01
    _, y = ct.step_response(ct.tf([wr ** 3], np.polymul([1, wr], [1, 2 * zr * wr, wr ** 2])), t)
    assert np.max(np.abs(out[:, 0] - y)) < 5e-3          # forward Euler at 0.01 s
    ref = ReferenceModel(wr, zr, r_max=2.0)
    out = np.array([ref.step(60.0, DT) for _ in range(2000)])
    assert np.max(np.abs(out[:, 1])) <= 2.0 + 1e-12
    assert out[-1, 0] == pytest.approx(60.0, abs=1e-3)


# ---------------------------------------------------------------------------- sampled margins, item 3
@pytest.mark.parametrize("nd", [0, 3, 7])
def test_margins_of_a_sampled_integrator_with_dead_time_by_hand(nd):
    """L(z) = Kp K h z^-nd/(z - 1) (a ZOH-sampled K/s with nd samples of dead time): with
    theta = w h, |L| = Kp K h / (2 sin(theta/2)) and arg L = -(pi/2 + theta/2 + nd theta), so
    theta_c = 2 asin(Kp K h / 2), PM = pi/2 - theta_c (nd + 1/2), the phase crossover at
    theta_pi = pi/(2 nd + 1) with GM = 2 sin(theta_pi/2)/(Kp K h), delay margin PM/(theta_c/h)."""
    kp, h = 1.2, DT
    loop = ct.tf([kp * K * h], [1.0, -1.0], h) * ct.tf([1.0], [1.0] + [0.0] * nd, h)
    m = discrete_margins(loop)
    th_c = 2 * np.arcsin(kp * K * h / 2)
    pm = np.pi / 2 - th_c * (nd + 0.5)
    th_pi = np.pi / (2 * nd + 1)
    assert m["phase_margin_deg"] == pytest.approx(np.degrees(pm), abs=1e-3)
    assert m["gain_crossover"] == pytest.approx(th_c / h, rel=1e-4)
    assert m["delay_margin_s"] == pytest.approx(pm / (th_c / h), rel=1e-4)
    assert m["gain_margin_db"] == pytest.approx(20 * np.log10(2 * np.sin(th_pi / 2) / (kp * K * h)), abs=1e-3)
    assert m["phase_crossover"] == pytest.approx(th_pi / h, rel=1e-3)
    assert m["stable"]


def test_delay_margin_is_where_the_sampled_loop_goes_unstable():
    """Adding whole samples of dead time to a CGSA loop on a first-order Nomoto model: stable below the
    computed delay margin, unstable above it (closed-loop poles, independent of the frequency grid)."""
    d = design_first_order(K, T, TW)
    dm = sampled_margins(d, K, T, 0.0, 0.0, DT)["delay_margin_s"]
    below, above = int(np.floor(dm / DT)) - 1, int(np.ceil(dm / DT)) + 1
    assert sampled_margins(d, K, T, 0.0, 0.0, DT, dead_time=below * DT)["stable"]
    assert not sampled_margins(d, K, T, 0.0, 0.0, DT, dead_time=above * DT)["stable"]
    assert delay_steps(0.5, DT) == 6


def test_servo_lag_and_dead_time_in_the_plant_match_the_simulator():
    """The sampled plant (python-control c2d) and NomotoShip's exact stepping agree sample by sample."""
    tau, dead = 0.4, 0.24
    plant = sampled_plant(K, 4.0, 1.0, 1.1, DT, servo_time_constant=tau, dead_time=dead)
    u = np.sin(np.arange(400) * 0.05) * 10
    _, y = ct.forced_response(plant, T=np.arange(400) * DT, U=u)
    ship = NomotoShip(K, 4.0, 1.0, 1.1, rudder_max=None, rudder_rate=None, servo_time_constant=tau,
                      dead_time=dead)
    ship.reset()
    psi = [0.0]
    for k in range(399):
        psi.append(ship.step(u[k], DT)["psi"])
    assert np.max(np.abs(np.asarray(psi) - y[0])) < 1e-9


def test_step_figures_on_a_known_response():
    t = np.arange(0, 100, 0.08)
    wn, z = 0.5, 0.5
    wd = wn * np.sqrt(1 - z ** 2)
    y = 10 * (1 - np.exp(-z * wn * t) * (np.cos(wd * t) + z / np.sqrt(1 - z ** 2) * np.sin(wd * t)))
    f = step_figures(t, y, 10.0, 0.02)
    assert f["overshoot_pct"] == pytest.approx(100 * np.exp(-z * np.pi / np.sqrt(1 - z ** 2)), rel=1e-3)
    assert 4 / (z * wn) * 0.8 < f["settling_time_s"] < 4 / (z * wn) * 1.2   # the 2 % rule of thumb


def test_loop_of_a_pid_on_the_design_model_is_stable_with_margins():
    d = design_pid(K, T, TW, rudder_max=35.0)
    m = sampled_margins(d, K, T, 0.0, 0.0, DT)
    assert m["stable"] and m["phase_margin_deg"] > 45 and m["sensitivity_peak"] < 1.5
    loop = loop_tf(d, sampled_plant(K, T, 0.0, 0.0, DT), DT)
    assert loop.dt == DT


# ----------------------------------------------------------------------------------- [control] table
def test_control_table_parsed_and_checked(tmp_path):
    assert parse_control_table({"tw_s": 5, "dead_time_s": 0.3}) == {"tw_s": 5.0, "dead_time_s": 0.3}
    for bad in ({"tw": 3}, {"tw_s": 0}, {"tw_s": "3"}, {"dead_time_s": -0.1}, {"rudder_max_deg": 95},
                {"setpoint_deg": 0}, {"tw_s": True}, {"rudder_rate_deg_s": float("inf")}):
        with pytest.raises(InputError):
            parse_control_table(bad, "dataset.toml")
    p = tmp_path / "dataset.toml"
    p.write_text('[ship]\nname = "KVLCC2"\n[control]\nrudder_rate_deg_s = 2.3\nbogus = 1\n')
    with pytest.raises(InputError, match="bogus"):
        read_dataset_control(p)
    p.write_text('[ship]\nname = "KVLCC2"\n[control]\nrudder_rate_deg_s = 2.3\n')
    cfg, notice = apply(ControlConfig(), read_dataset_control(p), "KVLCC2")
    assert cfg.rudder_rate == 2.3 and cfg.tw == ControlConfig().tw
    assert notice and "\n" not in notice and "KVLCC2" in notice and "tw_s" in notice
    assert apply(ControlConfig(), {}, "KCS")[1] is None
    assert read_dataset_control(tmp_path / "absent.toml") == {}


# ------------------------------------------------------------------------------- design-model rule
def _run(theta, name, seed):
    """A zigzag-like run from the six-parameter model, heading noise 0.05 deg."""
    n, h = 1500, DT
    t = np.arange(n) * h
    delta = 15 * np.sign(np.sin(2 * np.pi * t / 40.0))
    x = simulate(theta, [0.0, 0.0, 0.0], delta, h)
    rng = np.random.default_rng(seed)
    fr = pd.DataFrame({"time": t, "v": x[:, 0], "r": x[:, 1], "psi": x[:, 2] + rng.normal(0, 0.05, n),
                       "delta": delta})
    return Run(frame=fr, meta={"run_id": name, "dt": h})


def test_design_model_rule_picks_the_model_that_predicts_held_out_runs():
    """Runs made by a first-order Nomoto ship (K 0.3, T 3.9): the graphical model with those K, T is
    the truth; an 'identified' model with K 40 % high must lose, and one equal to the truth must not."""
    cfg = ControlConfig()
    truth = graphical_parameters(K, T)
    runs = [_run(truth, f"r{i}", i) for i in range(2)]
    wrong = {**truth, "b21": truth["b21"] * 1.4}
    got = choose_design_model({"parameters": wrong, "indices": {"K": 0.42, "T1": T, "T2": 0.0, "T3": 0.0,
                                                                "T": T}}, {"K": K, "T": T}, runs, cfg)
    assert got["chosen"] == "graphical"
    assert got["identified"]["heldout"]["mae_psi_deg"] > got["graphical"]["heldout"]["mae_psi_deg"]
    assert got["graphical"]["heldout"]["mae_psi_deg"] < 0.1     # the truth scores the noise, 0.04 deg
    same = choose_design_model({"parameters": truth, "indices": {"K": K, "T1": T, "T2": 0.0, "T3": 0.0,
                                                                 "T": T}}, {"K": K, "T": T}, runs, cfg)
    assert same["chosen"] == "identified" and "rule" in same
    none = choose_design_model(None, {"K": K, "T": T}, runs, cfg)
    assert none["chosen"] == "graphical"


# ----------------------------------------------------------------------- identification in the loop
@pytest.mark.slow
def test_adaptive_run_keeps_its_anti_bursting_rule():
    """In the loop on the nonlinear KCS: each re-design moves a gain by at most the stated share, and
    without excitation (no course changes) the gains never move."""
    pytest.importorskip("pipeline.tank")
    from pipeline.control.adaptive import AdaptiveStart, after_change_metrics, run_once
    from pipeline.model import PAPER_TABLE4

    theta = [PAPER_TABLE4[n] for n in ("a11", "a12", "a21", "a22", "b11", "b21")]
    cov = np.diag([0.05, 0.01, 0.5, 0.05, 1e-5, 1e-3]) ** 2
    cfg = replace(ControlConfig(), adaptive_duration=120.0, adaptive_change_s=60.0, adaptive_step_every=30.0,
                  wave=False)
    r = run_once(AdaptiveStart(theta, cov, 0.3867, 3.68), 1, cfg, adapt=True)
    g = r["gains"]
    for (_, kp0, kd0, _), (_, kp1, kd1, _) in zip(g[:-1], g[1:], strict=True):
        assert abs(kp1 - kp0) <= cfg.adaptive_max_gain_change * abs(kp0) + 1e-12
        assert abs(kd1 - kd0) <= cfg.adaptive_max_gain_change * abs(kd0) + 1e-12
    m = after_change_metrics(r["t"], r["ref"], r["psi"], r["delta"], cfg)
    assert np.isfinite(m["heading_mae_deg"]) and m["rudder_travel_deg"] > 0
    calm = replace(cfg, adaptive_step_deg=0.0, wind_rudder=0.0)
    quiet = run_once(AdaptiveStart(theta, cov, 0.3867, 3.68), 1, calm, adapt=True)
    assert {(kp, kd) for _, kp, kd, _ in quiet["gains"]} == {(quiet["gains"][0][1], quiet["gains"][0][2])}
    assert all(e.startswith(("start", "excitation")) for *_, e in quiet["gains"])


def test_stage_writes_the_papers_case_the_design_model_and_per_design_margins():
    """run_control on the paper's Table 7 model (CGSA from it, run on it, wind 2 deg and waves): the
    paper's case sits on the PD's floor 2/Kp (the waves move the mean only slightly); every design
    carries its sampled-loop margins; the autopilot's integrator removes the offset."""
    from pipeline.control.stage import run_control
    from pipeline.model import PAPER_GRAPHICAL, PAPER_TABLE7

    idx = {"dataset": "t", "provenance": "measured", "builtin_tank": False,
           "control_model": {"source": "test", **PAPER_TABLE7},
           "identified": {"srukf-ffm": {n: {"value": PAPER_TABLE7[n]} for n in ("K", "T1", "T2", "T3", "T")}},
           "graphical_model": {"source": "test", **PAPER_GRAPHICAL}}
    cfg = replace(ControlConfig(), seeds=2, duration=150.0, steady_start=100.0, robust_draws=5,
                  bode_points=20)
    doc, _ = run_control(idx, cfg, progress=False)
    pc = doc["paper_case"]
    kp = 1 / (PAPER_TABLE7["K"] * cfg.tw)
    assert pc["plant"] == "nomoto" and pc["design"] == "identified"
    assert pc["pd_steady_offset_deg"] == pytest.approx(2.0 / kp, rel=1e-9)          # 2.32 deg
    assert pc["steady_mae_mean"] == pytest.approx(2.0 / kp, abs=0.1)
    auto = next(r for r in doc["results"] if r["design"] == "autopilot")
    assert auto["stats"]["steady_mae"]["mean"] < 0.2
    for d in doc["designs"].values():
        assert d["sampled_loop"]["design_model"]["stable"]
    assert doc["design_model"]["chosen"] == "identified" and "rule" in doc["design_model"]
    assert "identified second-order" in doc["plants"]["nomoto"]["description"]


def test_cli_reads_the_control_table_of_the_datasets_toml(tmp_path, capsys):
    """The control command takes [control] from the dataset.toml that runs/index.json names; a bad
    key there is one line naming the file, exit 2, and the earlier outputs stay."""
    from pipeline.cli import main
    from pipeline.io import read_json, write_json
    from pipeline.model import PAPER_GRAPHICAL, PAPER_TABLE7

    toml = tmp_path / "dataset.toml"
    toml.write_text('[ship]\nname = "Ferry"\n[control]\ndead_time_s = 0.24\nservo_time_constant_s = 0.5\n'
                    'rudder_rate_deg_s = 5.0\n')
    base = tmp_path / "proc" / "f"
    write_json(base / "runs" / "index.json", {"dataset": "f", "runs": [],
                                              "ship": {"ship": "Ferry", "dataset_toml": str(toml)}})
    write_json(base / "indices" / "indices.json", {
        "dataset": "f", "provenance": "measured", "builtin_tank": False,
        "control_model": {"source": "test", **PAPER_TABLE7},
        "graphical_model": {"source": "t", **PAPER_GRAPHICAL}})
    argv = ["control", "--root", str(tmp_path / "proc"), "--dataset", "f", "--seeds", "1", "--no-progress"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert sum("Ferry" in line and "tw_s" in line for line in err.splitlines()) == 1
    m = read_json(base / "control" / "metrics.json")
    assert m["settings"]["dead_time_s"] == 0.24 and m["settings"]["rudder_rate_deg_s"] == 5.0
    assert m["robustness"]["dead_time_samples"] == 3 and m["robustness"]["servo_time_constant_s"] == 0.5
    before = (base / "control" / "metrics.json").read_bytes()
    toml.write_text('[control]\ndead_time = 0.24\n')
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "dataset.toml" in err and "dead_time" in err
    assert (base / "control" / "metrics.json").read_bytes() == before
