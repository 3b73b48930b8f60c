"""Typed stage results (pipeline/results.py, docs/api.md#typed-results): one pattern, the same JSON."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from pipeline.config import ControlConfig, FilterConfig
from pipeline.control.result import ControlMetrics, RefusedControl
from pipeline.control.stage import control_result
from pipeline.identify import Estimates, estimates, estimates_json, identify_arrays, synthetic
from pipeline.identify.core import FilterSettings, FilterState
from pipeline.results import Result, optional, spread


@dataclasses.dataclass(frozen=True)
class _Inner(Result):
    a: float
    b: list[int]


@dataclasses.dataclass(frozen=True)
class _Outer(Result):
    name: str
    inner: _Inner
    count: int | None = optional()
    label: dict = spread()
    tail: str = "end"


def test_to_json_keeps_field_order_leaves_out_none_and_spreads_in_place():
    full = _Outer("x", _Inner(1.5, [1, 2]), count=0, label={"virtual_tank": "sim", "z": 1})
    doc = full.to_json()
    # a falsy value (0) is written; only None leaves the key out
    assert list(doc) == ["name", "inner", "count", "virtual_tank", "z", "tail"]
    assert doc["inner"] == {"a": 1.5, "b": [1, 2]}
    bare = _Outer("x", _Inner(1.5, [1, 2])).to_json()
    assert list(bare) == ["name", "inner", "tail"]
    # through the JSON text and back: the nested result is rebuilt, the spread keys return
    assert _Outer.from_json(json.loads(json.dumps(doc))) == full
    assert _Outer.from_json(bare) == _Outer("x", _Inner(1.5, [1, 2]))


def test_from_json_refuses_a_missing_required_key():
    with pytest.raises(KeyError, match="'inner' missing"):
        _Outer.from_json({"name": "x"})


@pytest.fixture(scope="module")
def idents():
    t, d, _, y = synthetic.zigzag(n=300, seed=4)
    no_v = y.copy()
    no_v[:, 0] = np.nan
    cfg = FilterConfig()
    return {"srukf": identify_arrays(t, d, y, cfg, algorithm="srukf-ffm"),
            "ffm": identify_arrays(t, d, y, cfg, algorithm="ffm-ukf"),
            "no_v": identify_arrays(t, d, no_v, cfg, algorithm="srukf-ffm")}


def test_estimates_keys_follow_the_contract_order_with_the_optional_ones_only_when_set(idents):
    cfg = FilterConfig()
    meta = {"run_id": "zz", "provenance": "virtual", "source_file": "zz.csv", "test_name": "zigzag 20/20",
            "ship": "my hull"}
    est = estimates(idents["srukf"], meta, cfg, dataset="d")
    assert isinstance(est.filter_state, FilterState) and isinstance(est.settings, FilterSettings)
    doc = est.to_json()
    core = ["algorithm", "samples", "parameters", "covariance", "indices", "timing", "run_id", "dataset",
            "provenance", "source_file", "test_name", "parameters_std", "measured", "dt", "consistency",
            "filter_state", "settings", "flags", "noise_estimate"]
    # a user's simulated run (provenance virtual, not the built-in tank) carries the 'simulated' label
    assert list(doc) == core + ["simulated"]
    assert doc["filter_state"]["names"][:3] == ["v", "r", "psi"] and len(doc["filter_state"]["x"]) == 9
    assert doc["settings"]["fast_path"] is True and doc["settings"]["r_std"] == list(cfg.r_std)
    # the baseline counts its Cholesky repairs; a run without v says why its parameters are not unique
    ffm = estimates_json(idents["ffm"], {**meta, "provenance": "measured"}, cfg)
    assert list(ffm) == core + ["filterpy_failures"] and ffm["filterpy_failures"] == 0
    assert ffm["settings"]["fast_path"] is False
    no_v = estimates_json(idents["no_v"], {**meta, "provenance": "measured"}, cfg)
    assert list(no_v) == core + ["note"] and no_v["measured"] == ["r", "psi"]
    # the file's JSON text round-trips to the same typed object
    again = Estimates.from_json(json.loads(json.dumps(doc)))
    assert again.filter_state == est.filter_state and again.settings == est.settings
    assert again.to_json() == json.loads(json.dumps(doc))


def _refused_indices():
    cm = {"source": "refused", "refused": True, "reason": "no trustworthy indices: T flagged", "K": 0.3,
          "T1": 10.0, "T2": 0.0, "T3": 0.0, "T": 10.0, "basis": "no trustworthy indices: T flagged",
          "rejected": [], "flags": [], "second_order": {"ok": False, "reason": "refused"}}
    return {"dataset": "d", "provenance": "measured", "control_model": cm, "graphical_model": None}


def test_a_refused_control_is_its_own_result_and_names_its_indices_file_last():
    result, ts = control_result(_refused_indices(), ControlConfig(seeds=1), progress=False)
    assert isinstance(result, RefusedControl) and result.refused and ts.empty
    assert result.reason == "no trustworthy indices: T flagged"
    doc = dataclasses.replace(result, indices_source="indices.json").to_json()
    assert list(doc)[:6] == ["dataset", "provenance", "virtual", "builtin_tank", "refused", "reason"]
    assert list(doc)[-1] == "indices_source" and doc["designs"] == {} and doc["seeds"] == []
    assert "indices_source" not in result.to_json()


def test_a_designed_control_leaves_out_the_blocks_it_did_not_make():
    ind = {"dataset": "d", "provenance": "measured",
           "control_model": {"source": "paper", "K": 0.39, "T1": 12.0, "T2": 1.2, "T3": 1.6, "T": 11.6,
                             "second_order": {"ok": True, "reason": None}},
           "graphical_model": None}
    cfg = ControlConfig(seeds=1, robust_draws=2, bode_points=20, duration=60.0, steady_start=40.0)
    result, _ = control_result(ind, cfg, progress=False)
    assert isinstance(result, ControlMetrics) and not result.refused
    doc = result.to_json()
    # no KCS plant for measured data, so no in-loop identification block; no file named yet
    assert "adaptive" not in doc and "indices_source" not in doc and "refused" not in doc
    assert list(doc)[:4] == ["dataset", "provenance", "virtual", "builtin_tank"]
    assert doc["seeds"] == list(result.seeds) and len(doc["seeds"]) == 1
