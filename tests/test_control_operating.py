"""The project's autopilot is designed at the course-keeping operating point: the smallest zigzags'
K, T when usable, else the design model, saying why; the margins of both bases are in the output
(pipeline/control/operating_point.py, docs/control.md "Operating point")."""

from __future__ import annotations

from dataclasses import replace

import pytest

from pipeline.config import ControlConfig
from pipeline.control.operating_point import small_amplitude_model
from pipeline.control.stage import run_control
from pipeline.model import PAPER_GRAPHICAL, PAPER_TABLE7

CFG = replace(ControlConfig(), seeds=1, duration=60.0, steady_start=40.0, robust_draws=2, bode_points=20,
              adaptive=False)


def _indices(small_flags=()):
    fl = list(small_flags)
    rows = [{"run_id": "z10s", "method": "standard", "test": "10/10", "K": 0.6, "T": 8.0, "flags": fl},
            {"run_id": "z10p", "method": "standard", "test": "10/10", "K": 0.5, "T": 7.0, "flags": fl},
            {"run_id": "z10s", "method": "integral", "test": "10/10", "K": 9.0, "T": 9.0, "flags": []},
            {"run_id": "z20s", "method": "standard", "test": "20/20", "K": 0.3, "T": 4.0, "flags": []}]
    return {"dataset": "t", "provenance": "measured", "builtin_tank": False,
            "control_model": {"source": "test", **PAPER_TABLE7}, "graphical": rows,
            "graphical_model": {"source": "test", **PAPER_GRAPHICAL}}


def test_small_amplitude_model_is_the_mean_of_the_smallest_zigzags_standard_method():
    m, why = small_amplitude_model(_indices())
    assert why == "" and m["rudder_deg"] == 10.0 and m["runs"] == ["z10s", "z10p"]
    assert m["K"] == pytest.approx(0.55, rel=1e-12) and m["T"] == pytest.approx(7.5, rel=1e-12)
    assert small_amplitude_model({"graphical": []})[0] is None


def test_autopilot_is_designed_at_the_small_amplitude_model_with_both_margins():
    doc, _ = run_control(_indices(), CFG, plants=("nomoto",), progress=False)
    op = doc["operating_point"]
    assert op["used"] == "small_amplitude"
    K, T, tw = 0.55, 7.5, CFG.tw
    wn = 1.0 / tw
    pid = doc["designs"]["autopilot"]
    assert pid["K"] == pytest.approx(K) and pid["Kp"] == pytest.approx(T * wn ** 2 / K, rel=1e-12)
    assert doc["designs"]["identified"]["K"] == pytest.approx(PAPER_TABLE7["K"])   # CGSA: the paper's chain
    for basis in ("design_model", "small_amplitude"):
        for kind in ("cgsa", "pid"):
            for plant in ("design_model", "small_amplitude"):
                assert op["margins"][basis][kind]["plants"][plant]["stable"]
    assert any(n.startswith("autopilot (PID) designed from the small-amplitude model") for n in doc["notes"])


def test_flagged_small_amplitude_indices_leave_the_design_model():
    ill = {"check": "ill_conditioned", "subject": "T", "value": 578.0, "band": [0, 60],
           "reason": "T too long"}
    doc, _ = run_control(_indices([ill]), CFG, plants=("nomoto",), progress=False)
    op = doc["operating_point"]
    assert op["used"] == "design_model" and "T too long" in op["why"]
    assert doc["designs"]["autopilot"]["K"] == pytest.approx(PAPER_TABLE7["K"])


def test_hsva_dataset_gives_the_kvlcc2_its_own_steering_gear():
    """data/raw/hsva/dataset.toml carries a full [control] table: the KVLCC2 runs on its own rudder
    rate (measured from the files) and Tw, with no notice that the KCS's were assumed."""
    from pathlib import Path

    from pipeline.control.settings import KEYS, apply, read_dataset_control

    toml = Path(__file__).resolve().parents[1] / "data" / "raw" / "hsva" / "dataset.toml"
    values = read_dataset_control(toml)
    assert set(values) == set(KEYS)
    cfg, notice = apply(ControlConfig(), values, "KVLCC2")
    assert notice is None and cfg.rudder_rate == 15.6 and cfg.tw == 5.9 and cfg.rudder_max == 35.0
