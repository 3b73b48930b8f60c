"""Reports: notebooks executed with papermill and rendered to self-contained HTML.

The stage outputs are written here in the schemas of pipeline/catalog.py from a small simulated
truth (the paper's Table 4 model driven by a zigzag rudder), so the test does not depend on the
other stages' code; the rendered HTML is then checked for its figures, tables and banner.
"""

from __future__ import annotations

import json
import re
import sys
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline.catalog import Catalog
from pipeline.cli import main
from pipeline.errors import InputError
from pipeline.io import write_frame

sys.path.insert(0, str(Path(__file__).parent))
from report_catalog import ALGS, make_catalog  # noqa: E402

# ------------------------------------------------------------------------------------------ tests
IMG = re.compile(r"<img[^>]+src=\"data:image/png;base64,")


CONTENT = {   # notebook: (least number of embedded PNG figures, texts the page must hold)
    "identification": (6, ["paper MSE v", "MAE psi", "Table 5", "Table 6", "paper Table 4",
                           "timing.json", "forgetting factor", "residual", "Conclusion"]),
    "indices": (2, ["K (1/s)", "T1 (s)", "K' (-)", "T' (-)", "1st overshoot (deg)", "period (s)",
                    "first overshoot", "Autopilot designed from", "Conclusion"]),
    "control": (1, ["Kp", "rise time (s)", "paper", "wave seed", "Designed from", "Conclusion"]),
    "diagnosis": (3, ["held-out gain", "rudder offset", "cuts the heading error by 61 %", "The model ladder",
                      "Every effect tried", "course stability", "Conclusion"]),
}


@pytest.mark.slow
def test_reports_render_with_figures_tables_banner(tmp_path):
    """All four notebooks on a tiny virtual dataset (one test, so xdist renders them once)."""
    root = tmp_path / "proc"
    make_catalog(root, "tiny", "virtual")
    out = tmp_path / "reports"
    assert main(["report", "--datasets", "tiny", "--root", str(root), "--out", str(out)]) == 0
    for notebook, (min_figs, texts) in CONTENT.items():
        page = (out / f"{notebook}-tiny.html").read_text(encoding="utf-8")
        assert len(IMG.findall(page)) >= min_figs, notebook
        assert "VIRTUAL TANK: simulated data, NOT measured" in page, notebook
        assert page.count("<table") >= 3, notebook
        assert "zz20.csv" in page and "SHA-256" in page, notebook   # provenance: source files
        for text in texts:
            assert text in page, (notebook, text)
        # self-contained: nothing fetched from the network; code hidden by default
        assert not re.search(r"""(?:src|href)=["']?(?:https?:)?//""", page), notebook
        assert "body:not(.show-code)" in page
        assert "Traceback" not in page, notebook
    index = (out / "index.html").read_text()
    for notebook in CONTENT:
        assert f"href='{notebook}-tiny.html'" in index
    assert "VIRTUAL TANK" in index and index.count("<li>") == 4
    assert (out / "identification-tiny.html").stat().st_mode & 0o044   # readable by others


