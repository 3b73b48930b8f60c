"""Diagnosis stage: extended simulator, fit, failure paths, command line, measured HSVA data."""

from __future__ import annotations

import dataclasses as dc
import json

import numpy as np
import pytest
from scipy import stats
from selection_only import SELECTION_ONLY  # the setting, and its reason, of selection-only tests

from pipeline.cli import main
from pipeline.config import DiagnoseConfig
from pipeline.diagnose import TruthConfig, diagnose, simulate_extended, zigzag_truth
from pipeline.diagnose.core import _context
from pipeline.diagnose.fit import fit_structure, series_from_run
from pipeline.errors import InputError
from pipeline.io import write_run
from pipeline.model import PAPER_TABLE4, simulate

SPEC_EFFECTS = {
    "rudder_offset",
    "nonlinear_yaw_damping",
    "rudder_delay",
    "rudder_lag",
    "speed_loss",
    "nonlinear_sway_damping",
    "sway_yaw_coupling",
    "rudder_saturation",
    "rudder_asymmetry",
}


def test_extended_without_effects_is_the_continuous_model():
    """With no effect the diagnosis simulates pipeline.model.rhs without error of its own: a step
    response converges to the model's exact steady state (not the Euler model's), and the rudder
    offset is the same as adding it to the rudder."""
    from pipeline.model import state_matrices

    d = np.full(3000, 10.0)
    x = simulate_extended(PAPER_TABLE4, (0, 0, 0), d, 0.08)
    A, B = state_matrices(PAPER_TABLE4)
    ss = -np.linalg.solve(A[:2, :2], B[:2] * 10.0)
    np.testing.assert_allclose(x[-1, :2], ss, rtol=1e-6)
    rng = np.random.default_rng(0)
    dd = np.cumsum(rng.normal(0, 1, 300))
    c = simulate_extended(PAPER_TABLE4, (0, 0, 0), dd, 0.08, offset_deg=1.5)
    np.testing.assert_allclose(c, simulate_extended(PAPER_TABLE4, (0, 0, 0), dd + 1.5, 0.08), atol=1e-12)
    assert (
        np.max(
            np.abs(
                simulate(PAPER_TABLE4, (0, 0, 0), dd, 0.08)
                - simulate_extended(PAPER_TABLE4, (0, 0, 0), dd, 0.08)
            )
        )
        > 1e-3
    )


def test_cubic_damping_cuts_yaw_rate():
    d = np.full(1000, 20.0)
    lin = simulate_extended(PAPER_TABLE4, (0, 0, 0), d, 0.08)
    nl = simulate_extended(PAPER_TABLE4, (0, 0, 0), d, 0.08, n_rrr_s_per_deg2=-0.01)
    assert abs(nl[-1, 1]) < 0.8 * abs(lin[-1, 1])


def test_linear_fit_recovers_noise_free_truth_response():
    cfg = TruthConfig(noise=False)
    runs = [zigzag_truth(20, 20, "starboard", 60.0, cfg), zigzag_truth(10, 10, "port", 60.0, cfg)]
    series = [series_from_run(r) for r in runs]
    f = fit_structure(series, (), _context(series))
    from pipeline.model import nomoto_indices

    k_fit, k_true = nomoto_indices(f.params())["K"], nomoto_indices(PAPER_TABLE4)["K"]
    assert abs(k_fit - k_true) < 0.1 * k_true


def test_bad_input_is_refused(tmp_path):
    cfg = TruthConfig()
    run = zigzag_truth(20, 20, "starboard", 30.0, cfg)
    with pytest.raises(InputError, match="no validation run"):
        diagnose([run], [])
    with pytest.raises(InputError, match="twice"):
        diagnose([run], [run])
    bad = dc.replace(run, frame=run.frame.drop(columns=["delta"]))
    with pytest.raises(InputError, match="delta"):
        diagnose([bad], [run])
    nan = run.frame.copy()
    nan.loc[10, "r"] = np.nan
    with pytest.raises(InputError, match="non-finite"):
        diagnose([dc.replace(run, frame=nan)], [zigzag_truth(10, 10, "port", 30.0, cfg)])


def _write(tmp_path, name, run):
    p = tmp_path / f"{name}.parquet"
    write_run(p, run)
    return str(p)


