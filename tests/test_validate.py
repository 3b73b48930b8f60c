"""Validation stage end to end on small synthetic data (own index.json; no other stage needed)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.config import FilterConfig
from pipeline.identify import identify_run, synthetic
from pipeline.io import read_frame, write_json, write_run
from pipeline.model import PAPER_TABLE4, simulate
from pipeline.validate import (
    PAPER_TABLES,
    ValidationMetrics,
    free_run,
    metrics_document,
    scores,
    validate,
)


def _dataset(root, with_v=True):
    runs_dir = root / "syn" / "runs"
    runs = [synthetic.zigzag_run("zz20", rudder=20, heading=20, n=800, seed=1, with_v=with_v),
            synthetic.zigzag_run("zz10", rudder=10, heading=10, n=500, seed=2, with_v=with_v)]
    entries = []
    for r in runs:
        write_run(runs_dir / f"{r.name}.parquet", r)
        entries.append({"run_id": r.name, "file": f"{r.name}.parquet", **r.meta})
    write_json(runs_dir / "index.json", {"dataset": "syn", "provenance": "virtual", "runs": entries})
    return runs


def test_scores_known_answer():
    meas = np.array([[0.0, 1.0, 2.0], [1.0, 1.0, -2.0]])
    pred = np.array([[0.5, 3.0, 1.0], [1.0, 0.0, 0.0]])
    s = scores(meas, pred)
    assert s == {"mse_v": 0.125, "mse_r": 2.5, "mae_psi": 1.5, "samples": 2}
    meas[:, 0] = np.nan
    assert scores(meas, pred)["mse_v"] is None


def test_free_run_with_true_parameters_reproduces_clean_run():
    run = synthetic.zigzag_run("z", n=300, seed=0, noise=(0.0, 0.0, 0.0))
    pred = free_run({"parameters": PAPER_TABLE4}, run)
    assert np.allclose(pred, run.frame[["v", "r", "psi"]].to_numpy()[1:], atol=1e-12)
    d = run.frame["delta"].to_numpy()
    assert np.allclose(pred, simulate(PAPER_TABLE4, (0, 0, 0), d, 0.08)[1:])


def test_validation_metrics_typed_round_trip():
    """validate() on a held-out run with the true parameters as the estimate: the typed metrics
    document carries its rows (free-run of the truth on noise-free data: zero error), the paper's
    tables, the virtual-data label, and from_json(to_json(x)) == x."""
    ident = synthetic.zigzag_run("zi", n=120, seed=0, noise=(0.0, 0.0, 0.0))
    held = synthetic.zigzag_run("zh", rudder=10, heading=10, n=150, seed=1, noise=(0.0, 0.0, 0.0))
    x = [0.0, 0.0, 0.0, *PAPER_TABLE4.values()]
    est = {"algorithm": "srukf-ffm", "samples": 120, "parameters": PAPER_TABLE4,
           "filter_state": {"x": x, "P": (np.eye(9) * 1e-8).tolist()}}
    rows, _ = validate({"srukf-ffm": est}, ident, [held])
    assert [(r["segment"], r["mode"]) for r in rows] == [("held-out", "one-step"), ("held-out", "free-run")]
    doc = metrics_document("syn", {"provenance": "virtual"}, ident_run="zi", validation_runs=["zh"],
                           rows=rows, flags={"srukf-ffm": []})
    assert ValidationMetrics.from_json(doc.to_json()) == doc
    out = doc.to_json()
    assert list(out) == ["dataset", "provenance", "ident_run", "validation_runs", "rows", "paper",
                         "definitions", "flags", "simulated"]
    assert out["rows"] == rows and out["paper"] == PAPER_TABLES
    free = doc.rows[1]
    assert free.samples == 149 and free.mse_r == pytest.approx(0.0, abs=1e-20) and free.mae_psi < 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("with_v", [True, False])
def test_identify_then_validate_end_to_end(tmp_path, capsys, with_v):
    runs = _dataset(tmp_path, with_v)
    root = ["--root", str(tmp_path), "--dataset", "syn"]
    assert main(["identify", *root]) == 0
    assert main(["validate", *root]) == 0
    doc = json.loads((tmp_path / "syn" / "validate" / "metrics.json").read_text())
    assert doc["ident_run"] == "zz20" and doc["validation_runs"] == ["zz10"]
    assert doc["paper"] == json.loads(json.dumps(PAPER_TABLES))
    rows = {(r["algorithm"], r["segment"], r["mode"]): r for r in doc["rows"]}
    assert len(rows) == 8
    # one-step on the rest of the identification run: prior predictions of samples 585..799
    osa = rows[("srukf-ffm", "identification-rest", "one-step")]
    assert osa["samples"] == 800 - 585
    assert rows[("srukf-ffm", "identification-rest", "free-run")]["samples"] == 800 - 586
    assert rows[("srukf-ffm", "held-out", "free-run")]["samples"] == 499
    for r in doc["rows"]:
        assert (r["mse_v"] is None) == (not with_v)
        # measurement noise is 0.02 deg/s and 0.01 deg: one-step errors are of that size
        if r["mode"] == "one-step":
            assert r["mse_r"] < 5 * 0.02 ** 2 * 2 and r["mae_psi"] < 0.05
        # free-run of a model identified on its own truth stays close on held-out data
        assert r["mae_psi"] < (0.5 if with_v else 3.0)
    # the two algorithms are the same filter in exact arithmetic
    for key in [("held-out", "free-run"), ("identification-rest", "one-step")]:
        a, b = rows[("srukf-ffm", *key)], rows[("ffm-ukf", *key)]
        assert np.isclose(a["mse_r"], b["mse_r"], rtol=1e-5)
    # the typed document built from the same rows is the file, key for key and in order
    index = json.loads((tmp_path / "syn" / "runs" / "index.json").read_text())
    typed = metrics_document("syn", index, ident_run="zz20", validation_runs=["zz10"], rows=doc["rows"],
                             flags=doc["flags"])
    assert json.loads(json.dumps(typed.to_json())) == doc and list(typed.to_json()) == list(doc)
    assert ValidationMetrics.from_json(doc) == typed
    preds, _ = read_frame(tmp_path / "syn" / "validate" / "predictions.parquet")
    assert {"algorithm", "run_id", "mode", "time", "delta", "v", "r", "psi", "v_pred", "r_pred",
            "psi_pred"} <= set(preds.columns)
    one = preds[(preds.algorithm == "srukf-ffm") & (preds["mode"] == "one-step") & (preds.run_id == "zz20")]
    assert np.isclose(one["time"].iloc[0], 585 * 0.08)
    # the identification-rest one-step continues the identification filter (up to the re-factorised
    # covariance and the restarted de of the fuzzy factor at the first step)
    ident = identify_run(runs[0], FilterConfig(), samples=800)
    assert np.allclose(one["r_pred"].to_numpy(), ident.trace["r_pred"].to_numpy()[585:], atol=1e-5)


def test_validate_without_estimates_fails_cleanly(tmp_path, capsys):
    _dataset(tmp_path)
    assert main(["validate", "--root", str(tmp_path), "--dataset", "syn"]) == 2
    err = capsys.readouterr().err
    assert "estimates.json" in err and "\n" not in err.strip()
    assert not (tmp_path / "syn" / "validate").exists()
