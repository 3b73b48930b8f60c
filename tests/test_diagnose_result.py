"""diagnosis.json as a typed object (pipeline.diagnose.result, docs/diagnosis.md): the report a
diagnosis returns is its typed result's JSON form, its keys are the file's contract in the file's
order, and the JSON form reads back into the same object."""

from __future__ import annotations

import dataclasses as dc

import pytest

from pipeline.config import DiagnoseConfig
from pipeline.diagnose import CATALOGUE, TruthConfig, diagnose, zigzag_truth
from pipeline.diagnose.gates import GateResult
from pipeline.diagnose.result import (
    DiagnosisReport,
    Finding,
    FoldReport,
    Gain,
    HeldOutSelection,
    OtherLinearGain,
    Reference,
    ReferenceFold,
    UnjudgedFinding,
)
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
    "validation", "per_run", "residuals", "carried",
]
SETTINGS_KEYS = [
    "min_gain", "min_abs_gain_deg", "alpha", "block_T", "block_s", "time_scale_s", "heading_noise_deg",
    "max_effects", "inadequate_floors", "structured_r2", "catalogue", "two_fold", "u_ref_m_s",
    "x0_box_sigma", "fit", "significance",
]

# gain: measured (nested leave-one-run-out or --test runs), and not measured (three keys fewer)
GAIN_KEYS = [
    "mae_psi_relative_reduction", "interval_95", "measured_on", "method", "baseline_mae_psi_deg",
    "extended_mae_psi_deg", "per_run", "nested", "against_other_linear", "flag",
    "validation_mae_psi_relative_reduction",
]
GAIN_NOT_MEASURED_KEYS = [k for k in GAIN_KEYS if k not in ("baseline_mae_psi_deg", "extended_mae_psi_deg",
                                                            "per_run")]
NESTED_KEYS = [
    "fold", "effects", "cause", "chosen_on", "measured_on", "baseline_mae_psi_deg", "extended_mae_psi_deg",
    "gain", "baseline_sign_bounds", "other_linear_mae_psi_deg", "reference_mae_psi_deg", "carried",
]
OTHER_LINEAR_KEYS = ["mae_psi_relative_reduction", "interval_95", "other_linear_mae_psi_deg",
                     "extended_mae_psi_deg", "validation_mae_psi_relative_reduction"]
