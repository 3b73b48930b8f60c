"""Reports say what the user said, at the scale they think in (docs/reports.md, "Scale on the pages").

Two datasets of the same ship are ingested through the real ``ingest`` from a folder with a
``dataset.toml`` (tank, source, provenance, scale): one of full-scale files (KCS, 1:37.89: the virtual
tank's run Froude-scaled up before it is written), one of model-scale files.  The index page must tell
them apart; the identification, indices and control pages of the full-scale one give its tank, source
and provenance and its times also at full scale, and name the paper's ship beside the paper's values.
"""

from __future__ import annotations

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

LAM = 37.89                      # the KCS model's scale (SIMMAN 2020)
KNOT = 1852.0 / 3600.0           # m/s
DATASETS = {   # name: (scale of the files, tank, source)
    "kcs full #1": (LAM, "MARIN", "full-scale logs of the KCS, 2025"),
    "kcs model": (1.0, "HSVA", "model tests, 2024"),
}


def _ingest(base: Path) -> tuple[Path, dict[str, float]]:
    """Ingest both datasets under ``base``; returns the processed root and, per dataset, the approach
    speed (kn, the first sample's u) read from the file as written (before ingest)."""
    from pipeline import tank

    raw, root = base / "raw", base / "proc"
    approach_kn = {}
    for name, (files_scale, tank_name, source) in DATASETS.items():
        folder = raw / name
        folder.mkdir(parents=True)
        frame = tank.simulate(tank.zigzag(20, 20, "starboard", duration=60.0)).frame.copy()
        if files_scale > 1:        # the same run as a full-scale logger would write it (Froude)
            k = math.sqrt(files_scale)
            frame["time"] *= k
            frame["u"] *= k
            frame["v"] *= k
            frame["r"] /= k
            frame["rpm"] /= k
            frame["x0"] *= files_scale
            frame["y0"] *= files_scale
        approach_kn[name] = float(frame["u"].iloc[0]) / KNOT
        with open(folder / "zz20.csv", "w") as fh:
            fh.write("# ship: KCS\n# test: zigzag 20/20 starboard\n")
            frame[["time", "x0", "y0", "psi", "u", "v", "r", "delta", "rpm"]].to_csv(fh, index=False)
        (folder / "dataset.toml").write_text(
            f'[ship]\nname = "KCS"\nlpp_m = 230.0\n\n[data]\nscale = {files_scale}\nmodel_scale = {LAM}\n'
            f'tank = "{tank_name}"\nsource = "{source}"\nprovenance = "measured"\n')
        assert main(["ingest", "--dataset", name, "--raw", str(raw), "--root", str(root)]) == 0
    return root, approach_kn


def test_index_tells_two_datasets_of_one_ship_apart(tmp_path):
    """The facts come from dataset.toml through ingest's runs/index.json (not 'not given'); the index
    page shows, per dataset, ship, scale (with the files' own), tank, source and provenance."""
    from pipeline.report import particulars
    from pipeline.report.render import Report, write_index

    root, approach_kn = _ingest(tmp_path)
    out = tmp_path / "reports"
    out.mkdir()
    reports = []
    for name, (files_scale, tank_name, source) in DATASETS.items():
        index = json.loads((root / name / "runs" / "index.json").read_text())
        p = particulars.particulars(index)
        assert (p["tank"], p["source"], p["provenance"], p["scale"]) == (tank_name, source, "measured", LAM)
        rows = dict(particulars.rows(index))
        assert particulars.NOT_GIVEN not in (rows["tank"], rows["source"], rows["provenance"])
        # full-scale approach speed: the Froude-scaled model speed is the speed the files were written at
        lo = float(re.findall(r"[\d.]+", rows["approach speed, full scale (kn)"])[0])     # one run
        # (to 1 %: the page gives 3 digits, and ingest's approach window is not only the first sample)
        assert lo == pytest.approx(approach_kn[name] * (1 if files_scale > 1 else math.sqrt(LAM)), rel=1e-2)
        assert particulars.full_scale_factor(index) == (LAM if files_scale > 1 else None)
        page = tmp_path / "reports" / f"indices-{name}.html"
        page.write_text("<html></html>")
        reports.append(Report("indices", name, page, 1.0, "measured", 1, ship=particulars.summary(index),
                              identity=particulars.identity(index)))
    write_index(out, reports)
    v = _Visible()
    v.feed((out / "index.html").read_text(encoding="utf-8"))
    ident = [dict(rows) for cap, rows in v.tables]
    assert len(ident) == 2
    full, model = sorted(ident, key=lambda d: d["tank"])[::-1]       # MARIN (full-scale files), HSVA
    assert full == {"ship": "KCS", "scale": "1:37.89 (full-scale files)", "tank": "MARIN",
                    "source": "full-scale logs of the KCS, 2025", "provenance": "measured",
                    "described in": str(tmp_path / "raw" / "kcs full #1" / "dataset.toml")}
    assert (model["scale"], model["tank"], model["source"]) == ("1:37.89 (model-scale files)", "HSVA",
                                                                "model tests, 2024")