@pytest.mark.long     # CI cut: the diagnosis through the command line in tests/test_dataset.py's every-stage
# build, the gates of a found effect (tests/test_diagnose_gates.py), the refusals below
def test_cli_writes_contract_and_leaves_nothing_on_failure(tmp_path, capsys):
    cfg = TruthConfig(rudder_offset=2.0, seed=3)
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
    paths = [
        _write(tmp_path, f"r{j}", zigzag_truth(a, a, s, 60.0, dc.replace(cfg, seed=j)))
        for j, (a, s) in enumerate(legs)
    ]
    out = tmp_path / "diag"
    assert main(["diagnose", "--train", *paths[:2], "--validate", *paths[2:], "--out", str(out)]) == 0
    rep = json.loads((out / "diagnosis.json").read_text())
    assert rep["cause"] == "rudder_offset"
    assert set(rep) >= {"cause", "findings", "baseline", "extended", "gain"}
    assert [f["effect"] for f in rep["findings"]][0] == "rudder_offset"
    # every effect tried: docs/diagnosis.md's and the open catalogue's own (its sensor effect)
    assert {f["effect"] for f in rep["findings"]} == SPEC_EFFECTS | {"heading_misalignment"}
    for f in rep["findings"]:
        assert {
            "effect",
            "significant",
            "estimate",
            "validation_gain",
            "evidence",
            "physical",
            "material",
            "floor",
        } <= set(f)
    off = rep["findings"][0]
    assert off["material"] and "deg to starboard" in off["physical"]
    assert off["estimate"]["offset_deg"] == pytest.approx(2.0, rel=0.1)
    # the honest gain: nested cross-validation, measured on held-out runs of the outer folds only
    g = rep["gain"]
    assert g["mae_psi_relative_reduction"] > 0.3 and g["measured_on"]
    assert set(g["measured_on"]) <= set(rep["training_runs"] + rep["validation_runs"])
    assert g["interval_95"][0] <= g["mae_psi_relative_reduction"] <= g["interval_95"][1]
    assert [r["model"] for r in rep["ladder"]] == ["baseline", "+rudder_offset"]
    assert rep["ladder"][1]["validation_mae_psi_deg"] < 0.5 * rep["ladder"][0]["validation_mae_psi_deg"]
    assert rep["stability"]["total"] >= 2 and rep["stability"]["folds_agreeing"] >= 2
    assert rep["course_stable"] == [True, True]
    assert (out / "series.parquet").exists() and list(out.glob("freerun_*.png"))
    # a bad run: exit 2, one line, no output directory
    bad = tmp_path / "bad.parquet"
    bad.write_text("not parquet")
    out2 = tmp_path / "diag2"
    assert main(["diagnose", "--train", str(bad), "--validate", paths[2], "--out", str(out2)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.parquet" in err
    assert not out2.exists()


@pytest.fixture(scope="module")
def hsva_design(hsva_dir):
    """All 13 measured HSVA zigzags, roles by the catalog rule, diagnosed once for the tests below."""
    pytest.importorskip("pipeline.ingest")
    from pipeline.cli.diagnose import load_run
    from pipeline.diagnose.design import pick_catalog_runs

    runs = {p.stem: load_run(p) for p in sorted(hsva_dir.glob("*.dat"))}
    entries = [
        {"run_id": k, **{m: r.meta.get(m) for m in ("kind", "rudder_deg", "heading_deg", "first_side")}}
        for k, r in runs.items()
    ]
    tr, va, te = pick_catalog_runs(entries)
    rep = diagnose([runs[k] for k in tr], [runs[k] for k in va], test=[runs[k] for k in te]).report
    return runs, tr, va, te, rep


# long: the 13 measured HSVA zigzags diagnosed (minutes); CI cut: the design on HSVA's index
# (test_catalog_rule_spans_hsva_amplitudes) and the measured KVLCC2 side swap of make test's
# generalisation cut.  One xdist group: the module fixture is built once, on one worker
@pytest.mark.long
@pytest.mark.xdist_group("hsva_design")
def test_hsva_measured_kvlcc2(hsva_design):
    """All 13 measured HSVA zigzags, roles by the stated rule of the catalog mode.

    Rule (:func:`pipeline.cli.diagnose.pick_catalog_runs`, by amplitude and side, from the test and
    first side ingest reads in each file): twins spanning the amplitudes on both sides are the selection
    runs: the crossed 10/10 and 20/10 pairs, 35/5 + 30/5 (largest rudder), 10/5 + 10/1 and 15/1 + 15/5
    (smallest heading, a 1 deg zigzag on each side), one of each twin to training and one to
    validation (the diagnosis adds the reverse fold); the three other zigzags (5/1, 20/5, 25/5) are
    test runs no choice sees.  Required: the gain reported on
    the test runs only with its interval; no effect named that makes the unseen runs worse.

    Measured 2026-11-24: cause none.  The nearest, nonlinear yaw damping (held-out +18 %, per fold +12 %,
    +23 %), makes the held-out 10/1 zigzag significantly worse (2.56 -> 7.68 deg, block t -3.9); the sway
    terms run away on it (2.7 -> 26-29 deg, its heading swing 7 deg).  (With the 10-20 deg pairs alone the
    damping was named and made the 1 deg zigzags drift: 5/1 8 -> 49 deg, test gain -148 %.)
    """
    runs, tr, va, te, rep = hsva_design
    assert len(runs) == 13
    # the rule: every run used once; both sides and the ends of both amplitudes in the selection
    assert sorted(tr + va + te) == sorted(runs) and len(set(tr + va + te)) == 13
    pre = "HSVA_CPMC_KVLCC2_"
    assert tr == [pre + x for x in ("Z_35_05", "Z_20_10_P", "Z_15_01", "Z_10_10_S", "Z_10_05")]
    assert va == [pre + x for x in ("Z_30_05", "Z_20_10_S", "Z_15_05", "Z_10_10_P", "Z_10_01")]
    assert rep["provenance"] == "measured"
    # HSVA's approaches drift -0.09 to +0.11 deg, of both signs (measured 2026-11-25): no misalignment
    drift = rep["data_checks"]["approach_drift"]
    assert len(drift["per_run"]) == 13 and drift["warning"] is None
    assert max(abs(d) for d in drift["per_run"].values()) < 0.2, drift
    # HSVA's r is the heading's derivative (docs/contract.md#run-data): no run's rate bias is significant,
    # none corrected (measured 2026-11-25: -0.0009 to +0.0008 deg/s against standard errors of 0.0004-0.0018),
    # all under the smallest bias a MEMS gyro has (0.003 deg/s)
    rates = rep["data_checks"]["rate_bias"]["per_run"]
    assert len(rates) == 13 and not any(x["corrected"] for x in rates.values()), rates
    assert max(abs(x["bias_deg_s"]) for x in rates.values()) < 0.003, rates
    # the linear model's free-run error on held-out KVLCC2 zigzags is degrees, not noise
    assert rep["baseline"]["validation"]["mae_psi_deg"] > 1.0
    assert len(rep["folds"]) == 2 and rep["stability"]["total"] == 2
    # the gain is measured on the three test runs only, with its interval, and is not negative
    g = rep["gain"]
    assert sorted(g["measured_on"]) == sorted(te)
    assert {p["run_id"] for p in g["per_run"]} == set(te)
    assert g["interval_95"][0] <= g["mae_psi_relative_reduction"] <= g["interval_95"][1]
    assert g["mae_psi_relative_reduction"] >= 0 and g["flag"] is None
    if rep["cause"] != "none":
        f = next(x for x in rep["findings"] if x["effect"] == rep["cause"])
        assert f["significant"] and rep["cause"] in rep["extended"]["effects"]
    else:
        assert rep["extended"]["effects"] == []
        # the reason is said: the nearest candidate and the effects refused for running away
        assert "Nearest:" in rep["summary"] and "running away" in rep["summary"]
        away = [f for f in rep["findings"] if "runs away" in f["evidence"]]
        assert away and all(pre + "Z_10_01" in f["evidence"] for f in away)
    # the best linear model is the fit without the sign bounds (4.97 deg pooled held out against the
    # bounded 6.26): every step of the bounded family is held to it (gate beats_best_linear), and the
    # nearest, r|r| yaw damping (+14 % against the bounded fit), predicts those runs at 5.36 deg: refused
    # by that gate alone, so it cannot make the unseen test runs worse (2.90 -> 5.66 deg without it)
    assert rep["baseline"]["sign_bounds"] is False
    best = rep["ladder"][0]["validation_mae_psi_deg"]
    yaw = next(x for x in rep["findings"] if x["effect"] == "nonlinear_yaw_damping")
    gate = next(x for x in yaw["gates"] if x["code"] == "beats_best_linear")
    assert gate["threshold"] == pytest.approx(best) and gate["value"] > best, gate
    assert [x["code"] for x in yaw["gates"] if not x["passed"]] == ["beats_best_linear"], yaw["gates"]
    # a dead time or a servo lag of ~0.8 s buys 3 % over the whole held-out runs and predicts the ship
    # worse from its measured state (pieces of one ship time scale: +14 %, block t -7): refused by the
    # short-horizon judge (pipeline.diagnose.select), with that reason said
    for e in ("rudder_delay", "rudder_lag"):
        f = next(x for x in rep["findings"] if x["effect"] == e)
        assert e not in rep["extended"]["effects"]
        assert "predicts worse from the measured state" in f["evidence"], f["evidence"]
        assert f["short_horizon_gain"] < 0 and f["short_horizon_block_t"] < 0, f


@pytest.mark.long
@pytest.mark.xdist_group("hsva_design")
@pytest.mark.xfail(strict=True, reason=(
    "measured with the best linear model as the baseline and the anchored form at it (the defaults): the "
    "fold that trains on the 1 deg zigzag 10/1 alone names the cross terms (sway_yaw_coupling), the "
    "selection on both folds names none: 1 of 2 folds agree (docs/diagnosis.md, Known limits)"))
def test_hsva_same_cause_in_every_fold(hsva_design):
    """HSVA gives the same cause in every fold of the chosen design.

    Measured 2026-11-24/25 (a strict xfail until then): folds agreed 1 of 2.  The selection on both
    folds named nothing (held-out 5.64 deg); the fold that trains on the 1 deg zigzag 10/1 alone named
    nonlinear yaw damping, later the cross terms' modulus form (+42 % on its validation runs, its linear
    damping at the bounds a11 = a21 = a22 = 0), which run away on 10/1 wherever 10/1 is held out.  Since
    2026-11-25 a step must not hinge on one training run (pipeline.diagnose.select.Search.hinges):
    refitted without 10/1, every nonlinear damping of that fold runs away on it (6.46 -> 17-36 deg,
    heading swing 7.1 deg), so that fold names nothing either.  The verdict is none in both folds: the
    KVLCC2's large zigzags ask for more damping than its linear model has, and no catalogue term
    fitted on some runs predicts the 1 deg zigzags it did not see."""
    rep = hsva_design[-1]
    st = rep["stability"]
    assert [c["cause"] for c in st["causes"]] == [rep["cause"]] * st["total"], st
    assert st["folds_agreeing"] == st["total"] == 2


def test_block_sandwich_std_matches_monte_carlo_for_correlated_errors():
    """Regression on a slowly varying input with AR(1) errors (rho 0.95): the textbook std is far too
    small; the block sandwich std must match the spread of the estimate over many seeded draws."""
    from pipeline.diagnose.fit import sandwich_cov

    n, rho = 2000, 0.95
    t = np.arange(n) * 0.1
    x = np.sin(2 * np.pi * t / 30.0)
    J = x[:, None]
    clusters = (t // 10.0).astype(int)
    rng = np.random.default_rng(5)
    est, sand, naive = [], [], []
    for _ in range(200):
        w = rng.normal(0, 1, n)
        e = np.empty(n)
        e[0] = w[0]
        for k in range(1, n):
            e[k] = rho * e[k - 1] + np.sqrt(1 - rho**2) * w[k]
        a = float(x @ e / (x @ x))  # estimate of a (true 0)
        res = e - a * x
        est.append(a)
        sand.append(np.sqrt(sandwich_cov(J, res, clusters)[0, 0]))
        naive.append(np.sqrt(res @ res / (n - 1) / (x @ x)))
    mc = np.std(est)
    assert 0.7 * mc < np.median(sand) < 1.3 * mc, (mc, np.median(sand))
    assert np.median(naive) < 0.4 * mc


@pytest.mark.slow
def test_two_effects_found_together_by_stepwise_selection():
    """Offset AND cubic damping (cutting the 20/20 yaw rate by 30 %) on the linear truth model: the
    stepwise search holds both, each worth >= min_gain when dropped from the final model, both
    recovered; the clean twin gives none (see test_diagnose_cases.py)."""
    from pipeline.diagnose.truth import damping_for_cut

    n_rrr = damping_for_cut(0.3)
    cfg = TruthConfig(seed=5, rudder_offset=2.0, n_rrr=n_rrr)
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
    runs = [zigzag_truth(a, a, s, 80.0, dc.replace(cfg, seed=cfg.seed + j)) for j, (a, s) in enumerate(legs)]
    rep = diagnose(runs[:2], runs[2:], cfg=SELECTION_ONLY).report
    assert set(rep["extended"]["effects"]) == {"rudder_offset", "nonlinear_yaw_damping"}, rep["ladder"]
    for e in ("rudder_offset", "nonlinear_yaw_damping"):
        f = next(x for x in rep["findings"] if x["effect"] == e)
        assert f["significant"] and min(f["validation_gain_in_extended_folds"]) >= 0.10
    est = rep["extended"]["effect_estimates"]
    assert est["rudder_offset"]["estimate"]["offset_deg"] == pytest.approx(2.0, rel=0.1)
    if rep["extended"]["forms"]["nonlinear_yaw_damping"] == "cubic":
        assert est["nonlinear_yaw_damping"]["estimate"]["n_rrr_s_per_deg2"] == pytest.approx(n_rrr, rel=0.25)


def _with(run, **cols):
    f = run.frame.copy()
    for k, v in cols.items():
        f[k] = v
    return dc.replace(run, frame=f)


def test_robustness_refusals_are_one_line_input_errors(tmp_path, capsys):
    """Runs a careless user gives the diagnosis: u = 0 at the start or throughout, u < 0 (astern), runs of
    different ships or approach speeds, and runs without rudder excitation are refused with one line
    (exit 2)."""
    cfg = TruthConfig(seed=4)
    a = zigzag_truth(20, 20, "starboard", 30.0, cfg)
    b = zigzag_truth(10, 10, "port", 30.0, dc.replace(cfg, seed=5))
    n = len(a.frame)
    cases = {
        "zero at the start": _with(a, u=np.r_[np.zeros(40), np.full(n - 40, 2.0)]),
        "astern": _with(a, u=np.full(n, -1.0)),
        "no rudder excitation": _with(a, delta=np.full(n, 0.3)),
    }
    cases["zero at the start (throughout)"] = _with(a, u=np.zeros(n))
    for what, bad in cases.items():
        key = what.split(" (")[0]
        with pytest.raises(InputError, match=key.split()[0] if key != "astern" else "astern"):
            diagnose([bad], [b])
    other = dc.replace(b, meta={**b.meta, "ship": "KVLCC2"})
    mine = dc.replace(a, meta={**a.meta, "ship": "KCS"})
    with pytest.raises(InputError, match="different ships"):
        diagnose([mine], [other])
    with pytest.raises(InputError, match="approach speed"):
        diagnose([a], [_with(b, u=b.frame["u"] * 1.3)])
    # through the command line: exit 2, one line naming the run, no output, no traceback
    paths = [_write(tmp_path, "astern", cases["astern"]), _write(tmp_path, "ok", b)]
    out = tmp_path / "d"
    assert main(["diagnose", "--train", paths[0], "--validate", paths[1], "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "astern" in err and "complex" not in err and not out.exists()


@pytest.mark.long     # CI cut: tests/test_trust.py's primed indices at model and full scale
def test_verdict_does_not_depend_on_the_scale_of_the_data():
    """The same runs seen at model scale and as if at full scale without --scale (time stretched by
    sqrt(4), speeds by sqrt(4), yaw rate divided by it; resampled to the same 0.08 s step) give the
    same cause and nearly the same held-out gains: every time in the method is in ship time scales."""
    cfg = TruthConfig(seed=7, rudder_offset=-1.5)
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
    runs = [zigzag_truth(a, a, s, 80.0, dc.replace(cfg, seed=cfg.seed + j)) for j, (a, s) in enumerate(legs)]

    def stretch(run, k=2.0):
        f = run.frame
        t = f["time"].to_numpy() * k
        tn = np.arange(0.0, t[-1] + 1e-9, 0.08)
        g = {"time": tn}
        for c, fac in (("psi", 1.0), ("delta", 1.0), ("r", 1 / k), ("v", k), ("u", k)):
            g[c] = np.interp(tn, t, f[c].to_numpy() * fac)
        import pandas as pd

        return dc.replace(run, frame=pd.DataFrame(g), meta={**run.meta, "dt": 0.08})

    a = diagnose(runs[:2], runs[2:], cfg=SELECTION_ONLY).report
    b = diagnose([stretch(r) for r in runs[:2]], [stretch(r) for r in runs[2:]], cfg=SELECTION_ONLY).report
    assert a["cause"] == b["cause"] == "rudder_offset"
    assert b["settings"]["time_scale_s"] == pytest.approx(2.0 * a["settings"]["time_scale_s"], rel=0.05)
    for x, y in zip(
        a["findings"][0]["validation_gain_folds"], b["findings"][0]["validation_gain_folds"], strict=True
    ):
        assert x == pytest.approx(y, abs=0.05)


def _entry(rid, a, h, side="starboard"):
    return {"run_id": rid, "kind": "zigzag", "rudder_deg": a, "heading_deg": h, "first_side": side}


def _amp(runs, ids, key):
    return sorted(r[key] for r in runs if r["run_id"] in ids)


def test_catalog_rule_uses_every_run():
    """Catalog mode: two runs of one rudder amplitude (a pair first) are twins, one trains and one
    validates; with two pairs, the pairs of the smallest and largest amplitude are crossed (each side has
    both sides and both amplitudes); every other zigzag is a test run; one pair: it is the selection."""
    from pipeline.diagnose.design import pick_catalog_runs

    e = _entry
    runs = [e("z10s", 10, 10, "starboard"), e("z10p", 10, 10, "port"), e("z20s", 20, 10, "starboard"),
            e("z20p", 20, 10, "port"), e("z05", 5, 1, "starboard"), e("z35", 35, 5, "starboard")]
    train, val, test = pick_catalog_runs(runs)
    # 5 and 35 deg occur once: no twin, so they are test runs (the rule calls them extrapolated)
    assert train == ["z20s", "z10p"] and val == ["z20p", "z10s"] and sorted(test) == ["z05", "z35"]
    train, val, test = pick_catalog_runs(runs[:2] + runs[4:])
    assert train == ["z10s"] and val == ["z10p"] and sorted(test) == ["z05", "z35"]
    with pytest.raises(InputError, match="two zigzag"):
        pick_catalog_runs(runs[:1])


#: HSVA's 13 measured KVLCC2 zigzags as the runs index names them (rudder deg, heading deg, first side)
HSVA_INDEX = [
    ("Z_05_01", 5, 1, "starboard"), ("Z_10_01", 10, 1, "starboard"), ("Z_10_05", 10, 5, "starboard"),
    ("Z_10_10_P", 10, 10, "port"), ("Z_10_10_S", 10, 10, "starboard"), ("Z_15_01", 15, 1, "starboard"),
    ("Z_15_05", 15, 5, "starboard"), ("Z_20_05", 20, 5, "starboard"), ("Z_20_10_P", 20, 10, "port"),
    ("Z_20_10_S", 20, 10, "starboard"), ("Z_25_05", 25, 5, "starboard"), ("Z_30_05", 30, 5, "starboard"),
    ("Z_35_05", 35, 5, "starboard"),
]


def _check_design(runs, train, val, test):
    """The rule's promises on any index: every run once; training and validation hold the same rudder
    amplitudes within the twin tolerance (so the diagnosis can swap them); the extremes of rudder and
    heading amplitude among twinned runs are in the selection unless no twin of unused runs holds them;
    a test run outside the selection's range then has no free twin."""
    from pipeline.config import DiagnoseConfig
    from pipeline.diagnose.design import extrapolated

    TWIN_TOL = DiagnoseConfig().twin_tolerance
    ids = [r["run_id"] for r in runs]
    assert sorted(train + val + test) == sorted(ids) and len(set(train + val + test)) == len(ids)
    a_tr, a_va = _amp(runs, train, "rudder_deg"), _amp(runs, val, "rudder_deg")
    assert len(a_tr) == len(a_va)
    assert all(abs(x - y) <= TWIN_TOL * max(x, y) for x, y in zip(a_tr, a_va, strict=True))
    def tw(a, b):
        return abs(a["rudder_deg"] - b["rudder_deg"]) <= TWIN_TOL * max(a["rudder_deg"], b["rudder_deg"])

    twinned = [r for r in runs if any(o is not r and tw(o, r) for o in runs)]
    sel = [r for r in runs if r["run_id"] in train + val]
    free = [r for r in twinned if r not in sel]
    for key in ("rudder_deg", "heading_deg"):
        for ext in (min, max):
            v = ext(r[key] for r in twinned)
            # covered, or every run there is left without a free twin (its twins are all selection runs)
            assert v in {r[key] for r in sel} or not any(
                a is not b and a[key] == v and tw(a, b) for a in free for b in free), (key, ext)
    # a heading end of the selection on one side only: no twin of unused runs could bring it to the other
    by = {r["run_id"]: r for r in runs}
    for v in (min(r["heading_deg"] for r in sel), max(r["heading_deg"] for r in sel)):
        if (v in {by[x]["heading_deg"] for x in train}) != (v in {by[x]["heading_deg"] for x in val}):
            assert not any(a is not b and a["heading_deg"] == v and tw(a, b) for a in free for b in free), v
    for rid in extrapolated(runs, train + val, test):
        r = next(x for x in runs if x["run_id"] == rid)
        assert not any(o is not r and tw(o, r) for o in free), rid


def test_catalog_rule_spans_hsva_amplitudes():
    """HSVA's 13 names: the crossed 10/10 and 20/10 pairs, the largest rudder twin 35/5 + 30/5
    and two smallest-heading twins 10/1 + 10/5 and 15/1 + 15/5 (a 1 deg zigzag on each side) are the
    selection; the other three are test runs between them in amplitude, except 5/1 (the only 5 deg
    run: no twin, extrapolated, stated)."""
    from pipeline.diagnose.design import extrapolated, pick_catalog_runs

    runs = [_entry(f"HSVA_CPMC_KVLCC2_{n}", a, h, s) for n, a, h, s in HSVA_INDEX]
    train, val, test = pick_catalog_runs(runs)
    short = [[x.split("KVLCC2_")[1] for x in xs] for xs in (train, val, test)]
    assert short[0] == ["Z_35_05", "Z_20_10_P", "Z_15_01", "Z_10_10_S", "Z_10_05"]
    assert short[1] == ["Z_30_05", "Z_20_10_S", "Z_15_05", "Z_10_10_P", "Z_10_01"]
    assert short[2] == ["Z_05_01", "Z_20_05", "Z_25_05"]
    assert extrapolated(runs, train + val, test) == ["HSVA_CPMC_KVLCC2_Z_05_01"]
    _check_design(runs, train, val, test)
    # each side has a starboard and a port run, a 1 deg and a 10 deg heading, 10 deg and >= 30 deg rudder
    by = {r["run_id"]: r for r in runs}
    for half in (train, val):
        assert {by[x]["first_side"] for x in half} == {"starboard", "port"}
        assert {1, 10} <= {by[x]["heading_deg"] for x in half}
        assert min(by[x]["rudder_deg"] for x in half) == 10 and max(by[x]["rudder_deg"] for x in half) >= 30
    # the order of the index does not matter
    assert pick_catalog_runs(runs[::-1]) == (train, val, test)


def test_catalog_rule_without_pairs():
    """A dataset of one-sided zigzags only (no pairs): twins of equal rudder amplitude, crossed.  The
    twins 30/10 + 30/20 and 10/5 + 10/10 span 10 and 30 deg rudder; the 5 deg heading needs a second
    twin (20/5 + 20/10) to be on both sides; the 20 deg heading has no free twin left, so it is on the
    validation side only; 15/10 and 20/20 are test runs."""
    from pipeline.diagnose.design import extrapolated, pick_catalog_runs

    runs = [_entry(f"z{a}_{h}", a, h) for a, h in
            [(10, 5), (10, 10), (15, 10), (20, 5), (20, 10), (20, 20), (30, 10), (30, 20)]]
    train, val, test = pick_catalog_runs(runs)
    assert train == ["z30_10", "z20_10", "z10_5"] and val == ["z30_20", "z20_5", "z10_10"]
    assert test == ["z15_10", "z20_20"]
    _check_design(runs, train, val, test)
    # 10 deg rudder has a twin (10/5 + 10/10): the smallest twinned amplitude must be selected
    assert extrapolated(runs, train + val, test) == []


def test_catalog_rule_without_twins():
    """No two runs share a rudder amplitude (within 15 %): one fold, the runs at the ends of both
    amplitudes train, the inner runs are dealt validate, test in turn; two runs: larger trains."""
    from pipeline.diagnose.design import pick_catalog_runs

    runs = [_entry(f"z{a}", a, h) for a, h in [(5, 1), (10, 5), (15, 10), (20, 5), (25, 5), (35, 20)]]
    train, val, test = pick_catalog_runs(runs)
    assert train == ["z5", "z35"] and val == ["z10", "z20"] and test == ["z15", "z25"]
    assert pick_catalog_runs(runs[:2]) == (["z10"], ["z5"], [])


def _circle(rid, a, side):
    return {"run_id": rid, "kind": "turning", "rudder_deg": a, "heading_deg": None, "first_side": side}


def test_catalog_rule_uses_turning_circles():
    """Turning circles are runs a user gave: twins of them join the selection,
    crossed (starboard trains in the first twin, then alternately); one without a twin is a test run,
    extrapolated unless the selection holds a turning circle; the zigzags' design is unchanged; an
    index of turning circles alone still gets a design."""
    from pipeline.diagnose.design import extrapolated, pick_catalog_runs

    zz = [_entry("z20s", 20, 20), _entry("z20p", 20, 20, "port"), _entry("z10s", 10, 10),
          _entry("z10p", 10, 10, "port")]
    alone = pick_catalog_runs(zz)
    # the virtual tank's six runs: both 35 deg circles in the selection, one on each side of the design
    tc = [_circle("t35p", 35, "port"), _circle("t35s", 35, "starboard")]
    train, val, test = pick_catalog_runs(zz + tc)
    assert train == alone[0] + ["t35s"] and val == alone[1] + ["t35p"] and test == alone[2] == []
    # two twins, largest rudder first, alternating sides; an odd 20 deg circle is a test run that the
    # selection's circles (25 and 35 deg) do not span; a zigzag test run is judged against zigzags only
    more = tc + [_circle("t25s", 25, "starboard"), _circle("t25p", 25, "port"),
                 _circle("t20s", 20, "starboard")]
    train, val, test = pick_catalog_runs(zz + more + [_entry("z15s", 15, 10)])
    assert train[-2:] == ["t35s", "t25p"] and val[-2:] == ["t35p", "t25s"] and test == ["z15s", "t20s"]
    assert extrapolated(zz + more + [_entry("z15s", 15, 10)], train + val, test) == ["t20s"]
    # one circle: a test run, extrapolated (no selection run turns)
    train, val, test = pick_catalog_runs(zz + tc[:1])
    assert (train, val) == alone[:2] and test == ["t35p"]
    assert extrapolated(zz + tc[:1], train + val, test) == ["t35p"]
    # same-side twins (30 and 35 deg to starboard) are twins too; every run used once
    same = [_circle("t35s", 35, "starboard"), _circle("t30s", 30, "starboard")]
    train, val, test = pick_catalog_runs(zz + same)
    assert train[-1] == "t35s" and val[-1] == "t30s"
    assert sorted(train + val + test) == sorted(r["run_id"] for r in zz + same)
    # circles only (no zigzag): they are the runs the design is made of
    train, val, test = pick_catalog_runs(tc)
    assert sorted(train + val) == ["t35p", "t35s"] and test == []


def test_catalog_design_keeps_to_one_approach_speed():
    """A campaign at two speeds: the diagnosis refuses runs more than 15 % apart in
    approach speed (one linear model holds at one speed), so catalog mode designs on the largest set
    that agrees and leaves the others out with the reason, instead of failing on the whole dataset."""
    from pipeline.cli.diagnose import _other_speed
    from pipeline.diagnose.design import one_speed

    def e(rid, u, kind="zigzag"):
        return {"run_id": rid, "kind": kind, "approach_speed": u}

    runs = [e("a", 2.00), e("b", 2.01), e("c", 1.98, "turning"), e("d", 1.50), e("f", 1.52), e("g", None)]
    used, other = one_speed(runs, 0.15)
    assert [x["run_id"] for x in used] == ["a", "b", "c", "g"] and [x["run_id"] for x in other] == ["d", "f"]
    why = _other_speed(other[0], used, 0.15)
    assert "1.500 m/s" in why and "1.980-2.010 m/s" in why and "15%" in why and "--train" in why
    # within the tolerance every run is used; no speeds known: every run is used
    assert one_speed(runs[:3], 0.15) == (runs[:3], [])
    assert one_speed([e("x", None), e("y", None)], 0.15)[1] == []
    # a tie in size: the set with more zigzags, then the faster one
    tie = [e("s1", 1.5), e("s2", 1.5, "turning"), e("f1", 2.0), e("f2", 2.0)]
    assert [x["run_id"] for x in one_speed(tie, 0.15)[0]] == ["f1", "f2"]
    tie = [e("s1", 1.5), e("s2", 1.5), e("f1", 2.0), e("f2", 2.0)]
    assert [x["run_id"] for x in one_speed(tie, 0.15)[0]] == ["f1", "f2"]
    # the edge: 15 % apart exactly is one speed (check_runs refuses only beyond it)
    assert one_speed([e("p", 2.0), e("q", 2.3)], 0.15)[1] == []


def test_catalog_mode_says_which_runs_it_left_out(tmp_path, monkeypatch, capsys):
    """``diagnose --dataset``: a campaign's index with a run at a 30 % lower approach speed and a test
    of another kind beside four zigzags: the design is made of the zigzags, the two others are left
    out with their reasons, printed and in diagnosis.json (``runs_not_used``); the diagnosis runs."""
    from pipeline.catalog import Catalog

    monkeypatch.setattr("pipeline.cli.diagnose.DiagnoseConfig", lambda: SELECTION_ONLY)   # CI time
    cat = Catalog(root=tmp_path, dataset="campaign")
    cfg = TruthConfig(rudder_offset=2.0, seed=3)
    legs = {"z20s": (20, "starboard"), "z10p": (10, "port"), "z20p": (20, "port"), "z10s": (10, "starboard"),
            "z20s_slow": (20, "starboard"), "pullout": (20, "starboard")}
    entries = []
    for j, (rid, (a, side)) in enumerate(legs.items()):
        run = zigzag_truth(a, a, side, 40.0, dc.replace(cfg, seed=j))
        write_run(cat.runs_dir / f"{rid}.parquet", dc.replace(run, meta={**run.meta, "run_id": rid}))
        entries.append({"run_id": rid, "file": f"{rid}.parquet", "rudder_deg": a, "heading_deg": a,
                        "kind": "other" if rid == "pullout" else "zigzag", "first_side": side,
                        "approach_speed": 1.4 if rid == "z20s_slow" else 2.0})
    cat.runs_index.write_text(json.dumps({"dataset": "campaign", "runs": entries}))
    assert main(["diagnose", "--dataset", "campaign", "--root", str(tmp_path), "--no-plots"]) == 0
    out = capsys.readouterr().out
    rep = json.loads((cat.diagnose_dir / "diagnosis.json").read_text())
    assert rep["training_runs"] == ["z20s", "z10p"] and rep["validation_runs"] == ["z20p", "z10s"]
    assert sorted(rep["runs_not_used"]) == ["pullout", "z20s_slow"]
    slow = rep["runs_not_used"]["z20s_slow"]
    assert "1.400 m/s" in slow and "2.000-2.000 m/s" in slow
    assert "kind 'other'" in rep["runs_not_used"]["pullout"]
    assert "not used: " in out and "z20s_slow (approach speed 1.400 m/s" in out
    assert "design: train z20s, z10p; validate z20p, z10s; test none (the honest gain by nested" in out


def test_catalog_mode_takes_the_descriptions_roles(tmp_path, monkeypatch, capsys):
    """``diagnose --dataset`` with ``[roles]`` train / validate / test in the dataset's description
    (docs/dataset.md; ingest records them in runs/index.json): the design is the user's, said so, and a run in
    no role is left out with that reason.  Found 2026-11-26: the roles were recorded and ignored, the stated
    rule designing instead."""
    from pipeline.catalog import Catalog

    monkeypatch.setattr("pipeline.cli.diagnose.DiagnoseConfig", lambda: SELECTION_ONLY)   # CI time
    cat = Catalog(root=tmp_path, dataset="mine")
    cfg = TruthConfig(rudder_offset=2.0, seed=3)
    legs = {"z20s": (20, "starboard"), "z10p": (10, "port"), "z20p": (20, "port"), "z10s": (10, "starboard"),
            "z15s": (15, "starboard")}
    entries = []
    for j, (rid, (a, side)) in enumerate(legs.items()):
        run = zigzag_truth(a, a, side, 40.0, dc.replace(cfg, seed=j))
        write_run(cat.runs_dir / f"{rid}.parquet", dc.replace(run, meta={**run.meta, "run_id": rid}))
        entries.append({"run_id": rid, "file": f"{rid}.parquet", "rudder_deg": a, "heading_deg": a,
                        "kind": "zigzag", "first_side": side, "approach_speed": 2.0})
    roles = {"identify": None, "train": ["z20p", "z10s"], "validate": ["z20s"], "test": ["z10p"]}
    cat.runs_index.write_text(json.dumps({"dataset": "mine", "roles": roles, "runs": entries}))
    assert main(["diagnose", "--dataset", "mine", "--root", str(tmp_path), "--no-plots"]) == 0
    out = capsys.readouterr().out
    rep = json.loads((cat.diagnose_dir / "diagnosis.json").read_text())
    assert rep["training_runs"] == ["z20p", "z10s"] and rep["validation_runs"] == ["z20s"]
    assert rep["gain"]["measured_on"] == ["z10p"]
    assert rep["runs_not_used"] == {"z15s": "in no [roles] of the dataset's description"}
    assert "design (the dataset's [roles]): train z20p, z10s; validate z20s; test z10p" in out


@pytest.mark.parametrize("roles, msg", [
    ({"train": ["z20s"]}, "[roles] gives train but not validate"),
    ({"train": ["z20s"], "validate": ["zz99"]},
     "[roles] validate names run 'zz99', which the dataset has not"),
    ({"train": ["z20s"], "validate": ["z20s"]}, "[roles] names run 'z20s' in both train and validate"),
])
def test_descriptions_roles_refused_in_one_line(roles, msg):
    from pipeline.diagnose.design import roles_design
    from pipeline.errors import InputError

    index = {"ship": {"dataset_toml": "data/raw/mine/dataset.toml"}, "roles": roles,
             "runs": [{"run_id": "z20s"}, {"run_id": "z10p"}]}
    with pytest.raises(InputError) as err:
        roles_design(index)
    assert str(err.value).startswith("data/raw/mine/dataset.toml: " + msg) and "\n" not in str(err.value)
    assert roles_design({"roles": {"identify": "z20s", "train": [], "validate": []}, "runs": []}) is None


def test_catalog_rule_promises_on_any_index():
    """The rule's promises (:func:`_check_design`) on seeded random run indexes: amplitudes from a
    tank's usual grid, sides at random, 2 to 14 runs, some with pairs, some without any twin."""
    from pipeline.diagnose.design import pick_catalog_runs

    rng = np.random.default_rng(11)
    for n in range(200):
        k = int(rng.integers(2, 15))
        runs = [_entry(f"r{n}_{i}", float(rng.choice([5, 10, 15, 20, 25, 30, 35])),
                       float(rng.choice([1, 5, 10, 20])), str(rng.choice(["starboard", "port"])))
                for i in range(k)]
        train, val, test = pick_catalog_runs(runs)
        assert train and val
        twinned = any(a is not b and abs(a["rudder_deg"] - b["rudder_deg"]) <= 0.15 * b["rudder_deg"]
                      for a in runs for b in runs)
        if twinned:
            _check_design(runs, train, val, test)
        else:
            assert sorted(train + val + test) == sorted(r["run_id"] for r in runs)


def test_floor_text_says_a_diverging_removal_in_words():
    """The materiality floor text of a response-change effect: a removal that changes the yaw rate by
    more than the manoeuvre's own peak (measured on HSVA: 1845 %) is said to diverge, not given as a
    percentage; an ordinary change keeps its percentage; the report passes the words through."""
    from pipeline.diagnose.effects.base import response_floor_text
    from pipeline.report.diagnosis_text import floor_measured

    big = response_floor_text(18.448, 0.05)
    assert "diverges" in big and "1845" not in big and "18 times" in big and "floor 5%" in big
    assert "no longer finite" in response_floor_text(float("inf"))
    small = response_floor_text(0.123, 0.05)
    assert small == "changes the peak yaw rate of the largest manoeuvre by 12.3% (floor 5%)"
    assert "diverges" in floor_measured(big + " [the precision model tests are trusted to]")


def test_step_refuses_an_effect_that_runs_away_or_harms_one_held_out_manoeuvre():
    """The no-run-away rule of a step (select.py): a model that cuts the error of a large held-out
    zigzag (10 -> 1 deg) but lets a small one's error grow by more than its own heading swing (1 -> 4 deg
    on a +-1 deg zigzag: it no longer makes that manoeuvre) fails, naming the run, although the pooled
    gain is large; the same cut with the small run's error grown by less than its swing (1 -> 1.5 deg)
    is not refused for that reason, but is when it holds on every block (significant harm); an
    unchanged small run with noise is no harm."""
    from pipeline.diagnose.effects import BY_NAME, Context
    from pipeline.diagnose.fit import Series
    from pipeline.diagnose.select import Fold, Search

    t = np.arange(0.0, 200.0, 0.1)
    big = Series("big", t, 20 * np.sign(np.sin(t / 10)), 20 * np.sin(t / 10), np.cos(t / 10))
    small = Series("small", t, 5 * np.sign(np.sin(t / 10)), 1.0 * np.sin(t / 10), 0.1 * np.cos(t / 10))
    ctx = Context(t_ship=10.0, h=0.1, d_max=20.0, r_max=2.0, v_max=0.1)

    class FakeFit:
        values = {"nonlinear_yaw_damping": {"n_rrr_s_per_deg2": -0.01}}

        def form(self, effect):
            return BY_NAME[effect].forms[0]

    class Fake(Search):
        def __init__(self, err, noise=0.0):  # err: structure -> {run: heading error, deg}; noise deg
            super().__init__([Fold([big], [big, small])], ctx, DiagnoseConfig())
            self.err, self.noise = err, noise

        def fit(self, k, structure, start=None):
            return FakeFit()

        def response_change(self, k, structure, effect):
            return 0.5  # material: the floor is not what is tested here

        def short(self, k, structure):
            return [(1.0, [1.0], [0]) for _ in (big, small)]  # the short-horizon judge: no change

        def eval(self, k, structure):
            per = []
            for j, s in enumerate((big, small)):
                e = self.err[bool(structure)][s.name]
                # seeded error noise, different before and after: blocks differ by chance only
                noise = self.noise * np.random.default_rng(10 * j + bool(structure)).normal(0, 1, t.size)
                sim = np.column_stack([np.zeros_like(t), s.r, s.psi + e + noise])
                per.append({"sim": sim, "mae_psi_deg": e})
            return {"mae_psi_deg": float(np.mean([p["mae_psi_deg"] for p in per]))}, per

    after = (("nonlinear_yaw_damping", "cubic"),)
    away = Fake({False: {"big": 10.0, "small": 1.0}, True: {"big": 1.0, "small": 4.0}})
    st = away.step([0], (), after, "nonlinear_yaw_damping", 0.01)
    assert st.gain > 0.4 and not st.passes
    assert any("runs away" in w and "small 1.00 -> 4.00 deg" in w for w in st.why), st.why
    ok = Fake({False: {"big": 10.0, "small": 1.0}, True: {"big": 1.0, "small": 1.5}})
    st = ok.step([0], (), after, "nonlinear_yaw_damping", 0.01)
    assert not any("runs away" in w for w in st.why), st.why
    # ... but 1 -> 1.5 deg on every block of the small run (noise 0.3 deg) is significant harm
    worse = Fake({False: {"big": 10.0, "small": 1.0}, True: {"big": 1.0, "small": 1.5}}, noise=0.3)
    st = worse.step([0], (), after, "nonlinear_yaw_damping", 0.01)
    assert not st.passes and any("significantly worse" in w and "small" in w for w in st.why), st.why
    # the same noise with the small run's error unchanged: no harm found, the step passes
    same = Fake({False: {"big": 10.0, "small": 1.0}, True: {"big": 1.0, "small": 1.0}}, noise=0.3)
    st = same.step([0], (), after, "nonlinear_yaw_damping", 0.01)
    assert not any("significantly worse" in w for w in st.why) and st.passes, st.why


def _gated(effect, gain, folds, cut_deg, t, t_crit, blocks, **measured) -> dict:
    """A material finding of diagnosis.json that was not named, its ``gates`` judged by the selection's
    own gates (pipeline.diagnose.gates) on the evidence given (for the report's verdict tests)."""
    from pipeline.diagnose.gates import Evidence, judge

    ev = Evidence(gain=gain, fold_gains=tuple(folds), min_gain=0.10, abs_gain_deg=cut_deg,
                  noise_floor_deg=0.1, t=t, t_crit=t_crit, blocks=blocks, carried=(), floor_ok=(True,),
                  floor_words="", harm=(),
                  harm_level="0.05/10", short_gain=0.0, short_t=0.0, short_t_crit=1.67, short_horizon_T=1.0,
                  runaway=())
    ev = dc.replace(ev, **measured)
    gates = judge(ev, last=False)
    if all(g.passed for g in gates):
        gates += judge(ev, last=True)
    return {"effect": effect, "significant": False, "material": all(ev.floor_ok), "validation_gain": gain,
            "validation_gain_folds": list(folds), "abs_gain_deg": cut_deg, "block_t": t,
            "block_t_crit": t_crit, "blocks": blocks, "gates": [g.to_json() for g in gates],
            "evidence": "Not named: " + "; ".join(g.words for g in gates if not g.passed)}


SETTINGS = {"min_gain": 0.10, "min_abs_gain_deg": 0.10, "heading_noise_deg": 0.02}


def test_report_verdict_of_an_effect_that_harms_a_held_out_run():
    """A finding refused only by the no-harm gate (measured HSVA numbers) reads 'harms a held-out run'
    with the run and its numbers, read from the gate's code, not 'another effect already explained the
    same error'; the gate's value is the run's block t and its threshold minus the critical t."""
    from pipeline.diagnose.gates import RunTest
    from pipeline.report import diagnosis_text as dt

    harm = (RunTest("Z_10_01", -4.0, -2.9, "Z_10_01 2.71 -> 7.81 deg (block t = -4.0)"),)
    f = _gated("nonlinear_yaw_damping", 0.12, [0.04, 0.19], 0.65, 1.8, 1.67, 76, harm=harm)
    gate = next(g for g in f["gates"] if g["code"] == "no_harm")
    assert gate == {"code": "no_harm", "passed": False, "value": -4.0, "threshold": -2.9,
                    "words": gate["words"]}
    v, why = dt.verdict(f, SETTINGS)
    assert v == "harms a held-out run" and "Z_10_01 2.71 -> 7.81 deg" in why and "added to" not in why
    assert dt.failed_tests(f, SETTINGS) == ("harms a held-out run",)
    # the report reads the code, not the words: reworded, the verdict is the same
    gate["words"] = "another wording of the same refusal"
    assert dt.verdict(f, SETTINGS) == ("harms a held-out run", "another wording of the same refusal")


def test_report_verdict_of_an_effect_that_predicts_worse_from_the_measured_state():
    """A finding refused by the short-horizon gate (measured HSVA numbers of the dead time) reads
    'worse from the measured state' with its numbers beside the gain threshold it also failed."""
    from pipeline.report import diagnosis_text as dt

    f = _gated("rudder_delay", 0.03, [0.03, 0.03], 0.19, 1.9, 1.67, 76, short_gain=-0.14, short_t=-7.13)
    v, why = dt.verdict(f, SETTINGS)
    assert v == "immaterial" and "+14% (block t = -7.13 below -1.67)" in why and "added to" not in why
    assert dt.failed_tests(f, SETTINGS) == ("immaterial", "worse from the measured state")
    f = _gated("rudder_delay", 0.12, [0.11, 0.13], 0.19, 1.9, 1.67, 76, short_gain=-0.14, short_t=-7.13)
    assert dt.verdict(f, SETTINGS)[0] == "worse from the measured state"


def test_report_verdict_of_an_effect_that_hinges_on_a_training_run():
    """A finding that passes every gate but the hinge (the measured numbers of the virtual KCS's cubic
    yaw damping, six runs with turning circles) reads 'hinges on a training run' with the run and its
    numbers, not 'not significant' (what an unknown reason fell back to)."""
    from pipeline.report import diagnosis_text as dt

    run = "kcs_zigzag_10_10_P 9.11 -> 41.47 deg (heading swing 21.14 deg)"
    f = _gated("nonlinear_yaw_damping", 0.54, [0.62, 0.44], 6.6, 5.1, 1.66, 82, hinges=(run,))
    v, why = dt.verdict(f, SETTINGS)
    assert v == "hinges on a training run", (v, why)
    assert run in why and "added to" not in why
    assert dt.failed_tests(f, SETTINGS) == ("hinges on a training run",)
    # judged last: a step refused by another gate is not refitted for it, and its gate is not written
    f = _gated("nonlinear_yaw_damping", 0.05, [0.62, 0.44], 6.6, 5.1, 1.66, 82, hinges=(run,))
    assert "hinge" not in [g["code"] for g in f["gates"]]


def test_report_verdict_of_an_effect_carried_by_one_held_out_run():
    """A finding whose whole-run cut is significant only with one held-out run's blocks (the measured
    numbers of the virtual KCS's rudder offset, six runs with turning circles) reads 'carried by one
    held-out run' with the run and its t, not 'not significant'; beside a floor failure both are listed,
    each reason its own gate's words."""
    from pipeline.diagnose.gates import RunTest
    from pipeline.report import diagnosis_text as dt

    carried = (RunTest("kcs_zigzag_20_20_P", 1.24, 1.67,
                       "kcs_zigzag_20_20_P (without it block t = 1.24 below 1.67)"),)
    f = _gated("rudder_offset", 0.18, [0.07, 0.29], 2.4, 2.1, 1.66, 82, carried=carried)
    gate = next(g for g in f["gates"] if g["code"] == "carried_by_one_run")
    assert (gate["passed"], gate["value"], gate["threshold"]) == (False, 1.24, 1.67)
    v, why = dt.verdict(f, SETTINGS)
    assert v == "carried by one held-out run", (v, why)
    assert why.endswith("kcs_zigzag_20_20_P (without it block t = 1.24 below 1.67)") and "added to" not in why
    assert dt.failed_tests(f, SETTINGS) == ("carried by one held-out run",)
    f = _gated("rudder_offset", 0.18, [0.07, 0.29], 2.4, 2.1, 1.66, 82, carried=carried,
               floor_ok=(True, False),
               floor_words="below its physical floor in fold 2: |offset| 0.2 deg (floor 0.3 deg)")
    assert dt.failed_tests(f, SETTINGS) == ("immaterial", "carried by one held-out run")
    why = dt.verdict(f, SETTINGS)[1]
    assert why.startswith("below its physical floor in fold 2: |offset| 0.2 deg (floor 0.3 deg); ")
    assert why.endswith("kcs_zigzag_20_20_P (without it block t = 1.24 below 1.67)")


@pytest.mark.long     # CI cut: test_nested_workers_stay_in_process_where_a_fork_is_unsafe, and the
# workers started and killed by tests/test_faults.py's pool test
def test_nested_workers_give_the_same_report_bytes():
    """The nested leave-one-run-out in 2 worker processes (forked while the parent makes the main
    selection) gives the report of the in-process run byte for byte, in a fresh single-threaded
    interpreter (the only place the workers are used; tests/nested_bytes.py).  And switched off
    (DiagnoseConfig.nested_gain), it changes nothing but the gain, the stability and the reference
    fit's nested figures."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    done = subprocess.run([sys.executable, str(root / "tests" / "nested_bytes.py")], cwd=root,
                          capture_output=True, text=True,
                          env={**__import__("os").environ, "PYTHONPATH": str(root)}, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    got = json.loads(done.stdout.strip().splitlines()[-1])
    assert got["same"] is True and got["nested"] == 4
    # nested_gain off (a detection study's setting): the main selection and every finding are the
    # same; only the honest gain (none, with the reason), the held-out-run stability and the reference
    # fit's figures under the nested protocol (reference.nested_*) are not made
    assert got["off_differ"] == ["gain", "reference", "stability"], got
    assert got["reference_differ"] == ["nested_baseline_mae_psi_deg", "nested_interval_95",
                                       "nested_mae_psi_deg", "nested_mae_psi_relative_reduction",
                                       "nested_measured_on"], got
    assert got["off_gain"] is None and "switched off" in got["off_method"]
    assert got["cause"][0] == got["cause"][1] != "none"


def test_nested_workers_stay_in_process_where_a_fork_is_unsafe():
    """1 when asked, with fewer than two runs, and in a process with another thread (a fork would
    copy its held locks); otherwise the count asked, capped by the runs (the subprocess test above
    checks 2 in a fresh interpreter)."""
    import threading

    from pipeline.diagnose.core import _nested_workers

    stop = threading.Event()
    t = threading.Thread(target=stop.wait, daemon=True)
    t.start()
    try:
        assert _nested_workers(DiagnoseConfig(nested_workers=2), 4) == 1
        assert _nested_workers(DiagnoseConfig(nested_workers=0), 4) == 1
    finally:
        stop.set()
        t.join()
    assert _nested_workers(DiagnoseConfig(nested_workers=1), 4) == 1
    assert _nested_workers(DiagnoseConfig(nested_workers=8), 1) == 1
    if threading.active_count() == 1:   # pytest-xdist's worker has its own threads: then only the above
        assert _nested_workers(DiagnoseConfig(nested_workers=8), 3) == 3


def test_nested_workers_stay_in_a_daemon_process(monkeypatch):
    """A daemon process (a Dask worker) may not have children: in-process there, whatever is asked;
    the same single-threaded process that is not a daemon gets the workers (the branch is isolated
    by pretending this process has one thread)."""
    import multiprocessing
    import threading
    from types import SimpleNamespace

    from pipeline.diagnose.core import _nested_workers

    monkeypatch.setattr(threading, "active_count", lambda: 1)
    monkeypatch.setattr(multiprocessing, "current_process", lambda: SimpleNamespace(daemon=False))
    assert _nested_workers(DiagnoseConfig(nested_workers=2), 4) == 2
    monkeypatch.setattr(multiprocessing, "current_process", lambda: SimpleNamespace(daemon=True))
    assert _nested_workers(DiagnoseConfig(nested_workers=2), 4) == 1


# ------------------------------------------------------------------ nested leave-one-run-out: inner folds
def _runs(*names, rudder=None, turning=()):
    """Stand-ins for Series: a name, a rudder (deg) held at ``rudder[name]`` (10 if not given) and a
    heading that swings 10 deg, or turns through 360 deg for the names in ``turning``."""
    from types import SimpleNamespace

    t = np.linspace(0.0, 1.0, 50)
    return [SimpleNamespace(name=n, delta=np.full(50, float((rudder or {}).get(n, 10.0))),
                            psi=360.0 * t if n in turning else 10.0 * np.sin(6.0 * t)) for n in names]


def _names(folds):
    return [([s.name for s in f.train], [s.name for s in f.val]) for f in folds]


def test_inner_folds_validate_every_remaining_run_once_under_a_two_fold_design():
    """Outer train A B / validate C D with the reverse fold: holding out A, each of B, C, D is validated
    once by a model trained on the other two (known answer of core._inner_folds)."""
    from pipeline.diagnose.core import _inner_folds
    from pipeline.diagnose.select import Fold

    a, b, c, d = _runs("A", "B", "C", "D")
    folds = [Fold([a, b], [c, d]), Fold([c, d], [a, b])]
    assert _names(_inner_folds(folds, a, DiagnoseConfig())) == [
        (["C", "D"], ["B"]), (["B", "D"], ["C"]), (["B", "C"], ["D"])]
    assert _names(_inner_folds(folds, d, DiagnoseConfig())) == [
        (["B", "C"], ["A"]), (["A", "C"], ["B"]), (["A", "B"], ["C"])]
    # six runs, as the catalog design crosses the virtual tank's: A 20/20 S, B 10/10 P, C turning 35 S
    # trained, D 20/20 P, E 10/10 S, F turning 35 P validated.  Holding out A, five remain, sorted by
    # manoeuvre (B E, D, C F) and dealt into three groups: each run validated exactly once, and never
    # with its twin (the two turning circles, the two 10 deg zigzags) in its own group
    # (twin_left_trains off: the next test has the rule that keeps A's twin D out of the deal)
    runs = _runs("A", "B", "C", "D", "E", "F", rudder={"A": 20, "C": 35, "D": 20, "F": 35}, turning="CF")
    folds = [Fold(runs[:3], runs[3:]), Fold(runs[3:], runs[:3])]
    dealt = DiagnoseConfig(twin_left_trains=False)
    inner = _inner_folds(folds, runs[0], dealt)
    assert _names(inner) == [(["D", "E", "F"], ["B", "C"]), (["B", "C", "D"], ["E", "F"]),
                             (["B", "C", "E", "F"], ["D"])]
    # a setting below 2 cannot leave a fold without training runs
    assert len(_inner_folds(folds, runs[0], dc.replace(dealt, inner_folds=1))) == 2


def test_the_held_out_runs_lone_twin_trains_every_inner_fold():
    """The six-run design (A 20/20 S, B 10/10 P, C turning 35 S | D 20/20 P, E 10/10 S, F turning 35 P)
    with A held out leaves D the only 20 deg zigzag: with ``twin_left_trains`` (the default) it trains
    every inner fold and is validated by none, B E C F dealt into three groups, so that no inner fold
    asks a manoeuvre of a model that has not trained on it (the outer test never does).  Holding out a
    10 deg zigzag keeps its twin the same way; with a twin left beside another of its manoeuvre
    (four 10 deg zigzags) nothing changes; of four zigzags at two amplitudes the twin trains both folds
    of the other two."""
    from pipeline.diagnose.core import _inner_folds, _lone_twin
    from pipeline.diagnose.effects import Context
    from pipeline.diagnose.select import Fold, Search

    runs = _runs("A", "B", "C", "D", "E", "F", rudder={"A": 20, "C": 35, "D": 20, "F": 35}, turning="CF")
    folds = [Fold(runs[:3], runs[3:]), Fold(runs[3:], runs[:3])]
    assert _names(_inner_folds(folds, runs[0], DiagnoseConfig())) == [
        (["C", "D", "E"], ["B", "F"]), (["B", "C", "D", "F"], ["E"]), (["B", "D", "E", "F"], ["C"])]
    assert _names(_inner_folds(folds, runs[1], DiagnoseConfig())) == [
        (["C", "D", "E"], ["A", "F"]), (["A", "C", "E", "F"], ["D"]), (["A", "D", "E", "F"], ["C"])]
    # the hinge check of an inner fold never leaves out a training run that is the only one of its
    # manoeuvre there (Fold.kept): refitted without it, the model would be asked that manoeuvre from
    # none of its kind, which the outer test never asks.  The twin D is such a run in every fold; the
    # 10 deg zigzag B or E and the circle C or F where its twin is validated
    inner = _inner_folds(folds, runs[0], DiagnoseConfig())
    assert [[s.name for s in f.kept] for f in inner] == [["C", "D", "E"], ["B", "D"], ["D", "F"]]
    ctx = Context(t_ship=10.0, h=0.02, d_max=35.0, r_max=2.0, v_max=0.2, u_ref=1.0, u_min_ratio=0.8)
    jack = Search(inner, ctx, DiagnoseConfig()).jackknife()
    assert jack and all(all(inner[k].train[j] is not x for x in inner[k].kept) for k, j in jack)
    assert all(f.kept == () for f in _inner_folds(folds, runs[0], DiagnoseConfig(twin_left_trains=False)))
    # the same folds not keeping it: the fold training on B D E F leaves D out (two zigzags remain)
    bare = [Fold(f.train, f.val) for f in inner]
    assert [(k, j) for k, j in Search(bare, ctx, DiagnoseConfig()).jackknife()
            if bare[k].train[j] is runs[3]] == [(2, 1)]
    rest = [r for r in runs if r is not runs[0]]
    assert _lone_twin(runs[0], rest, 0.15) is runs[3]
    # within the twin tolerance only: a 20 deg run is no twin of a 10 or 35 deg one
    assert _lone_twin(runs[0], [runs[1], runs[2], runs[4], runs[5]], 0.15) is None
    a, b, c, d = _runs("A", "B", "C", "D")
    four = [Fold([a, b], [c, d]), Fold([c, d], [a, b])]
    assert _lone_twin(a, [b, c, d], 0.15) is None
    assert _names(_inner_folds(four, a, DiagnoseConfig())) == [
        (["C", "D"], ["B"]), (["B", "D"], ["C"]), (["B", "C"], ["D"])]
    a, b, c, d = _runs("A", "B", "C", "D", rudder={"A": 20, "C": 20})
    two = [Fold([a, b], [c, d]), Fold([c, d], [a, b])]
    assert _names(_inner_folds(two, a, DiagnoseConfig())) == [(["C", "D"], ["B"]), (["B", "C"], ["D"])]
    assert _names(_inner_folds(two, a, DiagnoseConfig(twin_left_trains=False))) == [
        (["C", "D"], ["B"]), (["B", "C"], ["D"]), (["B", "D"], ["C"])]


def test_inner_folds_keep_the_users_one_fold_design():
    """One outer fold (two_fold off, or sides not exchangeable): the design is kept, the held-out run
    taken from its side (the training runs stay whole when a validation run is held out)."""
    from pipeline.diagnose.core import _inner_folds
    from pipeline.diagnose.select import Fold

    a, b, c, d = _runs("A", "B", "C", "D")
    folds = [Fold([a, b], [c, d])]
    cfg = DiagnoseConfig(two_fold=False)
    assert _names(_inner_folds(folds, c, cfg)) == [(["A", "B"], ["D"])]
    assert _names(_inner_folds(folds, a, cfg)) == [(["B"], ["C", "D"])]


def test_the_honest_gain_is_flagged_when_it_fails_its_check():
    """diagnosis.json gain.flag known answers: no flag for a gain whose interval is above zero or where
    nothing is named; 'WORSE' (naming the runs) below zero; 'not shown better' for an interval that
    reaches zero (the virtual KCS read through a 1 deg misaligned heading: +0.5 % [-4 %, +4 %], which
    a reader would take for a cut)."""
    from dataclasses import replace

    from pipeline.diagnose.core import _gain_flag
    from pipeline.diagnose.result import Gain, HeldOutSelection

    runs = [{"run_id": "a", "gain": 0.1}, {"run_id": "b", "gain": -0.3}]
    ok = Gain(mae_psi_relative_reduction=0.58, interval_95=[0.41, 0.69], measured_on=["a", "b"], method="",
              per_run=runs, nested=[], against_other_linear=None)
    assert _gain_flag(ok, ["rudder_offset"]) is None
    assert _gain_flag(replace(ok, interval_95=None), ["rudder_offset"]) is None
    null = replace(ok, mae_psi_relative_reduction=0.005, interval_95=[-0.04, 0.04])
    assert _gain_flag(null, []) is None
    flag = _gain_flag(null, ["nonlinear_sway_damping"])
    assert flag.startswith("the extended model is not shown better") and "[-4%, +4%]" in flag, flag
    worse = replace(ok, mae_psi_relative_reduction=-0.05, interval_95=[-0.11, 0.03])
    flag = _gain_flag(worse, ["rudder_offset"])
    assert "WORSE" in flag and "worse on b:" in flag and "a," not in flag, flag

    # a verdict of none: no flag when every nested selection chose nothing (the gain is 0 by
    # construction), a flag when some did: the gain is then theirs, not the linear model's
    def held(effects):
        return HeldOutSelection(fold="hold out x", effects=effects, cause=effects[0] if effects else None,
                                chosen_on=["y"], measured_on=["x"], baseline_mae_psi_deg=1.0,
                                extended_mae_psi_deg=1.0, gain=0.0, baseline_sign_bounds=True,
                                other_linear_mae_psi_deg=None)

    quiet = [held([])] * 3
    assert _gain_flag(replace(ok, mae_psi_relative_reduction=0.0, nested=quiet), []) is None
    chose = [held(["rudder_offset", "sway_yaw_coupling"]), held([]),
             held(["rudder_offset", "sway_yaw_coupling"]), held(["rudder_asymmetry"])]
    named_some = replace(ok, mae_psi_relative_reduction=0.45, interval_95=[0.23, 0.65], nested=chose)
    flag = _gain_flag(named_some, [])
    assert flag.startswith("no effect is named on all the runs") and "in 3 of 4" in flag, flag
    assert "rudder_offset + sway_yaw_coupling (2 of 4); rudder_asymmetry (1 of 4)" in flag, flag
    assert "(+45%, 95 % interval [+23%, +65%])" in flag, flag


def test_harm_from_the_common_start_carries_the_start_uncertainty(monkeypatch):
    """The per-run no-harm test (select.py, Search._start_sd): every block of a free run shares the
    run's start, known only to the approach's standard deviations.  Known answer: a model whose
    heading error grows as (r0_true - r0) t (a ship near its margin drifting from a start error) has
    a per-run difference D linear in r0, so the propagated standard deviation is exactly
    drift * sd_r0 * mean block time, and from a start 1 sd off the 'harm' it shows is one draw of
    the start, not significant.  Only for a start that is one sample: the same start fitted over a
    quiet approach keeps the harm (its sd is the held-out box's, measured to overstate the start's
    error; select.py).  A model worse by the same amount whatever the start (a constant heading
    error) keeps its harm: the start's share is 0 there.  With no start uncertainty recorded
    the test is the block t-test alone (previous test)."""
    import pipeline.diagnose.select as sel
    from pipeline.diagnose.effects import BY_NAME, Context
    from pipeline.diagnose.fit import Series, Start

    t = np.arange(0.0, 200.0, 0.1)
    r_true, sd_r0, drift = 0.05, 0.05, 0.1  # deg/s, deg/s, deg per (deg/s) per s
    # the start, one sample (no quiet approach): r0 = 0, one sd below the truth
    one_sample = Start(np.zeros(3), np.array([0.0, sd_r0, 0.0]), one_sample=True)
    runs = [Series(n, t, 5 * np.sign(np.sin(t / 10)), a * np.sin(t / 10), 0.1 * np.cos(t / 10),
                   start=one_sample) for n, a in (("big", 20.0), ("small", 1.0))]
    ctx = Context(t_ship=10.0, h=0.1, d_max=20.0, r_max=2.0, v_max=0.1)
    noise = {s.name: np.random.default_rng(j).normal(0, 1, t.size) for j, s in enumerate(runs)}

    class FakeFit:
        values = {"nonlinear_yaw_damping": {"n_rrr_s_per_deg2": -0.01}}

        def __init__(self, bias, drift=0.0, scatter=0.0):
            self.bias, self.drift, self.scatter = bias, drift, scatter

        def form(self, effect):
            return BY_NAME[effect].forms[0]

    def fake_sim(fit, s, x0=None):
        x = s.x0 if x0 is None else x0
        e = fit.bias[s.name] + fit.drift * (r_true - x[1]) * (s.t - s.t[0]) + fit.scatter * noise[s.name]
        return np.column_stack([np.zeros_like(t), s.r, s.psi + e])

    monkeypatch.setattr(sel, "simulate_fit", fake_sim)

    class Fake(sel.Search):
        def __init__(self, before, after):
            super().__init__([sel.Fold(runs[:1], runs)], ctx, DiagnoseConfig())
            self.fits = {False: before, True: after}

        def fit(self, k, structure, start=None):
            return self.fits[bool(structure)]

        def response_change(self, k, structure, effect):
            return 0.5

        def short(self, k, structure):
            return [(1.0, [1.0], [0]) for _ in runs]

        def eval(self, k, structure):
            f = self.fit(k, structure)
            per = []
            for s in runs:
                x = fake_sim(f, s)
                per.append({"sim": x, "mae_psi_deg": float(np.mean(np.abs(x[:, 2] - s.psi)))})
            return {"mae_psi_deg": float(np.mean([p["mae_psi_deg"] for p in per]))}, per

    after = (("nonlinear_yaw_damping", "cubic"),)
    before = FakeFit({"big": 10.0, "small": 3.0})  # errors of one sign throughout: |e| is linear
    drifting = Fake(before, FakeFit({"big": 1.0, "small": 3.0}, drift=drift, scatter=0.3))
    edges = np.arange(0.0, 200.0, drifting.block_s)
    block_means = [t[(t >= b) & (t < b + drifting.block_s)].mean() for b in edges]
    sd = drifting._start_sd(0, runs[1], (), after)
    assert sd == pytest.approx(drift * sd_r0 * np.mean(block_means), rel=1e-6)
    assert drifting._start_sd(0, runs[1], (), ()) == 0.0  # the same model twice: no difference to carry
    # from the common start the small run is worse on every block (3 -> 3.5 deg on average) ...
    d = drifting._block_diffs(runs[1], fake_sim(before, runs[1]), fake_sim(drifting.fits[True], runs[1]))
    crit = stats.t.ppf(1.0 - DiagnoseConfig().alpha / len(runs), len(d) - 1)  # the test's Bonferroni level
    assert np.mean(d) / (np.std(d, ddof=1) / np.sqrt(len(d))) < -crit
    # ... but by one draw of its start: no harm found
    st = drifting.step([0], (), after, "nonlinear_yaw_damping", 0.01)
    assert not any("significantly worse" in w for w in st.why), st.why
    # the same start fitted over a quiet approach: its (box's) sd is not carried, the harm stays
    runs[1].start = dc.replace(one_sample, one_sample=False)
    assert drifting._start_sd(0, runs[1], (), after) == 0.0
    st = drifting.step([0], (), after, "nonlinear_yaw_damping", 0.01)
    assert any("significantly worse" in w and "small" in w for w in st.why), st.why
    runs[1].start = one_sample
    # worse by 0.5 deg whatever the start: the harm stays
    constant = Fake(before, FakeFit({"big": 1.0, "small": 3.5}, scatter=0.3))
    assert constant._start_sd(0, runs[1], (), after) == 0.0
    st = constant.step([0], (), after, "nonlinear_yaw_damping", 0.01)
    assert any("significantly worse" in w and "small" in w for w in st.why), st.why


def test_quiet_approach_samples_end_where_the_rudder_first_moves():
    """fit.quiet_approach_samples, known answers: the samples of the window before the rudder's
    first movement above the excitation floor; 0 for a run executed at its first sample (the virtual
    tank's), the whole window for a rudder that stays put; rudder noise below the floor is no movement.
    with_initial_states records whether the start is that one sample."""
    from pipeline.diagnose.fit import (
        MIN_APPROACH_SAMPLES,
        MIN_RUDDER_EXCITATION_DEG,
        Series,
        quiet_approach_samples,
        with_initial_states,
    )

    t = np.arange(0.0, 60.0, 0.1)
    wiggle = 0.4 * MIN_RUDDER_EXCITATION_DEG * np.sin(7.0 * t)   # under the floor
    late = np.where(t >= 3.0, 10.0, 0.0) + wiggle               # moves at sample 30
    s_late = Series("late", t, late, np.zeros_like(t), np.zeros_like(t))
    assert quiet_approach_samples(s_late, 10.0) == 30
    at_once = np.full_like(t, 10.0)
    at_once[0] = 0.0                                             # executed at the first sample
    s_now = Series("now", t, at_once, np.zeros_like(t), np.zeros_like(t))
    assert quiet_approach_samples(s_now, 10.0) == 0 < MIN_APPROACH_SAMPLES
    s_still = Series("still", t, wiggle, np.zeros_like(t), np.zeros_like(t))
    assert quiet_approach_samples(s_still, 10.0) == 101          # 10 s at 0.1 s, both ends
    s_late, s_now = with_initial_states([s_late, s_now], 10.0)
    assert s_late.start.one_sample is False and s_now.start.one_sample is True
    assert np.array_equal(s_now.x0, s_now.first_state())


def test_reverse_fold_follows_the_twin_tolerance():
    """The reverse fold is made only where both sides are the same manoeuvres within
    DiagnoseConfig.twin_tolerance (relative rudder amplitude): a 10 and an 11.2 deg zigzag (10.7 %
    apart) are the same at the default 15 %, not at 5 %.  Known answer through core._inner_folds:
    holding out the training run E of train A B E / validate C D leaves A B / C D, exchangeable or not."""
    from pipeline.diagnose.core import _exchangeable, _inner_folds
    from pipeline.diagnose.select import Fold

    a, b, c, d, e = _runs("A", "B", "C", "D", "E", rudder={"A": 10, "B": 20, "C": 11.2, "D": 20, "E": 30})
    assert _exchangeable([a, b], [c, d], DiagnoseConfig().twin_tolerance)
    assert not _exchangeable([a, b], [c, d], 0.05)
    folds = [Fold([a, b, e], [c, d])]
    assert _names(_inner_folds(folds, e, DiagnoseConfig())) == [(["A", "B"], ["C", "D"]),
                                                                (["C", "D"], ["A", "B"])]
    assert _names(_inner_folds(folds, e, DiagnoseConfig(twin_tolerance=0.05))) == [(["A", "B"], ["C", "D"])]


def test_a_lone_turn_trains_every_inner_fold_with_jackknife_same_kind():
    """The six-run design with a turning circle (C) held out leaves one turn (F) among zigzags: by
    default it is dealt like the others and validated by a fold trained on zigzags alone (A B D); with
    ``jackknife_same_kind`` it trains every inner fold and is validated by none, the zigzags dealt as
    before.  With both turns left (a zigzag held out) the setting changes nothing."""
    from pipeline.diagnose.core import _inner_folds
    from pipeline.diagnose.select import Fold

    runs = _runs("A", "B", "C", "D", "E", "F", rudder={"A": 20, "C": 35, "D": 20, "F": 35}, turning="CF")
    folds = [Fold(runs[:3], runs[3:]), Fold(runs[3:], runs[:3])]
    assert _names(_inner_folds(folds, runs[2], DiagnoseConfig(jackknife_same_kind=False,
                                                              twin_left_trains=False))) == [
        (["A", "E", "F"], ["B", "D"]), (["A", "B", "D"], ["E", "F"]), (["B", "D", "E", "F"], ["A"])]
    same = DiagnoseConfig(jackknife_same_kind=True, twin_left_trains=False)
    assert _names(_inner_folds(folds, runs[2], same)) == [
        (["A", "E", "F"], ["B", "D"]), (["A", "B", "D", "F"], ["E"]), (["B", "D", "E", "F"], ["A"])]
    from pipeline.diagnose.select import lone_turn

    assert lone_turn(runs) is None and lone_turn(runs[:2]) is None
    assert lone_turn([r for r in runs if r is not runs[2]]) is runs[5]
    default = _inner_folds(folds, runs[0], DiagnoseConfig(jackknife_same_kind=False, twin_left_trains=False))
    assert _names(_inner_folds(folds, runs[0], same)) == _names(default)
