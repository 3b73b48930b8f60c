"""One set of numbers (docs/diagnosis.md, "diagnosis.json"): the command line's line and the baseline
sentences of the report are made from the keys of diagnosis.json alone, in the mode actually used."""

from __future__ import annotations

from pipeline.report import diagnosis_text as dt


def _dg(test_runs: list, gain: float | None, flag_inadequate: bool = False) -> dict:
    return {
        "cause": "none" if gain == 0 else "nonlinear_sway_damping",
        "test_runs": test_runs,
        "baseline_adequate": not flag_inadequate,
        "baseline": {"validation": {"mae_psi_deg": 12.8}, "sign_bounds": False,
                     "other_linear": {"validation_mae_psi_deg": 10.1, "at_sign_bound": ["a21"]}},
        "extended": {"effects": ["nonlinear_sway_damping"], "validation": {"mae_psi_deg": 3.0}},
        "ladder": [{"validation_mae_psi_deg": 4.9}, {"validation_mae_psi_deg": 2.1}],
        "gain": {"mae_psi_relative_reduction": gain, "interval_95": [0.55, 0.68] if gain else None,
                 "baseline_mae_psi_deg": 12.46, "extended_mae_psi_deg": 5.2,
                 "measured_on": ["a", "b", "c"],
                 "against_other_linear": {"mae_psi_relative_reduction": 0.4, "interval_95": [0.3, 0.5],
                                          "validation_mae_psi_relative_reduction": 0.58}},
    }


def test_headline_says_the_mode_and_the_honest_numbers():
    """Nested mode: the gain, its own interval and the two mean MAEs it is made of (not fold 0's
    validation MAEs), each saying which runs and which fit it is over, 'nested leave-one-run-out';
    test-run mode says 'test runs' and the refitted models (the model kept is the baseline when no effect
    is named); without an honest gain the pooled validation MAEs of the ladder, said to be chosen on
    those runs."""
    nested = dt.headline(_dg([], 0.58))
    assert "honest gain +58 % (95 % interval [55 %, 68 %])" in nested
    assert ("mean free-run MAE psi over the 3 runs no choice has seen (nested leave-one-run-out): 12.46 deg "
            "for the linear baseline fitted without the held-out run -> 5.2 deg for the model each selection "
            "chose without the held-out run") in nested
    assert "12.8" not in nested
    test = dt.headline(_dg(["x"], 0.58))
    assert "(test runs): 12.46 deg for the linear baseline refitted on all training and validation runs -> " \
           "5.2 deg for the extended model refitted on them" in test
    kept = {**_dg(["x"], 0.0), "extended": {"effects": []}}
    assert "for the model kept (that same linear baseline: no effect is named)" in dt.headline(kept)
    none = dt.headline({**_dg([], None), "gain": {"mae_psi_relative_reduction": None}})
    assert "validation MAE psi 4.9 deg -> 2.1 deg (mean over the folds; chosen on these runs" in none
    assert "inadequate" in dt.headline(_dg([], 0.58, flag_inadequate=True))


def test_baseline_choice_sentence_reads_the_json():
    """The choice sentence gives the pooled MAEs of both linear fits (the ladder's first rung and
    other_linear's), the bound the other holds, and the gain against the other fit with its interval."""
    text = dt.baseline_choice_text(_dg([], 0.58))
    assert "without sign bounds (unconstrained)" in text
    assert "4.9 deg against 10.1 deg for the bounded" in text
    assert "holds a21 at its bound 0" in text
    assert "cuts the heading error by 40 % (95 % interval [30 %, 50 %])" in text and "58 %" in text
    assert dt.baseline_choice_text({"baseline": {}}) == ""


def test_an_unconstrained_baseline_with_a_ships_wrong_sign_is_said_to_be_a_predictor():
    """The virtual KCS's unconstrained baseline (a21 = +32.3, a22 = +1.13, course-stable by its poles):
    the sentence names both values and the poles; a bounded baseline, or an unconstrained one with a
    ship's signs, gets none."""
    base = {"sign_bounds": False, "course_stable": True,
            "parameters": {"a11": -1.289, "a12": -0.046, "a21": 32.326, "a22": 1.128, "b11": -0.0013,
                           "b21": 0.036}}
    text = dt.unphysical_signs_text({"baseline": base})
    assert "a21 = +32.3 and a22 = +1.13 have not a ship's sign" in text
    assert "a11 =" not in text and "b21" not in text
    assert "Its course stability (stable) is that of the poles" in text
    assert dt.unphysical_signs_text({"baseline": {**base, "sign_bounds": True}}) == ""
    ship = {**base["parameters"], "a21": -0.5, "a22": -0.2}
    assert dt.unphysical_signs_text({"baseline": {**base, "parameters": ship}}) == ""
    assert dt.unphysical_signs_text({"baseline": {}}) == ""