def test_missing_stage_output_is_one_clear_line(tmp_path, capsys):
    root = tmp_path / "proc"
    cat = make_catalog(root, "tiny", "measured")
    (cat.control_dir / "timeseries.parquet").unlink()
    out = tmp_path / "reports"
    code = main(["report", "--datasets", "tiny", "--root", str(root), "--out", str(out),
                 "--notebooks", "indices", "control"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1
    assert "timeseries.parquet" in err and "control" in err
    assert not out.exists() or not list(out.glob("*.html"))   # nothing rendered, nothing partial


@pytest.mark.slow
def test_bad_stage_output_fails_in_one_line(tmp_path, capsys):
    """A stage output without a contracted column: the notebook's InputError, one line, no HTML."""
    root = tmp_path / "proc"
    cat = make_catalog(root, "tiny", "virtual")
    path = cat.diagnose_dir / "series.parquet"
    frame = pd.read_parquet(path).drop(columns=["psi"])
    write_frame(path, frame)
    out = tmp_path / "reports"
    code = main(["report", "--datasets", "tiny", "--root", str(root), "--out", str(out),
                 "--notebooks", "diagnosis"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1, err
    assert "diagnosis.py" in err and "series.parquet" in err and "'psi'" in err
    assert not (out / "diagnosis-tiny.html").exists()


def test_missing_dataset_names_runs_index(tmp_path):
    from pipeline.report import check_inputs

    with pytest.raises(InputError, match=r"runs[/\\]index\.json"):
        check_inputs("identification", Catalog(root=tmp_path, dataset="nothing"))


@pytest.mark.parametrize("roles,notebook,why", [
    ({}, "identification", "has no zigzag run and its dataset.toml names no [roles] identify, so the "
                           "identify stage does not run"),
    ({"identify": "c35s"}, "indices", "has no zigzag run, so the indices stage does not run"),
])
def test_a_stage_that_cannot_run_on_the_data_is_named(tmp_path, roles, notebook, why):
    """A dataset of turning circles only: the report says the stage cannot run on it (not "run it
    first", which repeats the stage's own refusal; found 2026-11-26 on a user's circles-only set)."""
    from pipeline.io import write_json
    from pipeline.report import check_inputs

    cat = Catalog(root=tmp_path, dataset="circles")
    write_json(cat.runs_index, {"dataset": "circles", "roles": roles,
                                "runs": [{"run_id": "c35s", "kind": "turning"}]})
    with pytest.raises(InputError) as exc:
        check_inputs(notebook, cat)
    assert why in str(exc.value) and "--notebooks diagnosis" in str(exc.value), exc.value
    # with a zigzag among the runs the stage could run: the old hint stands
    write_json(cat.runs_index, {"dataset": "circles", "runs": [{"run_id": "z", "kind": "zigzag"}]})
    with pytest.raises(InputError, match=r"run `python -m pipeline \w+ --dataset circles` first"):
        check_inputs(notebook, cat)


def test_kernel_points_at_this_python():
    from jupyter_client.kernelspec import KernelSpecManager

    from pipeline.report import ensure_kernel

    ensure_kernel()
    spec = KernelSpecManager().get_kernel_spec("tanktest")
    assert Path(spec.argv[0]).parent.absolute() == Path(sys.executable).parent.absolute()


def test_missing_kernel_is_installed_from_this_python():
    """The kernelspec is installed with sys.executable (never the first python on PATH)."""
    from pipeline.errors import PipelineError
    from pipeline.report import ensure_kernel

    calls = []
    with pytest.raises(PipelineError, match="still missing"):
        ensure_kernel("tanktest-absent-kernel-for-test", install=calls.append)   # installs nothing
    assert len(calls) == 1
    cmd = calls[0]
    assert cmd[0] == sys.executable
    assert cmd[1:4] == ["-m", "ipykernel", "install"] and "--sys-prefix" in cmd


@pytest.mark.long     # CI cut: test_reports_render_with_figures_tables_banner (every page, a tiny catalog)
def test_reports_from_the_real_stages(tmp_path):
    """End to end on a tiny virtual-tank dataset: the real stage commands, then three reports.

    (The diagnosis report is covered by the catalog-schema test above; running the diagnose stage
    here would double this test's time.)
    """
    from pipeline import tank

    raw, root, out = tmp_path / "raw", tmp_path / "proc", tmp_path / "reports"
    raw.mkdir()
    for rud, side, tag in ((20, "starboard", "20_20_S"), (10, "starboard", "10_10_S")):
        run = tank.simulate(tank.zigzag(rud, rud, side, duration=80.0))
        tank.write_csv(raw / f"kcs_zigzag_{tag}.csv", run)
    d = ["--dataset", "e2e", "--root", str(root)]
    assert main(["ingest", *sorted(map(str, raw.glob("*.csv"))), "--out", str(root / "e2e" / "runs"),
                 "--dataset", "e2e"]) == 0
    for alg in ALGS:
        assert main(["identify", *d, "--algorithm", alg]) == 0
    assert main(["validate", *d]) == 0
    assert main(["indices", *d]) == 0
    assert main(["control", *d, "--seeds", "2", "--plants", "nomoto"]) == 0
    assert main(["report", "--datasets", "e2e", "--root", str(root), "--out", str(out),
                 "--notebooks", "identification", "indices", "control"]) == 0
    for notebook, (min_figs, _) in CONTENT.items():
        if notebook == "diagnosis":
            continue
        page = (out / f"{notebook}-e2e.html").read_text(encoding="utf-8")
        assert len(IMG.findall(page)) >= min(min_figs, 3), notebook
        assert "VIRTUAL TANK: simulated data, NOT measured" in page
        assert "kcs_zigzag_20_20_S.csv" in page
    ident = (out / "identification-e2e.html").read_text(encoding="utf-8")
    assert "Table 5" in ident and "Table 6" in ident and "paper Table 4" in ident


class _Visible(HTMLParser):
    """The text a reader sees (hidden code cells, styles and scripts left out) and every table as
    (caption, rows of cell texts), from a rendered report."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.text: list[str] = []
        self.tables: list[tuple[str, list[list[str]]]] = []
        self._hidden = 0          # depth inside a code cell's input wrapper
        self._divs: list[bool] = []
        self._skip = 0
        self._cell: list[str] | None = None
        self._row: list[str] | None = None
        self._caption: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        cls = dict(attrs).get("class") or ""
        if tag == "div":
            hide = "jp-Cell-inputWrapper" in cls
            self._divs.append(hide)
            self._hidden += hide
        elif tag in ("style", "script"):
            self._skip += 1
        elif tag == "table" and not self._hidden:
            self.tables.append(("", []))
        elif tag == "caption":
            self._caption = []
        elif tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag == "div" and self._divs:
            self._hidden -= self._divs.pop()
        elif tag in ("style", "script"):
            self._skip -= 1
        elif tag == "caption" and self._caption is not None and self.tables:
            self.tables[-1] = ("".join(self._caption).strip(), self.tables[-1][1])
            self._caption = None
        elif tag in ("td", "th") and self._cell is not None and self._row is not None:
            self._row.append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "tr" and self._row is not None and self.tables and not self._hidden:
            self.tables[-1][1].append(self._row)
            self._row = None

    def handle_data(self, data):
        if self._hidden or self._skip:
            return
        self.text.append(data)
        for buf in (self._cell, self._caption):
            if buf is not None:
                buf.append(data)

    def table(self, caption_start: str) -> list[list[str]]:
        """Body rows (index cell first) of the one table whose caption starts with ``caption_start``
        after its number; header rows dropped."""
        (rows,) = [r for c, r in self.tables if re.sub(r"^Table \d+\. ", "", c).startswith(caption_start)]
        # pandas writes two header rows: column labels (first cell empty) and the index name (only
        # the first cell filled); body rows have their index label and at least one value
        return [r for r in rows if r and r[0] and any(r[1:])]


def _render_diagnosis(root, out):
    """Render the 'tiny' dataset's diagnosis report: (page HTML, its visible-text parser, the visible
    text on one line)."""
    assert main(["report", "--datasets", "tiny", "--root", str(root), "--out", str(out),
                 "--notebooks", "diagnosis"]) == 0
    page = (out / "diagnosis-tiny.html").read_text(encoding="utf-8")
    v = _Visible()
    v.feed(page)
    return page, v, " ".join(" ".join(v.text).split())


@pytest.mark.long     # CI cut: test_reports_render_with_figures_tables_banner's diagnosis page
def test_diagnosis_report_shows_ladder_physics_and_honest_gain(tmp_path):
    """The full diagnosis.json of the stage (report_catalog.rich_diagnosis_doc): the ladder table holds
    the stage's ladder row by row, in order; the named effects are read physically with units; every
    effect has its verdict, sorted as the caption says; a course-unstable fold is reported; the honest
    gain carries its interval and test run; no raw dict, None or internal effect name is shown."""
    from report_catalog import RICH_TEST_SUFFIX, rich_diagnosis_doc

    root = tmp_path / "proc"
    make_catalog(root, "tiny", "virtual", rich_diagnosis=True)
    doc = rich_diagnosis_doc("zz20", "zz10")
    out = tmp_path / "reports"
    page, v, text = _render_diagnosis(root, out)

    # the runs the design left out, with the reason
    assert f"Not used: zz20_slow ({doc['runs_not_used']['zz20_slow']})." in text
    # the ladder: one row per rung of diagnosis.json, in its order, with its numbers
    ladder = v.table("The model ladder")
    assert len(ladder) == len(doc["ladder"])
    base_test = doc["ladder"][0]["test_mae_psi_deg"]
    for i, (row, rung) in enumerate(zip(ladder, doc["ladder"], strict=True)):
        step, model, effects, val, test, gain, iv = row
        assert step == str(i)
        assert val == f"{rung['validation_mae_psi_deg']:.4g}" and test == f"{rung['test_mae_psi_deg']:.4g}"
        if i == 0:
            assert model == "linear baseline" and effects == "none" and gain == "" and iv == ""
        else:
            added = rung["model"].lstrip("+")
            assert model == "adds " + added.replace("_", " ")
            assert gain == f"{100 * (1 - rung['test_mae_psi_deg'] / base_test):+.0f} %"
            lo, hi = rung["test_interval_95"]
            assert iv == f"[{100 * lo:.0f} %, {100 * hi:.0f} %]"        # a gain interval, in %
    assert ladder[2][2] == "rudder offset + nonlinear yaw damping"

    # every effect: named first, then by verdict, each verdict by held-out gain (the caption's order)
    verdicts = [(r[0], r[1]) for r in v.table("Every effect of the catalogue")]
    assert verdicts == [("rudder offset", "named"), ("nonlinear yaw damping", "named"),
                        ("rudder asymmetry (port/starboard)", "immaterial"),
                        ("sway-yaw cross terms", "immaterial"), ("speed loss in turns", "failed a fold"),
                        ("rudder dead time", "not significant"), ("steering-gear lag", "not tried")]
    assert "-2000 % (diverges)" in text
    assert "below its physical floor (|asymmetry| 0.4% (floor 3%))" in text
    assert "worse in a fold (per fold +30 %, -5 %)" in text
    assert "block t = 1.2 below 1.7 (21 dof)" in text

    # physical words with units; the offset's consequence in numbers (b21 x offset = 0.075 deg/s^2)
    assert "the rudder's neutral angle is 1.5 deg to port of the logged zero" in text
    assert "n_rrr (s/deg^2) = -0.02" in text
    assert "1.5 deg of rudder to port, a yaw acceleration of 0.075 deg/s^2" in text
    assert "offset (deg) = -1.5 +- 0.05" in text
    # the named damping's rival (select's one-standard-error tie), without the offset/asymmetry hint
    told = [text[i:i + 500] for i in range(len(text)) if text.startswith("Not told apart from:", i)]
    assert len(told) == 2, told
    # the offset's rival: an asymmetry, with what separates the two; the damping's: without that hint
    assert "rudder asymmetry (port/starboard) (+52 %)" in told[0], told[0]
    assert "a straight run at zero rudder" in told[0], told[0]
    assert "(+14 %)" in told[1] and "Runs that separate them would decide." in told[1], told[1]

    # stability: fold 2's baseline is course-unstable and says so, with its pole
    stab = v.table("Course stability of the fitted models")
    assert stab[0][-1].startswith("course-stable") and stab[1][-1].startswith("course-UNSTABLE")
    assert "1 of 2 name the same cause" in text

    # the honest gain, its interval, the run it is measured on
    test_run = "zz10" + RICH_TEST_SUFFIX
    assert "cuts the heading error by 61 % (95 % interval [48 %, 70 %])" in text
    assert v.table("The runs the honest gain")[0][0] == test_run

    # no raw dicts, None or internal names anywhere a reader looks
    for bad in ("None", "{'", "rudder_offset", "nonlinear_yaw_damping", "n_rrr_s_per_deg2", "nan"):
        assert not re.search(rf"(?<![\w_]){re.escape(bad)}(?![\w_])", text), bad
    (concl,) = re.findall(r"class=.conclusion.[^>]*>(.*?)</div>", page, flags=re.S)
    assert "61 %" in concl and test_run in concl
    # the cause's rival is in the conclusion too
    assert "hardly told it from rudder asymmetry (port/starboard) (+52 %)" in concl, concl
    assert "Flag:" not in text and "Flagged" not in concl      # an interval above zero: no flag

    # a flagged honest gain (diagnosis.json gain.flag) is said under the headline and in the conclusion
    path = next(root.rglob("diagnosis.json"))
    flagged = json.loads(path.read_text())
    flagged["gain"].update(mae_psi_relative_reduction=0.01, interval_95=[-0.04, 0.05],
                           flag="the extended model is not shown better than the baseline on the unseen runs")
    path.write_text(json.dumps(flagged))
    page, v, text = _render_diagnosis(root, out)
    assert "Flag: the extended model is not shown better than the baseline on the unseen runs" in text
    (concl,) = re.findall(r"class=.conclusion.[^>]*>(.*?)</div>", page, flags=re.S)
    assert "Flagged: the extended model is not shown better" in concl, concl

    # a verdict of none measured by nested leave-one-run-out, some of whose selections named effects:
    # the gain is theirs, not the linear model's, and the page says so (the stage's own flag,
    # pipeline.diagnose.core._gain_flag), never "the extended model cuts ..." under "Cause: none"
    from pipeline.diagnose.core import _gain_flag
    from pipeline.diagnose.result import Gain

    none = json.loads(path.read_text())
    nested = [{"fold": f"hold out {r}", "effects": eff, "cause": eff[0] if eff else "none",
               "chosen_on": ["zz20", "zz10"], "measured_on": [r], "baseline_mae_psi_deg": 10.0,
               "extended_mae_psi_deg": 10.0 * (1 - g), "gain": g, "baseline_sign_bounds": True,
               "other_linear_mae_psi_deg": None}
              for r, eff, g in (("zz20", ["rudder_offset", "sway_yaw_coupling"], 0.85), ("zz10", [], 0.0))]
    none["gain"].update(mae_psi_relative_reduction=0.45, interval_95=[0.23, 0.65],
                        measured_on=["zz20", "zz10"], method="nested leave-one-run-out", nested=nested,
                        per_run=[{"run_id": n["measured_on"][0], "baseline_mae_psi_deg": 10.0,
                                  "extended_mae_psi_deg": 10.0 * (1 - n["gain"]), "gain": n["gain"]}
                                 for n in nested])
    none["gain"]["flag"] = _gain_flag(Gain.from_json({"against_other_linear": None} | none["gain"]), [])
    none.update(cause="none", ladder=none["ladder"][:1], test_runs=[])   # nested mode: no test runs
    none["extended"].update(effects=[], effect_estimates={})
    for f in none["findings"]:
        f["significant"] = False
    path.write_text(json.dumps(none))
    page, v, text = _render_diagnosis(root, out)
    assert "Cause: none" in text
    assert ("Flag: no effect is named on all the runs, but the selection repeated without each run named "
            "effects in 1 of 2 (rudder offset + sway-yaw cross terms (1 of 2))") in text
    (concl,) = re.findall(r"class=.conclusion.[^>]*>(.*?)</div>", page, flags=re.S)
    assert "Flagged: no effect is named on all the runs" in concl, concl
    for bad in ("rudder_offset", "sway_yaw_coupling"):        # the catalogue's names read as words
        assert bad not in text, bad
    assert "the model each round chose cuts the heading error by 45 % (95 % interval [23 %, 65 %])" in text
    assert "the extended model cuts" not in text
    rows = {r[0]: r[-1] for r in v.table("The runs the honest gain")}
    assert rows == {"zz20": "+85 %", "zz10": "+0 %"}, rows
    assert "chosen without it, MAE psi (deg)" in text and "extended MAE psi (deg)" not in text


def test_diagnosis_words_and_verdicts():
    """The report's reading of diagnosis.json: known answers, without rendering."""
    from report_catalog import rich_diagnosis_doc

    from pipeline.report import diagnosis_text as dt

    doc = rich_diagnosis_doc("a", "b")
    got = {f["effect"]: dt.verdict(f, doc["settings"])[0] for f in doc["findings"]}
    assert got == {"rudder_offset": "named", "nonlinear_yaw_damping": "named",
                   "rudder_asymmetry": "immaterial", "speed_loss": "failed a fold",
                   "rudder_delay": "not significant",
                   "sway_yaw_coupling": "immaterial", "rudder_lag": "not tried"}
    assert dt.failed_tests(doc["findings"][5], doc["settings"]) == ("immaterial", "failed a fold",
                                                                     "not significant")
    assert dt.failed_tests(doc["findings"][0], doc["settings"]) == ("named",)
    # a named effect the held-out runs could not tell from another says so (select's rivals)
    f = dict(doc["findings"][0], rivals=[{"effect": "rudder_asymmetry", "validation_gain": 0.25}])
    v, why = dt.verdict(f, doc["settings"])
    assert v == "named" and why.endswith(
        "hardly told it from rudder asymmetry (port/starboard) (+25 %), within one standard error")
    assert dt.verdict(dict(doc["findings"][0], rivals=[]), doc["settings"])[1] == \
        "passes every test: gain, every fold, above noise and floor, significant"
    # a gain below the threshold is immaterial even with everything else passing
    f = dict(doc["findings"][4], validation_gain=0.05, validation_gain_folds=[0.04, 0.06], block_t=3.0)
    assert dt.verdict(f, doc["settings"]) == ("immaterial", "held-out gain +5 % below the 10 % threshold")
    # poles: [[-0.3, 0.01], [3, 0.1]] has eigenvalues (-0.2 +- sqrt(0.28)) / 2: +0.1646 1/s
    words = dt.stability_words(doc["folds"][1]["baseline"]["parameters"], False)
    assert words.startswith("course-UNSTABLE: its slowest pole is +0.165 1/s")
    assert "doubles in 4.21 s" in words
    # steady turn of a decoupled model: r = b21 delta / -a22 = 0.1 x 2 / 0.5 = 0.4 deg/s
    diag = {"a11": -1.0, "a12": 0.0, "a21": 0.0, "a22": -0.5, "b11": 0.0, "b21": 0.1}
    assert dt.steady_turn(diag, 2.0) == pytest.approx(0.4)
    assert dt.steady_turn(doc["folds"][1]["baseline"]["parameters"], 2.0) is None    # unstable: none
    assert "to port" in dt.offset_words({"offset_deg": -1.0}, diag)
    assert "0.2 deg/s (12 deg per minute) to starboard" in dt.offset_words({"offset_deg": 1.0}, diag)
    assert dt.gain_sentence(-1.48, [-2.19, -0.41]).startswith("makes the heading error WORSE by 148 %")
    assert dt.gain_text(-20.0) == "-2000 % (diverges)" and dt.gain_text(None) == "n/a"
    # a removal's heading cut: a size up to half a turn, beyond it the divergence in words
    assert dt.cut_text(2.345) == "cut 2.3 deg" and dt.cut_text(None) == "cut n/a"
    assert dt.cut_text(1.2e4).startswith("without it the free run diverges (mean heading error 1.2e+04 deg")
    assert dt.param_label("y_vvr_s_per_m_deg") == "y_vvr (s/(m deg))"
    assert dt.param_label("asymmetry") == "asymmetry (-)"
    assert dt.plain("k n_rrr_s_per_deg2 = 1", ["n_rrr_s_per_deg2"]) == "k n_rrr (s/deg^2) = 1"
    rows = dt.ladder_rows({"ladder": [{"model": "baseline", "effects": []},
                                      {"model": "+rudder_offset-speed_loss", "effects": ["rudder_offset"]}]})
    assert rows[1]["model"] == "adds rudder offset; drops speed loss in turns"
    assert dt.move_words("+rudder_offset+speed_loss+nonlinear_yaw_damping-rudder_lag") == (
        "adds rudder offset, speed loss in turns and " + dt.effect_label("nonlinear_yaw_damping")
        + "; drops " + dt.effect_label("rudder_lag"))
    assert rows[1]["test gain over baseline"] == "n/a"
    cx, my = dt.binned(np.linspace(-1, 1, 200), 2 * np.linspace(-1, 1, 200))
    assert np.allclose(my, 2 * cx, atol=0.02)


def test_reports_rerender_only_what_changed(tmp_path, monkeypatch):
    """`report --changed` (make reports): a page is rendered again only when a stage output it reads,
    its notebook or the report code changed (fingerprint in reports.json)."""
    import importlib

    rr = importlib.import_module("pipeline.report.render")   # the module (the package exports a function)
    root, out = tmp_path / "proc", tmp_path / "reports"
    cat = make_catalog(root, "tiny", "virtual")
    fp = rr.fingerprint("indices", cat)
    write_json_path = cat.diagnose_dir / "diagnosis.json"
    write_json_path.write_text(write_json_path.read_text().replace("rudder_offset", "rudder_delay"))
    assert rr.fingerprint("indices", cat) == fp              # the indices page does not read diagnose/
    calls = []

    def fake_render(nb, c, out_dir, kernel=rr.KERNEL_NAME):
        calls.append(nb)
        dest = Path(out_dir) / f"{nb}-{c.dataset}.html"
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_text("page")
        return rr.Report(nb, c.dataset, dest, 0.1, "virtual", 2, "KCS", rr.fingerprint(nb, c))

    monkeypatch.setattr(rr, "render", fake_render)
    monkeypatch.setattr(rr, "ensure_kernel", lambda kernel: None)
    rr.render_all(["tiny"], ["indices", "diagnosis"], out, root=root, force=False)
    assert calls == ["indices", "diagnosis"]                   # nothing rendered yet: both
    calls.clear()
    reports, _ = rr.render_all(["tiny"], ["indices", "diagnosis"], out, root=root, force=False)
    assert calls == [] and all(r.skipped for r in reports)     # nothing changed: nothing rendered
    idx = cat.indices_dir / "indices.json"
    idx.write_text(idx.read_text().replace("0.3867", "0.3868"))
    rr.render_all(["tiny"], ["indices", "diagnosis"], out, root=root, force=False)
    assert calls == ["indices"]                                # only the page that reads it
    assert "indices-tiny.html" in (out / "index.html").read_text()


@pytest.mark.parametrize("ship, note, builtin", [
    ("KCS", "virtual tank (MMG model of the KCS, SIMMAN 2020 model scale); not measured data", True),
    ("KCS", None, True),
    ("Tanker X", "from our own MMG code", False),
    ("KCS", "CFD free-running simulation, in-house solver", False),
])
def test_banner_names_the_builtin_tank_only_for_its_runs(tmp_path, ship, note, builtin):
    """Simulated runs of a user's own (provenance virtual) are flagged as simulated, NOT measured, but
    not called the built-in KCS tank; the tank's own runs are."""
    import json

    from pipeline.report.nb import Data, banner

    cat = make_catalog(tmp_path, dataset="usersim", provenance="virtual", ship=ship)
    if note is not None:
        idx = json.loads(cat.runs_index.read_text())
        for e in idx["runs"]:
            e["header"] = {"ship": ship, "provenance": "virtual", "note": note}
        cat.runs_index.write_text(json.dumps(idx))
    html = banner(Data(tmp_path, "usersim"), "t").data
    assert "NOT measured" in html
    assert ("built-in virtual tank (3-DOF MMG model of the KCS" in html) is builtin
    assert ("SIMULATED data, NOT measured" in html) is (not builtin)
    if not builtin:
        assert ship in html and "not the built-in KCS tank" in html
    # the figures' legend says the same: a user's simulated runs are not "virtual tank"
    want = "virtual tank (logged)" if builtin else "simulated (logged)"
    assert Data(tmp_path, "usersim").source_label == want


@pytest.mark.parametrize("builtin", [True, False])
def test_index_page_labels_only_the_builtin_tank_virtual_tank(tmp_path, builtin):
    """The reports' index page says VIRTUAL TANK for the built-in tank's dataset only; a user's simulated
    runs are labelled simulated, not the KCS tank (as each page's banner says)."""
    from pipeline.report.render import Report, write_index

    (tmp_path / "identification-sim.html").write_text("<html></html>")
    write_index(tmp_path, [Report("identification", "sim", tmp_path / "identification-sim.html", 1.0,
                                  "virtual", 2, builtin_tank=builtin)])
    page = (tmp_path / "index.html").read_text()
    assert ("VIRTUAL TANK (simulated, not measured)" in page) is builtin
    assert ("SIMULATED data (not measured; not the built-in KCS tank)" in page) is (not builtin)
