"""One set of numbers, said once (docs/diagnosis.md, "Reports"): the diagnosis page, rendered from the
stage's own diagnosis.json in a test-run case and in a nested leave-one-run-out case, says every MAE
and gain from the key that holds it, says which runs and which fit each MAE is over, words the honest
gain in the mode actually used, and every interval holds its point value.

Truth: the linear truth model (pipeline.diagnose.truth) with a 1 deg rudder offset, five 60 s zigzags
(20/20 and 10/10 to both sides chose; a 15/15 is the test run).  The catalogue is cut to the offset and
the cubic yaw damping (a CI-sized diagnosis); the report kernel reads the words of the full one.
"""

from __future__ import annotations

import dataclasses as dc
import json
import math
import re
import sys
from pathlib import Path

import pytest

from pipeline.cli import main

sys.path.insert(0, str(Path(__file__).parent))
from report_catalog import make_catalog  # noqa: E402
from test_reports import _Visible  # noqa: E402

NUM = r"(-?\d+(?:\.\d+)?(?:e[+-]?\d+)?)"


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    """{mode: (diagnosis.json, rendered page, the stage's test_series.parquet or None)} for the test-run
    and the nested case."""
    import pipeline.diagnose as diag
    import pipeline.diagnose.core as core
    import pipeline.diagnose.effects as effects
    import pipeline.diagnose.select as select
    from pipeline.diagnose import TruthConfig, diagnose, zigzag_truth
    from pipeline.diagnose.output import write_outputs
    from pipeline.io import read_frame

    mp = pytest.MonkeyPatch()
    cut = (effects.BY_NAME["rudder_offset"], effects.BY_NAME["nonlinear_yaw_damping"])
    for mod in (effects, core, select, diag):
        mp.setattr(mod, "CATALOGUE", cut)
    cfg = TruthConfig(seed=7, rudder_offset=1.0)
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard"), (15, "starboard")]
    runs = [zigzag_truth(a, a, s, 60.0, dc.replace(cfg, seed=cfg.seed + j)) for j, (a, s) in enumerate(legs)]
    out = {}
    try:
        for mode, test in (("test runs", runs[4:]), ("nested leave-one-run-out", [])):
            d = diagnose(runs[:2], runs[2:4], test=test)
            root = tmp_path_factory.mktemp("proc")
            cat = make_catalog(root, "tiny", "virtual")
            write_outputs(d, cat.diagnose_dir, plots=False)
            html = tmp_path_factory.mktemp("reports")
            assert main(["report", "--datasets", "tiny", "--root", str(root), "--out", str(html),
                         "--notebooks", "diagnosis"]) == 0
            doc = json.loads((cat.diagnose_dir / "diagnosis.json").read_text())
            ts = cat.diagnose_dir / "test_series.parquet"
            out[mode] = (doc, (html / "diagnosis-tiny.html").read_text(encoding="utf-8"),
                         read_frame(ts)[0] if ts.exists() else None)
    finally:
        mp.undo()
    return out


def _visible(page: str) -> tuple[_Visible, str]:
    v = _Visible()
    v.feed(page)
    return v, " ".join(" ".join(v.text).split())


def _said(printed: str, value) -> bool:
    """``printed`` is ``value`` (a number) within the rounding of the digits it shows (at most 4
    significant: diagnosis_text.num)."""
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        return False
    digits = len(re.sub(r"^[-0.]*|e.*$|\.", "", printed)) or 1
    return any(float(f"{value:.{k}g}") == float(printed) for k in range(digits, 5))


def _pct_said(printed: str, value) -> bool:
    return isinstance(value, (int, float)) and f"{100 * value:.0f}" == printed.lstrip("+")


