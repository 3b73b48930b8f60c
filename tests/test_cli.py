"""The command line: no default dataset, no abbreviations, --version, plain help, full paths."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline import __version__
from pipeline.cli import build_parser, main, prog_name

ROOT = Path(__file__).resolve().parents[1]
CATALOG_STAGES = ("identify", "validate", "indices", "control", "diagnose")


@pytest.mark.parametrize("stage", CATALOG_STAGES)
def test_a_stage_without_dataset_refuses_and_writes_nothing(stage, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "data" / "processed" / "virtual").mkdir(parents=True)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    assert main([stage]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"error: {stage}: give --dataset NAME (`python -m pipeline datasets` lists them) or the "
                   "files to work on; there is no default dataset")
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_options_are_never_abbreviated(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["ingest", str(tmp_path / "a.csv"), "--out", str(tmp_path / "o"), "--scal", "45.7"])
    assert exc.value.code == 2
    assert "unrecognized arguments: --scal 45.7" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["identify", "--data", "virtual"])
    assert "unrecognized arguments: --data" in capsys.readouterr().err


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser(prog="tanktest").parse_args(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"tanktest {__version__}"


@pytest.mark.parametrize("stage", ["diagnose", "ingest", "identify", "tank", "run", "control"])
def test_help_is_plain_text(stage, capsys):
    with pytest.raises(SystemExit):
        build_parser(prog="tanktest").parse_args([stage, "--help"])
    out = capsys.readouterr().out
    assert out.startswith(f"usage: tanktest {stage}")
    for markup in ("``", ":func:`", ":class:`", ":meth:`", "**"):
        assert markup not in out, (stage, markup)
    if stage == "diagnose":
        assert "data/processed/D/runs/index.json" in out and "pick_catalog_runs" in out


def test_prog_name_follows_how_it_was_started():
    assert prog_name("/usr/local/bin/tanktest") == "tanktest"
    assert prog_name(str(ROOT / "pipeline" / "__main__.py")) == "python -m pipeline"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-m", "pipeline", "--help"], capture_output=True, text=True,
                         env=env, cwd=ROOT, check=True).stdout
    assert out.startswith("usage: python -m pipeline ")


def test_missing_file_is_named_by_its_full_path(tmp_path, capsys, monkeypatch):
    assert main(["ingest", "/nonexistent/file.dat", "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip() == "error: /nonexistent/file.dat: file not found"
    monkeypatch.chdir(tmp_path)
    assert main(["ingest", "rel.dat", "--out", "o"]) == 2
    assert capsys.readouterr().err.strip() == f"error: {tmp_path / 'rel.dat'}: file not found"
    assert not (tmp_path / "o").exists()


def test_a_missing_run_is_named_by_its_full_path_in_identify_and_diagnose(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["identify", "gone.parquet", "--out", "o"]) == 2
    assert capsys.readouterr().err.strip() == f"error: {tmp_path / 'gone.parquet'}: file not found"
    assert main(["diagnose", "--train", "gone.dat", "--validate", "gone.dat", "--out", "o"]) == 2
    assert capsys.readouterr().err.strip() == f"error: {tmp_path / 'gone.dat'}: file not found"
