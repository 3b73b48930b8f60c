"""The README is run, not only read: its Python example executes, its dataset.toml example ingests the
files it names, and it stays a user's page (docs/index.md says where the rest is)."""

from __future__ import annotations

import contextlib
import io
import re
import tomllib
from pathlib import Path

import pytest

from pipeline.io import read_json

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
TOML_MARK = "# example for ../shared/data/kvlcc2_hsva"


def _blocks(language: str) -> list[str]:
    """The fenced code blocks of README.md in ``language``, in order."""
    return re.findall(rf"^```{language}\n(.*?)^```", README.read_text(encoding="utf-8"), re.S | re.M)


def test_readme_is_short_and_carries_no_dated_history():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines: the rest belongs in docs/"
    dated = [ln for ln in lines if re.search(r"\b20\d\d-\d\d-\d\d\b", ln)]
    assert not dated, f"README.md lines carrying a date (history goes to CHANGELOG.md): {dated}"


def test_readme_python_example_runs_and_agrees_with_the_graphical_method():
    """The example's identified first-order K and T, from the filter, against Nomoto's standard test
    method on the same run (an independent reading of the zigzag's heading extrema, docs/indices.md):
    within 10 %, since both fit one first-order response to the same manoeuvre and differ only in how
    they weigh it.  The first overshoot
    against the independent RK4 reference of the KCS 20/20 zigzag (14.5 deg, docs/virtual-tank.md),
    within the tank tests' +-2 deg."""
    (code,) = [b for b in _blocks("python") if "identify_run" in b]
    namespace: dict = {"__name__": "readme_example"}
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, str(README), "exec"), namespace)
    printed = out.getvalue()
    assert "graphical K" in printed and " K = " in printed
    ident, graphical = namespace["ident"], namespace["graphical"]
    assert ident.algorithm == "srukf-ffm" and ident.samples == 585
    assert namespace["run"].meta["provenance"] == "virtual"
    for name in ("K", "T"):
        identified = namespace["indices"][name]["value"]
        assert identified == pytest.approx(graphical[name], rel=0.10), name
    first = namespace["zigzag_metrics"](namespace["run"])["first_overshoot_deg"]
    assert first == pytest.approx(14.5, abs=2.0)


def test_readme_dataset_toml_example_ingests_the_files_it_names(tmp_path, hsva_dir):
    """The README's dataset.toml, placed as a user would, reads the HSVA files and its [roles] name
    runs exactly as ingest names them (the diagnosis's role design accepts them)."""
    from pipeline.cli import main
    from pipeline.diagnose.design import roles_design

    (text,) = [b for b in _blocks("toml") if b.startswith(TOML_MARK)]
    doc = tomllib.loads(text)
    assert (ROOT / "data" / "raw" / "kvlcc2" / doc["data"]["files_dir"]).resolve() == hsva_dir.resolve()
    # the same description in a temporary raw root: only files_dir (relative to the file) is re-aimed
    folder = tmp_path / "raw" / "kvlcc2"
    folder.mkdir(parents=True)
    aimed = re.sub(r'^files_dir = ".*"$', f'files_dir = "{hsva_dir.as_posix()}"', text, flags=re.M)
    (folder / "dataset.toml").write_text(aimed, encoding="utf-8")
    assert main(["ingest", "--dataset", "kvlcc2", "--raw", str(tmp_path / "raw"),
                 "--root", str(tmp_path / "processed")]) == 0
    index = read_json(tmp_path / "processed" / "kvlcc2" / "runs" / "index.json")
    ids = {e["run_id"] for e in index["runs"]}
    assert ids == {p.stem for p in hsva_dir.glob("*.dat")}
    roles = doc["roles"]
    assert index["roles"]["identify"] == roles["identify"] in ids
    train, validate, test = roles_design(index)
    assert (train, validate, test) == (roles["train"], roles["validate"], roles["test"])
    assert index["ship"]["lpp_model_m"] == pytest.approx(320.0 / 45.7)
    assert index["identify"] == {"half_periods": 3.4}