REFERENCE_KEYS = [
    "computed", "effects", "forms", "validation_mae_psi_deg", "per_fold",
    "validation_mae_psi_relative_reduction", "test_mae_psi_deg", "test_baseline_mae_psi_deg",
    "test_mae_psi_relative_reduction", "test_interval_95", "nested_mae_psi_deg",
    "nested_baseline_mae_psi_deg", "nested_mae_psi_relative_reduction", "nested_interval_95",
    "nested_measured_on", "reason", "material", "material_threshold",
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
    # the "not made" shapes: every reference key, the figures None; the gain without its three figures
    assert list(rep["reference"]) == REFERENCE_KEYS
    assert rep["reference"]["reason"] == "not made: DiagnoseConfig.reference_fit is off"
    assert rep["reference"]["per_fold"] == [] and rep["reference"]["validation_mae_psi_deg"] is None
    assert list(rep["gain"]) == GAIN_NOT_MEASURED_KEYS
    assert rep["gain"]["nested"] == [] and rep["gain"]["against_other_linear"] is None
    assert rep["gain"]["method"].startswith("none: fewer than three runs")


def test_round_trip(diag, tmp_path):
    doc = read_json(write_json(tmp_path / "diagnosis.json", diag.report))
    back = DiagnosisReport.from_json(doc)
    assert _file(back.to_json(), tmp_path / "back.json") == (tmp_path / "diagnosis.json").read_bytes()
    assert all(isinstance(f, (Finding, UnjudgedFinding)) for f in back.findings)
    assert isinstance(back.folds[0], FoldReport)
    assert back.baseline_adequacy.adequate == doc["baseline_adequate"]
    assert back.settings.catalogue == [e.name for e in CATALOGUE]
    assert isinstance(back.gain, Gain) and isinstance(back.reference, Reference)
    assert back.gain == diag.result.gain and back.reference == diag.result.reference


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


def _held(run: str, effects: list[str]) -> HeldOutSelection:
    return HeldOutSelection(fold=f"hold out {run}", effects=effects, cause=effects[0] if effects else None,
                            chosen_on=["a", "b"], measured_on=[run], baseline_mae_psi_deg=1.2,
                            extended_mae_psi_deg=0.9, gain=0.25, baseline_sign_bounds=True,
                            other_linear_mae_psi_deg=None, reference_mae_psi_deg=0.7 if effects else None)


@pytest.mark.parametrize("validation", [0.31, None], ids=["other linear in every fold", "without"])
def test_measured_gain_keys_and_round_trip(tmp_path, validation):
    """A measured gain (nested leave-one-run-out) with its rounds and the gain against the other linear
    fit: every key in the file's order, the other fit's validation cut left out where it has none, and
    the JSON form reads back into the same object."""
    other = OtherLinearGain(mae_psi_relative_reduction=0.4, interval_95=[0.1, 0.6],
                            other_linear_mae_psi_deg=1.5, extended_mae_psi_deg=0.9,
                            validation_mae_psi_relative_reduction=validation)
    gain = Gain(mae_psi_relative_reduction=0.25, interval_95=[0.05, 0.4], measured_on=["c", "d"],
                method="nested leave-one-run-out", baseline_mae_psi_deg=1.2, extended_mae_psi_deg=0.9,
                per_run=[{"run_id": "c", "baseline_mae_psi_deg": 1.2, "extended_mae_psi_deg": 0.9,
                          "gain": 0.25}],
                nested=[_held("c", ["rudder_offset"]), _held("d", [])], against_other_linear=other,
                flag=None, validation_mae_psi_relative_reduction=0.3)
    doc = read_json(write_json(tmp_path / "gain.json", gain.to_json()))
    assert list(doc) == GAIN_KEYS
    assert [list(n) for n in doc["nested"]] == [NESTED_KEYS] * 2
    assert doc["nested"][1]["cause"] is None and doc["flag"] is None
    assert list(doc["against_other_linear"]) == (OTHER_LINEAR_KEYS if validation is not None
                                                 else OTHER_LINEAR_KEYS[:-1])
    assert Gain.from_json(doc) == gain
    with pytest.raises(KeyError, match="method"):
        Gain.from_json({k: v for k, v in doc.items() if k != "method"})


def test_computed_reference_keys_and_round_trip(tmp_path):
    """A reference fit made on two folds and test runs: every key in the file's order, its per-fold rows
    typed, and the JSON form reads back into the same object."""
    folds = [ReferenceFold(fold=f"fold {k}", validation_runs=[f"v{k}"], baseline_mae_psi_deg=2.0 + k,
                           reference_mae_psi_deg=0.5 + k) for k in range(2)]
    ref = Reference(computed=True, effects=["rudder_offset", "hull_nonlinearity"],
                    forms={"rudder_offset": "constant", "hull_nonlinearity": "abkowitz"},
                    validation_mae_psi_deg=1.0, per_fold=folds, validation_mae_psi_relative_reduction=0.6,
                    test_mae_psi_deg=0.8, test_baseline_mae_psi_deg=2.4, test_mae_psi_relative_reduction=0.67,
                    test_interval_95=[0.5, 0.8])
    doc = read_json(write_json(tmp_path / "reference.json", ref.to_json()))
    assert list(doc) == REFERENCE_KEYS and doc["reason"] is None
    assert [list(f) for f in doc["per_fold"]] == [["fold", "validation_runs", "baseline_mae_psi_deg",
                                                   "reference_mae_psi_deg"]] * 2
    back = Reference.from_json(doc)
    assert back == ref and isinstance(back.per_fold[0], ReferenceFold)
    # in the nested mode: its figures under the honest gain's protocol, in the same order
    nested = Reference(computed=True, effects=ref.effects, forms=ref.forms, validation_mae_psi_deg=1.0,
                       per_fold=folds, validation_mae_psi_relative_reduction=0.6, nested_mae_psi_deg=5.2,
                       nested_baseline_mae_psi_deg=9.7, nested_mae_psi_relative_reduction=0.46,
                       nested_interval_95=[0.34, 0.56], nested_measured_on=["a", "b"], material=True,
                       material_threshold=0.1)
    doc = read_json(write_json(tmp_path / "nested.json", nested.to_json()))
    assert list(doc) == REFERENCE_KEYS and doc["nested_measured_on"] == ["a", "b"]
    assert doc["test_mae_psi_deg"] is None
    assert Reference.from_json(doc) == nested
