"""Diagnosis stage: extended simulator, fit, failure paths, command line, measured HSVA data."""

from __future__ import annotations

import dataclasses as dc
import json

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.diagnose import TruthConfig, diagnose, simulate_extended, zigzag_truth
from pipeline.diagnose.fit import fit_model, series_from_run
from pipeline.errors import InputError
from pipeline.io import write_run
from pipeline.model import PAPER_TABLE4, simulate


def test_extended_reduces_to_spec_model():
    rng = np.random.default_rng(0)
    d = np.cumsum(rng.normal(0, 1, 300))
    a = simulate(PAPER_TABLE4, (0.01, 0.2, 3.0), d, 0.08)
    b = simulate_extended(PAPER_TABLE4, (0.01, 0.2, 3.0), d, 0.08)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    # an offset is the same as adding it to the rudder; the delay shifts by (delay - h)
    c = simulate_extended(PAPER_TABLE4, (0, 0, 0), d, 0.08, offset_deg=1.5)
    np.testing.assert_allclose(c, simulate(PAPER_TABLE4, (0, 0, 0), d + 1.5, 0.08), atol=1e-12)
    e = simulate_extended(PAPER_TABLE4, (0, 0, 0), d, 0.08, delay_s=0.08 + 0.4)
    shifted = np.concatenate([np.full(5, d[0]), d[:-5]])
    np.testing.assert_allclose(e, simulate(PAPER_TABLE4, (0, 0, 0), shifted, 0.08), atol=1e-9)


def test_cubic_damping_cuts_yaw_rate():
    d = np.full(1000, 20.0)
    lin = simulate_extended(PAPER_TABLE4, (0, 0, 0), d, 0.08)
    nl = simulate_extended(PAPER_TABLE4, (0, 0, 0), d, 0.08, n_rrr_s_per_deg2=-0.01)
    assert abs(nl[-1, 1]) < 0.8 * abs(lin[-1, 1])


