"""The diagnosis benchmark's comparison of two reports (pipeline.bench.diagnose._agreement): the
same-run baseline (plain fits) is judged by its verdict and by how far its figures moved."""

from __future__ import annotations

import copy

from pipeline.bench.diagnose import MOVED, _agreement


def _report():
    return {"cause": "rudder_offset", "extended": {"effects": ["rudder_offset"]},
            "gain": {"mae_psi_relative_reduction": 0.5, "nested": [{"effects": ["rudder_offset"]}]},
            "runs": [{"mae": 2.0, "flag": True}, {"mae": 4.0, "flag": False}]}


def test_identical_reports_agree():
    a = _report()
    # three figures: the booleans are none
    want = f"verdict the same; 0 of 3 figures moved by more than {MOVED:g} (largest 0)"
    assert _agreement(a, copy.deepcopy(a)) == want


def test_a_moved_figure_and_another_verdict_are_told():
    a, b = _report(), _report()
    b["runs"][1]["mae"] = 4.0 * (1 + 10 * MOVED)
    assert "1 of 3 figures moved" in _agreement(a, b) and "verdict the same" in _agreement(a, b)
    b["runs"][1]["mae"] = 4.0 * (1 + 0.1 * MOVED)           # within the optimiser's tolerance
    assert "0 of 3 figures moved" in _agreement(a, b)
    b["gain"]["nested"][0]["effects"] = []
    assert _agreement(a, b).startswith("verdict DIFFERENT")