@pytest.mark.long     # CI cut: test_full_scale_labels_known_answers (the labels without a render)
def test_full_scale_pages_say_tank_source_and_full_scale_times(tmp_path):
    """The stage outputs of the report catalogue (known model-scale values), described as the full-scale
    dataset's ingest describes it: every page names tank, source and provenance, gives times at model
    and at full scale (t_full = t_model sqrt(37.89)), and names the KCS beside the paper's values."""
    root_ing, _ = _ingest(tmp_path / "ing")
    name = "kcs full #1"
    described = json.loads((root_ing / name / "runs" / "index.json").read_text())["ship"]
    root, out = tmp_path / "proc", tmp_path / "reports"
    cat = make_catalog(root, name, "measured", ship="KVLCC2")      # not the paper's ship
    index = json.loads(cat.runs_index.read_text())
    index["ship"] = dict(described, ship="KVLCC2")
    for e in index["runs"]:
        e["scale_factor"] = LAM
        e["ship"] = "KVLCC2"
    cat.runs_index.write_text(json.dumps(index))
    assert main(["report", "--datasets", name, "--root", str(root), "--out", str(out),
                 "--notebooks", "identification", "indices", "control"]) == 0
    k = math.sqrt(LAM)
    text = {}
    views = {}
    for nb in ("identification", "indices", "control"):
        v = _Visible()
        v.feed((out / f"{nb}-{name}.html").read_text(encoding="utf-8"))
        views[nb] = v
        text[nb] = t = " ".join(" ".join(v.text).split())
        assert "Tank: MARIN" in t and "Source: full-scale logs of the KCS, 2025" in t, nb
        assert "Provenance: measured" in t and f"Described in: {described['dataset_toml']}" in t, nb
        assert "not given" not in t.split("Particulars")[0], nb           # the banner's head
        assert f"t_full = t_model x sqrt(37.89) = t_model x {k:.3g}" in t, nb
        assert "The paper's values are for its ship, the KCS (Meng et al." in t and "KVLCC2" in t, nb
    # identification: the window at both scales; the paper's columns named with its ship
    window = 584 * 0.08                                   # 585 samples at 0.08 s (report catalogue)
    (settings,) = [r for r in views["identification"].tables if any("identification window" in c[0]
                                                                   for c in r[1] if c)]
    rows = {r[0]: r[1] for r in settings[1] if len(r) == 2}
    assert float(rows["identification window, model scale (s)"]) == pytest.approx(window, rel=1e-6)
    assert float(rows["identification window, full scale 1:37.89 (s)"]) == pytest.approx(window * k, rel=1e-5)
    assert "paper (KCS) Table 4" in text["identification"] and "paper (KCS) MSE v" in text["identification"]
    # indices: Table 7's dimensional indices at full scale, the zigzag period at both scales
    ind = json.loads((cat.indices_dir / "indices.json").read_text())["identified"]["srukf-ffm"]
    full = {r[0]: r[1] for r in views["indices"].table("Table 7's dimensional indices")}
    assert float(full["T1, full scale (s)"]) == pytest.approx(ind["T1"]["value"] * k, rel=1e-3)
    assert float(full["K, full scale (1/s)"]) == pytest.approx(ind["K"]["value"] / k, rel=1e-3)
    assert "paper (KCS) Table 7" in text["indices"]
    zrows = views["indices"].table("ITTC 7.5-04-02-01")
    header = [r for c, r in views["indices"].tables if c.startswith("Table") and "ITTC" in c][0][0]
    i_model, i_full = header.index("period, model scale (s)"), header.index("period, full scale (s)")
    assert float(zrows[0][i_model]) == 30.0 and float(zrows[0][i_full]) == pytest.approx(30.0 * k, rel=1e-3)
    # control: the mean rise time (20 s model) at full scale, in its table and the conclusion
    rise = {r[0]: r[1:] for r in views["control"].table("Mean metrics of the table above")}
    assert [float(x) for x in rise["rise time, full scale (s)"]] == pytest.approx([20.0 * k] * 2, rel=1e-3)
    assert f"rise time 20 s model scale, {20.0 * k:.3g} s full scale" in text["control"]
    assert "paper (KCS)" in text["control"]
    designs = {r[0]: r[1:] for r in views["control"].table("The designs' indices")}
    assert [float(x) for x in designs["T, full scale (s)"]] == pytest.approx([3.9 * k, 3.8 * k], rel=1e-3)
    assert [float(x) for x in designs["Tw, full scale (s)"]] == pytest.approx([3.0 * k] * 2, rel=1e-3)
    assert "href='control-kcs%20full%20%231.html'" in (out / "index.html").read_text()


def test_full_scale_labels_known_answers():
    """Froude similarity at scale 49 (sqrt = 7): seconds x 7, rates / 7, m/s x 7 in knots (1852 m per
    3600 s); non-dimensional and angle labels are not converted; a scale that is no scale is refused."""
    from pipeline.report.particulars import full_scale_label, to_full

    assert full_scale_label("rise time (s)", 49.0, 20.0) == ("rise time, full scale (s)",
                                                             pytest.approx(140.0))
    assert full_scale_label("K (1/s)", 49.0, 0.7) == ("K, full scale (1/s)", pytest.approx(0.1))
    assert full_scale_label("steady r (deg/s)", 49.0, 7.0) == ("steady r, full scale (deg/s)",
                                                               pytest.approx(1.0))
    name, kn = full_scale_label("approach (m/s)", 49.0, 1.0)
    assert name == "approach, full scale (kn)" and kn == pytest.approx(7.0 * 3600.0 / 1852.0)
    for lab in ("K' (-)", "max deviation (deg)", "advance (L)", "no unit"):
        assert full_scale_label(lab, 49.0, 1.0) is None, lab
    for bad in (0.0, -4.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="scale"):
            to_full(1.0, "time", bad)