def test_linear_fit_recovers_noise_free_truth_response():
    cfg = TruthConfig(noise=False)
    runs = [zigzag_truth(20, 20, "starboard", 60.0, cfg), zigzag_truth(10, 10, "port", 60.0, cfg)]
    f = fit_model([series_from_run(r) for r in runs])
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
    assert {f["effect"] for f in rep["findings"]} == {
        "rudder_offset",
        "nonlinear_yaw_damping",
        "rudder_delay",
        "speed_loss",
    }
    for f in rep["findings"]:
        assert {"effect", "significant", "estimate", "validation_gain", "evidence"} <= set(f)
    assert rep["gain"]["mae_psi_relative_reduction"] > 0.3
    assert (out / "series.parquet").exists() and list(out.glob("freerun_*.png"))
    # a bad run: exit 2, one line, no output directory
    bad = tmp_path / "bad.parquet"
    bad.write_text("not parquet")
    out2 = tmp_path / "diag2"
    assert main(["diagnose", "--train", str(bad), "--validate", paths[2], "--out", str(out2)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.parquet" in err
    assert not out2.exists()


@pytest.mark.slow
def test_hsva_measured_kvlcc2(hsva_dir, tmp_path):
    """Train 20/10 P + 10/10 S, validate 20/10 S + 10/10 P (both sides, two amplitudes)."""
    pytest.importorskip("pipeline.ingest")
    from pipeline.cli.diagnose import load_run

    train = [
        load_run(hsva_dir / "HSVA_CPMC_KVLCC2_Z_20_10_P.dat"),
        load_run(hsva_dir / "HSVA_CPMC_KVLCC2_Z_10_10_S.dat"),
    ]
    val = [
        load_run(hsva_dir / "HSVA_CPMC_KVLCC2_Z_20_10_S.dat"),
        load_run(hsva_dir / "HSVA_CPMC_KVLCC2_Z_10_10_P.dat"),
    ]
    rep = diagnose(train, val).report
    assert rep["provenance"] == "measured"
    # the runs lose ~30 % of their speed: speed dependence must at least be tried
    sl = next(f for f in rep["findings"] if f["effect"] == "speed_loss")
    assert sl["validation_gain"] is not None
    assert 0.2 < sl["estimate"]["max_speed_loss"] < 0.4
    # the linear model's free-run error on held-out KVLCC2 zigzags is degrees, not noise
    assert rep["baseline"]["validation"]["mae_psi_deg"] > 1.0
    # cubic damping brings a large held-out gain on this full-form ship
    nl = next(f for f in rep["findings"] if f["effect"] == "nonlinear_yaw_damping")
    assert nl["validation_gain"] > 0.3 and nl["estimate"]["n_rrr_s_per_deg2"] < 0
    # the mirror split gives the same answer: two folds, stable baselines, the same cause, same sign
    assert len(rep["folds"]) == 2 and all(f["baseline"]["stable"] for f in rep["folds"])
    assert rep["cause"] == "nonlinear_yaw_damping" and nl["significant"]
    for fold in nl["folds"]:
        assert fold["significant"] and fold["estimate"]["n_rrr_s_per_deg2"] < 0 and fold["z"] >= 3.0
    # each fold's baseline is the stable optimum of least training cost over its starts
    from pipeline.diagnose.fit import fit_baseline, fit_model, is_stable, series_from_run

    mirror = [series_from_run(r) for r in val]
    best = fit_baseline(mirror)
    assert is_stable(best.theta)
    single = fit_model(mirror)  # the single continuation start: an unstable or costlier optimum
    assert best.cost <= single.cost + 1e-9


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
        a = float(x @ e / (x @ x))                      # estimate of a (true 0)
        res = e - a * x
        est.append(a)
        sand.append(np.sqrt(sandwich_cov(J, res, clusters)[0, 0]))
        naive.append(np.sqrt(res @ res / (n - 1) / (x @ x)))
    mc = np.std(est)
    assert 0.7 * mc < np.median(sand) < 1.3 * mc, (mc, np.median(sand))
    assert np.median(naive) < 0.4 * mc


@pytest.mark.slow
def test_two_effects_real_only_together_are_found_as_a_pair():
    """_best_pair (tried when no single effect holds in every fold): on the linear truth model with a
    2 deg offset AND cubic damping cutting the 20/20 yaw rate by 30 %, the pair (offset, damping) is
    real, each member is needed (drop-one >= min_gain in both folds) and both are recovered; on clean
    data no pair is claimed."""
    import dataclasses as dc

    from pipeline.config import DiagnoseConfig
    from pipeline.diagnose import TruthConfig, zigzag_truth
    from pipeline.diagnose.core import _best_pair
    from pipeline.diagnose.fit import evaluate, fit_baseline, fit_model, series_from_run
    from pipeline.diagnose.truth import damping_for_cut

    effects = ("rudder_offset", "nonlinear_yaw_damping")
    kw = {"max_nfev": 400, "block_s": 20.0}

    def pair_for(cfg):
        legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
        runs = [series_from_run(zigzag_truth(a, a, s, 80.0, dc.replace(cfg, seed=cfg.seed + j)))
                for j, (a, s) in enumerate(legs)]
        folds = [(runs[:2], runs[2:]), (runs[2:], runs[:2])]
        bases = [fit_baseline(t, **kw) for t, _ in folds]
        fold_base = [evaluate(b, v) for b, (_, v) in zip(bases, folds, strict=True)]
        fold_fits = {e: [fit_model(t, (e,), start=b, **kw) for b, (t, _) in zip(bases, folds, strict=True)]
                     for e in effects}
        fits = {e: fold_fits[e][0] for e in effects}
        rows = [{"effect": e, "folds": [{"extended_mae_psi_deg": evaluate(f, v)[0]["mae_psi_deg"]}
                                        for f, (_, v) in zip(fold_fits[e], folds, strict=True)]}
                for e in effects]
        return _best_pair(rows, fits, fold_fits, folds, fold_base, DiagnoseConfig(), kw)

    assert pair_for(TruthConfig(seed=5)) is None
    n_rrr = damping_for_cut(0.3)
    found = pair_for(TruthConfig(seed=5, rudder_offset=2.0, n_rrr=n_rrr))
    assert found is not None
    order, fl, _, gains, drop = found
    assert set(order) == set(effects)
    assert min(gains) >= 0.5
    for e in effects:
        assert min(drop[e]) >= DiagnoseConfig().min_gain, drop
    for f in fl:
        assert f.extra["offset_deg"] == pytest.approx(2.0, rel=0.1)
        assert f.extra["n_rrr_s_per_deg2"] == pytest.approx(n_rrr, rel=0.25)
