"""diagnosis.json as a typed object (pipeline.diagnose.result, docs/diagnosis.md): the report a
diagnosis returns is its typed result's JSON form, its keys are the file's contract in the file's
order, and the JSON form reads back into the same object."""

from __future__ import annotations

import dataclasses as dc

import pytest

from pipeline.config import DiagnoseConfig
from pipeline.diagnose import CATALOGUE, TruthConfig, diagnose, zigzag_truth
from pipeline.diagnose.gates import GateResult
from pipeline.diagnose.result import DiagnosisReport, Finding, FoldReport, UnjudgedFinding
from pipeline.io import read_json, write_json

# diagnosis.json's keys as docs/diagnosis.md lists them, in the file's order (written out here, not
# read from the dataclasses, so that a reordered or renamed field fails)
TOP_KEYS = [
    "cause", "baseline_adequate", "baseline_adequacy", "findings", "baseline", "extended", "gain",
    "ladder", "reference", "stability", "course_stable", "folds", "summary", "data_checks",
    "training_runs", "validation_runs", "test_runs", "provenance", "settings",
]
FINDING_KEYS = [
    "effect", "form", "significant", "material", "floor", "physical", "estimate", "uncertainty",
    "profile", "z", "validation_gain", "validation_gain_folds", "validation_gain_alone",
    "validation_gain_alone_folds", "validation_gain_in_extended", "validation_gain_in_extended_folds",
    "abs_gain_deg", "block_t", "block_t_crit", "blocks", "short_horizon_gain", "short_horizon_block_t",
    "hinges_on", "judged", "folds", "rivals", "evidence", "gates",
]
UNJUDGED_KEYS = [
    "effect", "significant", "material", "estimate", "uncertainty", "validation_gain",
    "validation_gain_folds", "z", "physical", "floor", "evidence", "gates",
]
BASELINE_KEYS = [
    "parameters", "uncertainty", "course_stable", "at_sign_bound", "sign_bounds", "best_linear_sign_bounds",
    "other_linear", "choice", "latent_sway_a12", "validation", "per_run", "residuals",
]
EXTENDED_KEYS = [
    "effects", "forms", "parameters", "uncertainty", "effect_estimates", "course_stable", "at_sign_bound",
    "validation", "per_run", "residuals",
]
SETTINGS_KEYS = [
    "min_gain", "min_abs_gain_deg", "alpha", "block_T", "block_s", "time_scale_s", "heading_noise_deg",
    "max_effects", "inadequate_floors", "structured_r2", "catalogue", "two_fold", "u_ref_m_s",
    "x0_box_sigma", "fit", "significance",
]


@pytest.fixture(scope="module")
def diag():
    """Two 30 s zigzags of the truth model (one training, one validation run): too few runs for a
    nested honest gain, so the case is small; the settings are the defaults but the reference fit."""
    cfg = TruthConfig(seed=3, rudder_offset=2.0)
    runs = [zigzag_truth(20, 20, "starboard", 30.0, cfg),
            zigzag_truth(10, 10, "port", 30.0, dc.replace(cfg, seed=4))]
    return diagnose(runs[:1], runs[1:], cfg=DiagnoseConfig(reference_fit=False))


def _file(obj, path):
    """The bytes of ``obj`` written as the diagnose command writes diagnosis.json."""
    return write_json(path, obj).read_bytes()


def test_report_is_the_typed_results_json(diag, tmp_path):
    assert isinstance(diag.result, DiagnosisReport)
    assert _file(diag.report, tmp_path / "a.json") == _file(diag.result.to_json(), tmp_path / "b.json")


def test_known_case_keys_in_the_files_order(diag):
    rep = diag.report
    assert list(rep) == TOP_KEYS
    assert list(rep["baseline"]) == BASELINE_KEYS
    assert list(rep["extended"]) == EXTENDED_KEYS
    assert list(rep["settings"]) == SETTINGS_KEYS
    assert list(rep["baseline_adequacy"]) == ["adequate", "mae_psi_deg", "threshold_deg", "noise_floor_deg",
                                              "floors", "reason", "signatures"]
    assert list(rep["stability"]) == ["folds_agreeing", "total", "causes", "rule"]
    assert list(rep["data_checks"]) == ["approach_drift", "rate_bias"]
    assert [f["effect"] for f in rep["findings"]] and len(rep["findings"]) == len(CATALOGUE)
    for f in rep["findings"]:
        assert list(f) == (FINDING_KEYS if "form" in f else UNJUDGED_KEYS), f["effect"]
    judged = [f for f in diag.result.findings if isinstance(f, Finding)]
    assert judged, "the case judges at least one effect"
    assert all(isinstance(g, GateResult) for f in judged for g in f.gates)
    rung = ["model", "effects", "validation_mae_psi_deg", "test_mae_psi_deg", "test_interval_95"]
    assert [list(r) for r in rep["ladder"]] == [rung] * len(rep["ladder"])
    assert rep["ladder"][0]["model"] == "baseline"
    (fold,) = rep["folds"]
    assert list(fold) == ["training_runs", "validation_runs", "course_stable", "baseline", "extended", "gain"]
    assert list(fold["baseline"]) == ["parameters", "uncertainty", "course_stable", "stable", "training_cost",
                                      "fit", "validation", "per_run"]
    assert list(fold["extended"]) == ["effects", "parameters", "course_stable", "validation", "per_run"]
    # the values the case was run with
    assert rep["training_runs"] == [diag.result.training_runs[0]] and rep["test_runs"] == []
    assert rep["settings"]["two_fold"] is False
    assert rep["reference"]["computed"] is False
    assert rep["gain"]["mae_psi_relative_reduction"] is None  # two runs: nothing held out of every choice


def test_round_trip(diag, tmp_path):
    doc = read_json(write_json(tmp_path / "diagnosis.json", diag.report))
    back = DiagnosisReport.from_json(doc)
    assert _file(back.to_json(), tmp_path / "back.json") == (tmp_path / "diagnosis.json").read_bytes()
    assert all(isinstance(f, (Finding, UnjudgedFinding)) for f in back.findings)
    assert isinstance(back.folds[0], FoldReport)
    assert back.baseline_adequacy.adequate == doc["baseline_adequate"]
    assert back.settings.catalogue == [e.name for e in CATALOGUE]


def test_missing_key_is_refused(diag, tmp_path):
    doc = read_json(write_json(tmp_path / "diagnosis.json", diag.report))
    del doc["settings"]["alpha"]
    with pytest.raises(KeyError, match="alpha"):
        DiagnosisReport.from_json(doc)


def test_unjudged_finding_keys_and_round_trip():
    """An effect not judged claims nothing: its keys are the short list, in order, and read back."""
    f = UnjudgedFinding(effect="rudder_delay", significant=False, material=False, estimate={}, uncertainty={},
                        validation_gain=None, validation_gain_folds=None, z=None, physical="",
                        floor="a dead time below one sample", evidence="Not tried: no rudder.", gates=[])
    doc = f.to_json()
    assert list(doc) == UNJUDGED_KEYS
    assert doc["gates"] == [] and doc["z"] is None
    assert UnjudgedFinding.from_json(doc) == f
    with pytest.raises(KeyError, match="evidence"):
        UnjudgedFinding.from_json({k: v for k, v in doc.items() if k != "evidence"})
