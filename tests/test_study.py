"""Study engine: spec checks, seeds, byte identity for 1 vs 2 workers, resume, failures,
and a study run through a scheduler and worker started as separate processes on the loopback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline.errors import InputError
from pipeline.io import read_json
from pipeline.study import get_kind, kinds, load_spec, run_study
from pipeline.study.engine import case_seed, plan
from pipeline.study.spec import spec_from_dict
from pipeline.study.stats import clopper_pearson, logistic_level

ROOT = Path(__file__).resolve().parents[1]
TINY_AUTOPILOT = {
    "study": {"kind": "autopilot_monte_carlo", "name": "tiny", "seed": 5},
    "autopilot_monte_carlo": {"plants": ["nomoto"], "tw": [2.0, 4.0], "wind_rudder": [0.0, 3.0], "seeds": 2,
                              # 60 s runs (default 200 s): the course is steady from 30 s on (the wind
                              # check below reads a mean rudder of -3.01 deg for 3 deg of wind rudder)
                              "control": {"duration": 60.0, "steady_start": 30.0}},
}


@pytest.fixture(scope="module")
def client(study_client):
    return study_client


# ---------------------------------------------------------------- no cluster needed


def test_every_registered_kind_has_its_settings_and_functions():
    names = [k.name for k in kinds()]
    assert names == ["detection_power", "autopilot_monte_carlo", "batch_identify"]
    for k in kinds():
        assert get_kind(k.name) is k
        assert callable(k.cases) and callable(k.run_case) and callable(k.summarise)


@pytest.mark.parametrize("doc,match", [
    ({}, r"missing \[study\]"),
    ({"study": {"kind": "nope"}}, "unknown study kind 'nope'"),
    ({"study": {"kind": "autopilot_monte_carlo", "sede": 1}}, "unknown key 'study.sede'"),
    ({"study": {"kind": "autopilot_monte_carlo"}, "autopilot_monte_carlo": {"tw": 3.0}},
     "autopilot_monte_carlo.tw.*expected a list"),
    ({"study": {"kind": "autopilot_monte_carlo"}, "detection_power": {}},
     r"unknown table \[detection_power\]"),
    ({"study": {"kind": "autopilot_monte_carlo", "seed": "x"}}, "study.seed.*integer"),
])
def test_bad_spec_is_refused_with_one_line_naming_the_key(doc, match):
    with pytest.raises(InputError, match=match) as exc:
        spec_from_dict(doc, "bad.toml")
    assert "bad.toml" in str(exc.value) and "\n" not in str(exc.value)


def test_example_specs_load_and_plan():
    for name in ("power-ci", "power-full", "autopilot"):
        spec = load_spec(ROOT / "studies" / f"{name}.toml")
        cases = plan(spec)
        assert len({c["case_id"] for c in cases}) == len(cases)
    assert 20 <= len(plan(load_spec(ROOT / "studies/power-ci.toml"))) <= 48          # "a few dozen"
    assert len(plan(load_spec(ROOT / "studies/power-full.toml"))) >= 200             # "hundreds"


def test_case_seed_depends_on_study_seed_and_params_only():
    p = {"plant": "nomoto", "tw": 3.0, "wind_rudder": 0.0, "replicate": 1}
    assert case_seed(5, p) == case_seed(5, dict(reversed(list(p.items()))))   # key order irrelevant
    assert case_seed(5, p) != case_seed(6, p)
    assert case_seed(5, p) != case_seed(5, {**p, "replicate": 2})
    spec = spec_from_dict(TINY_AUTOPILOT)
    a = {c["case_id"]: c["seed"] for c in plan(spec)}
    bigger = spec_from_dict({**TINY_AUTOPILOT, "autopilot_monte_carlo": {
        **TINY_AUTOPILOT["autopilot_monte_carlo"], "wind_rudder": [0.0, 3.0, 6.0]}})
    b = {c["case_id"]: c["seed"] for c in plan(bigger)}
    assert all(b[k] == v for k, v in a.items())          # adding cases leaves the others unchanged


def test_clopper_pearson_known_values():
    lo, hi = clopper_pearson(0, 10, confidence=0.95)
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** (1 / 10), rel=1e-9)
    lo, hi = clopper_pearson(10, 10, confidence=0.95)
    assert hi == 1.0 and lo == pytest.approx(0.025 ** (1 / 10), rel=1e-9)
    lo, hi = clopper_pearson(5, 10, confidence=0.95)                 # tabulated: 0.1871, 0.8129
    assert lo == pytest.approx(0.18709, abs=1e-4) and hi == pytest.approx(0.81291, abs=1e-4)


def test_min_detectable_recovers_a_known_power_curve():
    # detections drawn from a probit curve (not the logistic the method fits) with a 90 % point at 0.5
    from scipy.stats import norm

    rng = np.random.default_rng(0)
    mags = np.repeat([0.1, 0.2, 0.35, 0.5, 0.8, 1.2], 40)
    true90 = 0.5
    p = norm.cdf(norm.ppf(0.9) + 3.0 * np.log(mags / true90))
    det = rng.random(mags.size) < p
    out = logistic_level(mags, det, 0.9, 0.95, 300, np.random.default_rng(1))
    assert out["value"] == pytest.approx(true90, rel=0.25)
    assert out["interval"][0] < true90 < out["interval"][1]
    every = logistic_level(np.array([0.1, 0.2]), np.array([True, True]), 0.9, 0.95, 10, 0)
    assert every["value"] is None and "below the smallest" in every["note"]
    step = logistic_level(np.repeat([0.2, 0.8], 4), np.repeat([False, True], 4), 0.9, 0.95, 10, 0)
    assert step["value"] is None and step["interval"] == [0.2, 0.8]


# ---------------------------------------------------------------- on a local cluster


def test_same_bytes_for_1_and_2_workers_and_resume(tmp_path, client):
    spec = spec_from_dict(TINY_AUTOPILOT)
    s2 = run_study(spec, tmp_path / "w2", client=client, progress=False)
    assert s2["study"] == {"name": "tiny", "kind": "autopilot_monte_carlo", "seed": 5, "cases": 8,
                           "ok": 8, "failed": 0}
    run_study(spec, tmp_path / "w1", workers=1, progress=False)       # its own 1-worker LocalCluster
    for name in ("results.parquet", "summary.json"):
        assert (tmp_path / "w2" / name).read_bytes() == (tmp_path / "w1" / name).read_bytes(), name
    frame = pd.read_parquet(tmp_path / "w2" / "results.parquet")
    assert list(frame["case_id"]) == sorted(frame["case_id"])
    assert {"plant", "tw", "wind_rudder", "replicate", "steady_mae", "max_rudder"} <= set(frame.columns)
    assert not any("second" in c or "time" == c for c in frame.columns)
    # wind pushes the mean steady rudder against it: more wind, more opposite rudder (physics check)
    mean_rudder = frame.groupby("wind_rudder")["mean_rudder"].mean()
    assert mean_rudder[3.0] < mean_rudder[0.0] - 2.0
    # resume: a rerun runs nothing and writes the same bytes; a removed case file is run again
    before = (tmp_path / "w2" / "results.parquet").read_bytes()
    run_study(spec, tmp_path / "w2", client=client, progress=False)
    assert read_json(tmp_path / "w2" / "timings.json")["cases_run_now"] == 0
    victim = sorted((tmp_path / "w2" / "cases").glob("*.json"))[3]
    victim.unlink()
    run_study(spec, tmp_path / "w2", client=client, progress=False)
    assert read_json(tmp_path / "w2" / "timings.json")["cases_run_now"] == 1
    assert (tmp_path / "w2" / "results.parquet").read_bytes() == before


def _truth_csv(path: Path, seed: int) -> Path:
    from pipeline.diagnose import TruthConfig, zigzag_truth

    run = zigzag_truth(20, 20, "starboard", 60.0, TruthConfig(seed=seed))
    with open(path, "w") as fh:
        fh.write("# ship: TRUTH\n# test: zigzag 20/20 starboard\n")
        run.frame.to_csv(fh, index=False, float_format="%.6f", lineterminator="\n")
    return path


def test_failing_case_is_recorded_and_others_go_on(tmp_path, client):
    from pipeline.model import PAPER_TABLE4

    raw = tmp_path / "raw"
    raw.mkdir()
    _truth_csv(raw / "a_good.csv", 1)
    _truth_csv(raw / "c_good.csv", 2)
    (raw / "b_bad.csv").write_text("time,psi,r,delta\n0,0,0,0\n0.08,abc,0,0\n")
    spec = spec_from_dict({"study": {"kind": "batch_identify", "name": "fail", "seed": 1},
                           "batch_identify": {"inputs": [str(raw)], "samples": 500}})
    s = run_study(spec, tmp_path / "out", client=client, progress=False)
    assert s["study"]["ok"] == 2 and s["study"]["failed"] == 1
    (fail,) = s["failures"]
    assert fail["params"]["file"].endswith("b_bad.csv")
    assert fail["error"].startswith("InputError") and "b_bad.csv" in fail["error"]
    frame = pd.read_parquet(tmp_path / "out" / "results.parquet")
    good = frame[frame["status"] == "ok"]
    # the truth is the paper's Table 4 model: its indices come back from the batch identification
    from pipeline.model import nomoto_indices

    K = nomoto_indices(PAPER_TABLE4)["K"]
    assert np.allclose(good["K"], K, rtol=0.15), good["K"].tolist()
    assert (good["validation_mae_psi"] < 1.0).all()
    refused = frame.loc[frame["status"] == "error", "error"]
    assert refused.str.contains("row 3, column 'psi': value .*is not a number").all()
    # the failed case is stored (deterministic error): a rerun does not repeat it
    run_study(spec, tmp_path / "out", client=client, progress=False)
    assert read_json(tmp_path / "out" / "timings.json")["cases_run_now"] == 0


# ---------------------------------------------------------------- separate scheduler and worker


def test_study_through_scheduler_and_worker_processes(tmp_path):
    from pipeline.study.cluster import loopback_cluster, package_env

    with loopback_cluster(1, nanny=False) as addr:          # `dask scheduler` + `dask worker ADDR`
        spec = tmp_path / "tiny.toml"
        spec.write_text('[study]\nkind = "autopilot_monte_carlo"\nname = "cluster"\nseed = 5\n'
                        '[autopilot_monte_carlo]\nplants = ["nomoto"]\ntw = [3.0]\nwind_rudder = [2.0]\n'
                        'seeds = 3\n[autopilot_monte_carlo.control]\nduration = 60.0\nsteady_start = 30.0\n')
        res = subprocess.run([sys.executable, "-m", "pipeline", "study", str(spec), "--out",
                              str(tmp_path / "out"), "--scheduler", addr, "--no-progress"],
                             env=package_env(), capture_output=True, text=True, timeout=300, cwd=tmp_path)
        assert res.returncode == 0, res.stderr[-2000:]
        assert "3 cases, 3 ok, 0 failed" in res.stdout
        timings = read_json(tmp_path / "out" / "timings.json")
        assert timings["workers"] == 1                      # the separate worker did the work
        frame = pd.read_parquet(tmp_path / "out" / "results.parquet")
        assert len(frame) == 3 and (frame["status"] == "ok").all()


def test_bad_worker_count_and_missing_spec_exit_2(tmp_path):
    from pipeline.cli import main

    assert main(["study", str(tmp_path / "none.toml"), "--out", str(tmp_path / "o")]) == 2
    assert main(["study", str(ROOT / "studies/autopilot.toml"), "--out", str(tmp_path / "o"),
                 "--workers", "0"]) == 2
    assert not (tmp_path / "o").exists()
