"""The Python API (docs/api.md): a stage run in this process writes the same bytes as the command
line; settings are values checked before anything runs; the run design is the diagnose package's."""

from __future__ import annotations

import doctest
import shutil
from pathlib import Path

import pytest

import pipeline
from pipeline.cli import main
from pipeline.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
CLEAN = ROOT / "tests" / "data" / "probes" / "clean.csv"


def test_the_stages_in_build_order_and_the_build_uses_them():
    from pipeline import build

    assert pipeline.stages() == ("tank", "ingest", "identify", "validate", "indices", "control", "diagnose")
    assert [s.name for s in build.STAGES] == list(pipeline.stages()[1:])


@pytest.mark.parametrize("call,words", [
    (lambda: pipeline.run("fit", "virtual"), "unknown stage 'fit' (known: tank, ingest,"),
    (lambda: pipeline.run("identify", "virtual", algoritm="srukf-ffm"),
     "identify: unknown option 'algoritm'"),
    (lambda: pipeline.run("identify", "virtual", algorithm="ukf"),
     "identify: option algorithm: 'ukf' is not one of srukf-ffm, ffm-ukf"),
    (lambda: pipeline.run("diagnose", "virtual", no_plots="yes"), "diagnose: option no_plots is a switch"),
    (lambda: pipeline.run("tank", "virtual"), "tank takes no dataset"),
    (lambda: pipeline.run("tank"), "tank: option out is required"),
    (lambda: pipeline.run("identify", "virtual", samples="many"), "identify: option samples: 'many' is not"),
])
def test_bad_settings_are_refused_before_anything_runs(call, words, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError) as err:
        call()
    assert str(err.value).startswith(words), str(err.value)
    assert not any(tmp_path.iterdir())                      # nothing written


def test_a_stage_in_process_writes_the_command_lines_bytes(tmp_path, capsys):
    """ingest through the API, then through the command line into the same place, on a dataset called
    ``-dash`` (an option to a parser, a name here): the same files, byte for byte; the result lists them
    and the lines the stage said; a refused input is the InputError whose words the command line
    prints after ``error:``, and the earlier set stays as it was."""
    raw, root = tmp_path / "raw", tmp_path / "proc"
    (raw / "-dash").mkdir(parents=True)
    shutil.copy(CLEAN, raw / "-dash" / "zz.csv")
    (raw / "-dash" / "dataset.toml").write_text("[data]\nscale = 1\n")
    res = pipeline.run("ingest", "-dash", root=root, raw=raw)
    assert capsys.readouterr().out == ""                     # kept in res.log, not printed (echo off)
    assert res.stage == "ingest" and res.dataset == "-dash"
    assert res.folder == root / "-dash" / "runs"
    assert [p.name for p in res.files] == ["index.json", "zz.parquet"]
    assert res.json("index.json")["dataset"] == "-dash"
    with pytest.raises(InputError, match="wrote no 'nothing.json'"):
        res.path("nothing.json")
    by_api = {p.name: p.read_bytes() for p in res.files}
    shutil.rmtree(root)
    assert main(["ingest", "--dataset=-dash", f"--root={root}", f"--raw={raw}"]) == 0
    assert res.log == tuple(capsys.readouterr().out.splitlines())
    assert {p.name: p.read_bytes() for p in pipeline.api.result_files(res.folder)} == by_api
    # a refusal: the command line's one line is the API's error
    (raw / "-dash" / "zz.csv").write_text("time,psi,r,delta\n0,0,0,oops\n")
    with pytest.raises(InputError) as err:
        pipeline.run("ingest", "-dash", root=root, raw=raw)
    assert main(["ingest", "--dataset=-dash", f"--root={root}", f"--raw={raw}"]) == 2
    assert capsys.readouterr().err.strip() == f"error: {err.value}"
    assert {p.name: p.read_bytes() for p in pipeline.api.result_files(res.folder)} == by_api


def test_the_docs_examples_run(monkeypatch, tmp_path):
    """docs/api.md's examples, as a user would type them (doctest)."""
    monkeypatch.chdir(tmp_path)
    failed, tried = doctest.testfile(str(ROOT / "docs" / "api.md"), module_relative=False,
                                     optionflags=doctest.ELLIPSIS)
    assert tried >= 15 and failed == 0


def test_the_run_design_lives_in_the_diagnose_package():
    """The catalog design is importable from pipeline.diagnose.design (the command line re-exports it
    for one release); twins are rudder amplitudes within DiagnoseConfig.twin_tolerance, not the speed
    tolerance: 10 and 12 deg (2 deg, 17 % of the larger) are twins at a tolerance of 0.2 and not at the
    default."""
    import pipeline.cli.diagnose as cli
    from pipeline.config import DiagnoseConfig
    from pipeline.diagnose import design

    assert cli.pick_catalog_runs is design.pick_catalog_runs and cli.pick_zigzags is design.pick_zigzags
    assert DiagnoseConfig().twin_tolerance == 0.15

    def e(rid, a, side):
        return {"run_id": rid, "kind": "zigzag", "rudder_deg": a, "heading_deg": 10, "first_side": side}

    three = [e("a", 10.0, "starboard"), e("b", 12.0, "port"), e("c", 30.0, "starboard")]
    # no twin: the extremes of amplitude train, the other validates
    assert design.pick_catalog_runs(three) == (["a", "c"], ["b"], [])
    # a twin (10, 12): the larger rudder trains, its twin validates; the 30 deg run is a test run
    assert design.pick_catalog_runs(three, twin_tolerance=0.2) == (["b"], ["a"], ["c"])
    assert design.extrapolated(three, ["b", "a"], ["c"]) == ["c"]