def _leaves(doc, path=""):
    """(key path, number) of every numeric leaf of diagnosis.json."""
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _leaves(v, f"{path}.{k}" if path else str(k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from _leaves(v, f"{path}[{i}]")
    elif isinstance(doc, (int, float)) and not isinstance(doc, bool):
        yield path, doc


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["test runs", "nested leave-one-run-out"])
def test_every_figure_of_the_diagnosis_page_is_its_key(cases, mode):
    doc, page, _ = cases[mode]
    v, text = _visible(page)
    g = doc["gain"]
    other_mode = "nested leave-one-run-out" if mode == "test runs" else "test runs"

    # the honest gain: said wherever it is said (headline, its section, conclusion) from gain.*, with
    # the runs, the mode and the fits its two MAEs are over
    honest = re.compile(
        rf"by {NUM} % \(95 % interval \[{NUM} %, {NUM} %\]\) \(mean free-run MAE psi over the (\d+) runs? no "
        rf"choice has seen \(([a-z -]+)\): {NUM} deg for ([a-z -]+?) -> {NUM} deg for ([a-z ,:-]+?)\)")
    said = honest.findall(text)
    assert len(said) >= 2, text               # the headline and the honest gain's section at least
    for pct, lo, hi, n, m, bm, base_fit, em, model_fit in said:
        assert _pct_said(pct, abs(g["mae_psi_relative_reduction"]))
        assert _pct_said(lo, g["interval_95"][0]) and _pct_said(hi, g["interval_95"][1])
        assert int(n) == len(g["measured_on"]) and m == mode
        assert _said(bm, g["baseline_mae_psi_deg"]) and _said(em, g["extended_mae_psi_deg"])
        if mode == "test runs":
            assert base_fit == "the linear baseline refitted on all training and validation runs"
        else:
            assert base_fit == "the linear baseline fitted without the held-out run"
            assert model_fit == "the model each selection chose without the held-out run"
    # an interval holds its point: the honest gain's, every ladder rung's, and against the other fit
    ivs = [(g["mae_psi_relative_reduction"], g["interval_95"])]
    ag = g.get("against_other_linear") or {}
    if ag.get("interval_95"):
        ivs.append((ag["mae_psi_relative_reduction"], ag["interval_95"]))
    base_test = doc["ladder"][0].get("test_mae_psi_deg")
    for rung in doc["ladder"][1:]:
        if rung.get("test_interval_95"):
            ivs.append((1.0 - rung["test_mae_psi_deg"] / base_test, rung["test_interval_95"]))
    for point, (lo, hi) in ivs:
        assert lo <= point <= hi, (point, lo, hi)

    # each run's MAE says its run and its fit: the honest gain's runs from gain.per_run ...
    rows = v.table("The runs the honest gain is measured on")
    per = {p["run_id"]: p for p in g["per_run"]}
    assert sorted(r[0] for r in rows) == sorted(per)
    for run, b, e, _gain in rows:
        assert _said(b, per[run]["baseline_mae_psi_deg"]) and _said(e, per[run]["extended_mae_psi_deg"])
    headers = "baseline fitted without it, MAE psi (deg)" if mode != "test runs" else \
        "baseline refitted on all selection runs, MAE psi (deg)"
    assert headers in text
    # ... and each validation run's from baseline.per_run / extended.per_run, the first fold's fits
    caption = re.compile(rf"Validation run (\S+): .*?linear baseline \(blue dashed, MAE psi on this run "
                         rf"{NUM} deg\) and the extended model \(red, MAE psi on this run {NUM} deg\), "
                         r"both the first fold's fits on the training runs \(([^)]*)\)")
    caps = caption.findall(text)
    assert len(caps) == len(doc["validation_runs"])
    base_runs = {p["run_id"]: p for p in doc["baseline"]["per_run"]}
    ext_runs = {p["run_id"]: p for p in doc["extended"]["per_run"]}
    for run, b, e, trained in caps:
        assert _said(b, base_runs[run]["mae_psi_deg"]) and _said(e, ext_runs[run]["mae_psi_deg"])
        assert trained == ", ".join(doc["training_runs"])
    # ... and with test runs each test run's from gain.per_run, both models refitted on all selection runs
    test_caption = re.compile(rf"Test run (\S+): .*?linear baseline refitted on all training and validation "
                              rf"runs \(blue dashed, MAE psi on this run {NUM} deg\) and the extended model "
                              rf"refitted on them \(red, MAE psi on this run {NUM} deg\)\. "
                              r"No choice saw this run")
    test_caps = test_caption.findall(text)
    assert len(test_caps) == (len(doc["test_runs"]) if mode == "test runs" else 0), text
    for run, b, e in test_caps:
        assert _said(b, per[run]["baseline_mae_psi_deg"]) and _said(e, per[run]["extended_mae_psi_deg"])
    if mode != "test runs":
        assert "No test runs were given: the honest gain is the nested leave-one-run-out" in text
    # the selection's pooled baseline MAE (the ladder's first rung), said as such
    pooled = re.findall(rf"held-out heading error is {NUM} deg on the validation runs \(the mean over the "
                        r"folds", text)
    assert pooled and all(_said(x, doc["ladder"][0]["validation_mae_psi_deg"]) for x in pooled)

    # the reference fit under the honest gain's protocol (nested mode): the same held-out runs and the
    # same baseline figures as gain.*, its pooled MAE the mean of the held-out selections' entries, its
    # interval holding its point, and the page's sentence from those keys
    ref = doc["reference"]
    if mode == "test runs":
        assert ref.get("nested_mae_psi_deg") is None and ref.get("nested_measured_on") in (None, [])
    else:
        assert ref["computed"], ref        # the 1 deg offset leaves the linear baseline inadequate
        assert ref["nested_measured_on"] == g["measured_on"]
        assert ref["nested_baseline_mae_psi_deg"] == pytest.approx(g["baseline_mae_psi_deg"], rel=1e-12)
        assert ref["nested_mae_psi_deg"] == pytest.approx(
            sum(e["reference_mae_psi_deg"] for e in g["nested"]) / len(g["nested"]), rel=1e-12)
        lo, hi = ref["nested_interval_95"]
        assert lo <= ref["nested_mae_psi_relative_reduction"] <= hi
        said_ref = re.findall(
            r"Under the honest gain's protocol \(nested leave-one-run-out: refitted without each run and "
            rf"measured on it, (\d+) runs\), the reference cuts the heading error by {NUM} % \(95 % interval "
            rf"\[{NUM} %, {NUM} %\]\) \({NUM} deg -> {NUM} deg\)", text)
        assert said_ref, text
        for n, pct, lo_, hi_, bm, rm in said_ref:
            assert int(n) == len(g["measured_on"])
            assert _pct_said(pct, ref["nested_mae_psi_relative_reduction"])
            assert _pct_said(lo_, lo) and _pct_said(hi_, hi)
            assert _said(bm, g["baseline_mae_psi_deg"]) and _said(rm, ref["nested_mae_psi_deg"])

    # the words follow the mode actually used
    assert f"({other_mode})" not in text
    if mode == "test runs":
        assert "held out in turn" not in text and "repeated without each run" not in text
    else:
        assert "(each run held out in turn)" in text

    # no other figure: every deg and % of the sentences about errors and gains is some key's value
    leaves = list(_leaves(doc))
    sentences = [s for s in re.split(r"(?<=[a-z)\]])\. ", text) if "MAE" in s or "heading error" in s]
    assert sentences
    for s in sentences:
        for x in re.findall(rf"(?<![\w.]){NUM} deg(?![/^\w])", s):
            assert any(_said(x, val) for _, val in leaves), (x, s)
        for x in re.findall(r"(?<![\w.])([+-]?\d+) %", s):
            if x == "95":               # the interval's level, not a figure
                continue
            assert any(_pct_said(x, abs(val)) or _pct_said(x, val) for _, val in leaves), (x, s)


def test_the_gain_interval_holds_its_point_on_runs_of_unequal_length():
    """Known answer: a long run (1000 samples) where the extension cuts the heading error from 1 to
    0.1 deg, a short one (100 samples) where it cuts 10 to 9 deg.  The gain of the mean MAEs is
    1 - 4.55 / 5.5 = 17.3 %; error pooled sample by sample would say 50 %, and a bootstrap of that
    statistic gave the interval [29 %, 90 %], above its point (as was seen on measured zigzags beside
    longer turning circles).  The bootstrap resamples the point's own statistic, so its interval holds
    it: [11 %, 90 %] (wide: the short run has two blocks)."""
    import numpy as np

    from pipeline.config import DiagnoseConfig
    from pipeline.diagnose.core import _pair_gain
    from pipeline.diagnose.fit import Series

    rng = np.random.default_rng(3)
    series, pb, pe = [], [], []
    for name, n, b, e in (("long", 1000, 1.0, 0.1), ("short", 100, 10.0, 9.0)):
        t = np.arange(n) * 0.1
        s = Series(name, t, np.zeros(n), np.zeros(n), np.zeros(n))
        series.append(s)
        for out, err in ((pb, b), (pe, e)):
            sim = np.zeros((n, 3))
            sim[:, 2] = err * (1.0 + 0.2 * rng.standard_normal(n))
            out.append({"sim": sim, "mae_psi_deg": float(np.mean(np.abs(sim[:, 2])))})
    g, (lo, hi), bm, em = _pair_gain([(series, pb, pe)], DiagnoseConfig(), block_s=5.0)
    assert g == pytest.approx(1.0 - em / bm) and g == pytest.approx(1.0 - 4.55 / 5.5, abs=0.02)
    assert lo <= g <= hi


@pytest.mark.slow
def test_the_test_runs_drawn_are_the_free_runs_the_honest_gain_is_measured_on(cases):
    """test_series.parquet holds every test run and only them, and each model's MAE psi over its series
    is gain.per_run's figure for that run (the traces drawn are the ones measured); the nested case
    writes none."""
    import numpy as np

    doc, _, ts = cases["test runs"]
    assert ts is not None and sorted(set(ts.run_id)) == sorted(doc["test_runs"])
    for p in doc["gain"]["per_run"]:
        g = ts[ts.run_id == p["run_id"]]
        assert np.mean(np.abs(g.psi_baseline - g.psi)) == pytest.approx(p["baseline_mae_psi_deg"], rel=1e-12)
        assert np.mean(np.abs(g.psi_extended - g.psi)) == pytest.approx(p["extended_mae_psi_deg"], rel=1e-12)
        assert np.all(np.diff(g.time) > 0)
    assert cases["nested leave-one-run-out"][2] is None
