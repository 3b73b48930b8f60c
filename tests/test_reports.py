"""Reports: notebooks executed with papermill and rendered to self-contained HTML.

The stage outputs are written here in the schemas of pipeline/catalog.py from a small simulated
truth (the paper's Table 4 model driven by a zigzag rudder), so the test does not depend on the
other stages' code; the rendered HTML is then checked for its figures, tables and banner.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

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
                           "per step (us)", "forgetting factor", "residual", "Conclusion"]),
    "indices": (2, ["K (1/s)", "T1 (s)", "K' (-)", "T' (-)", "1st overshoot (deg)", "period (s)",
                    "first overshoot", "Autopilot designed from", "Conclusion"]),
    "control": (1, ["Kp", "rise time (s)", "paper", "wave seed", "Designed from", "Conclusion"]),
    "diagnosis": (1, ["held-out gain (%)", "rudder offset", "61 %", "extended: rudder offset", "Conclusion"]),
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_diagnosis_report_shows_ladder_physics_and_honest_gain(tmp_path):
    """Issue 11's keys, when present, are rendered; today's diagnosis.json (without them) renders too
    (the catalog test above)."""
    root = tmp_path / "proc"
    make_catalog(root, "tiny", "virtual", rich_diagnosis=True)
    out = tmp_path / "reports"
    assert main(["report", "--datasets", "tiny", "--root", str(root), "--out", str(out),
                 "--notebooks", "diagnosis"]) == 0
    page = (out / "diagnosis-tiny.html").read_text(encoding="utf-8")
    for text in ("model ladder", "linear + offset", "[1.4, 2.1]", "95 % interval [48 %, 70 %]",
                 "zz10-test", "neutral angle is 1.5 deg to port", "material", "stability across folds",
                 "folds agreeing: 2", "Conclusion"):
        assert text in page, text
    (concl,) = re.findall(r"class=.conclusion.[^>]*>(.*?)</div>", page, flags=re.S)
    assert "61 %" in concl and "zz10-test" in concl
    assert "None" not in concl and "{" not in concl          # no raw dicts, no None


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
