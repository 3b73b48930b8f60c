"""make pipeline / pipeline run: names never pass a shell; stages rerun when their inputs or code change.

Names from the user (a folder called ``x$(touch${IFS}X)`` ran ``touch`` during ``make reports``; names
with spaces must not break make); a stage target depends on the code it imports.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from pipeline import build
from pipeline.cli import main

ROOT = Path(__file__).resolve().parents[1]
HOSTILE = "x$(touch${IFS}X)"
SPACED = "my runs"


def _no_x_anywhere(*dirs: Path) -> None:
    for d in dirs:
        assert not [p for p in Path(d).rglob("X")], f"a file X appeared under {d}: a name was executed"


@pytest.mark.skipif(shutil.which("make") is None, reason="GNU make is not installed")
def test_make_passes_no_dataset_name_to_the_shell(tmp_path):
    """The real Makefile, run by make in a temporary copy whose Python only records its arguments."""
    shutil.copy(ROOT / "Makefile", tmp_path / "Makefile")
    (tmp_path / "pyproject.toml").write_text("")
    for name in (HOSTILE, SPACED):
        (tmp_path / "data" / "raw" / name).mkdir(parents=True)
        (tmp_path / "data" / "raw" / name / "zz 20 $(touch X).csv").write_text("time,psi,r,delta\n")
    log = tmp_path / "argv.log"
    py = tmp_path / ".venv" / "bin" / "python"
    py.parent.mkdir(parents=True)
    py.write_text(f"#!/bin/sh\nprintf '%s\\n' \"$@\" >> '{log}'\necho '--' >> '{log}'\n")
    py.chmod(0o755)
    stamp = tmp_path / ".venv" / ".installed"
    stamp.write_text("")
    old = os.path.getmtime(tmp_path / "pyproject.toml") - 10
    os.utime(tmp_path / "pyproject.toml", (old, old))            # the venv is up to date
    env = {**os.environ, "MAKEFLAGS": ""}
    # `make dataset D=...`: shell metacharacters and spaces arrive intact (a `$` is make's own syntax
    # on its command line; folder names with `$` go through `make pipeline`, which never sees them)
    by_hand = ("x;touch X", "x`touch X`", SPACED, "-dash")
    for target in (["pipeline"], ["reports"], ["datasets"], *(["dataset", f"D={n}"] for n in by_hand)):
        res = subprocess.run(["make", "--no-print-directory", *target], cwd=tmp_path, env=env,
                             capture_output=True, text=True, timeout=60)
        assert res.returncode == 0, (target, res.stdout, res.stderr)
    _no_x_anywhere(tmp_path)
    calls = [c.strip("\n").split("\n") for c in log.read_text().split("--\n") if c.strip()]
    assert ["-m", "pipeline", "run", "--all", "--shared", "../shared"] in calls
    assert ["-m", "pipeline", "report", "--all", "--changed", "--out", "reports"] in calls
    # a hostile or spaced name given to `make dataset` arrives as one intact argument
    for name in by_hand:
        assert ["-m", "pipeline", "run", f"--dataset={name}", "--shared", "../shared"] in calls, name


def _write_zigzag(folder: Path, stem: str) -> None:
    from pipeline import tank

    folder.mkdir(parents=True, exist_ok=True)
    tank.write_csv(folder / f"{stem}.csv", tank.simulate(tank.zigzag(20, 20, "starboard", duration=40.0)))


def test_run_ingests_datasets_with_hostile_and_spaced_names(tmp_path, monkeypatch, capsys):
    raw, root = tmp_path / "raw", tmp_path / "proc"
    for name in (HOSTILE, SPACED):
        _write_zigzag(raw / name, "zz 20 $(touch X)")
    monkeypatch.chdir(tmp_path)
    assert main(["run", "--list", "--raw", str(raw), "--shared", str(tmp_path / "none")]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert listed == ["virtual", SPACED, HOSTILE]          # sorted folders after the built-in tank
    code = main(["run", "--dataset", HOSTILE, SPACED, "--raw", str(raw), "--root", str(root),
                 "--shared", str(tmp_path / "none"), "--until", "ingest"])
    assert code == 0
    for name in (HOSTILE, SPACED):
        index = root / name / "runs" / "index.json"
        assert index.is_file(), name
        assert '"run_id": "zz 20 $(touch X)"' in index.read_text()
    _no_x_anywhere(tmp_path)


def test_unknown_dataset_is_one_line(tmp_path, capsys):
    code = main(["run", "--dataset", "nope", "--raw", str(tmp_path), "--shared", str(tmp_path)])
    assert code == 2
    assert "unknown dataset 'nope'" in capsys.readouterr().err


def test_stage_code_dependencies_follow_imports():
    """A stage depends on every pipeline module it imports, directly or not."""
    rel = {str(p.relative_to(build.PACKAGE_DIR)) for p in build.import_closure("pipeline.cli.indices")}
    for f in ("config.py", "model.py", "io.py", "cli/__init__.py", "cli/_common.py", "cli/indices.py",
              "indices/stage.py", "indices/zigzag.py", "runinfo.py", "errors.py"):
        assert f in rel, f
    assert "report/render.py" not in rel and "control/stage.py" not in rel
    ident = {str(p.relative_to(build.PACKAGE_DIR)) for p in build.import_closure("pipeline.cli.identify")}
    assert "identify/srukf.py" in ident and "indices/stage.py" not in ident


def _fake_stages(root: Path, ran: list[str], fail: tuple[str, ...] = ()):
    """A stand-in for the stage commands of dataset 'mine': records each stage in ``ran``, exits 2 for
    the stages in ``fail``, else writes the stage's outputs (its name and a counter)."""
    outputs = {s.name: s.outputs for s in build.STAGES}

    def fake(stage, dataset, options):
        assert dataset == "mine" and options["root"] == root     # names and paths as values
        ran.append(stage)
        if stage in fail:
            return 2
        for o in outputs[stage]:
            p = root / "mine" / o
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_text(f"{stage} {len(ran)}")
        return 0

    return fake


def test_only_stale_stages_rerun(tmp_path, monkeypatch):
    """Fake stage commands (they write a counter into their outputs): nothing reruns when nothing
    changed; a changed raw file reruns everything; a changed module of one stage reruns that stage
    and what reads its outputs, and nothing upstream."""
    raw, root = tmp_path / "raw", tmp_path / "proc"
    (raw / "mine").mkdir(parents=True)
    (raw / "mine" / "a.csv").write_text("time,psi,r,delta\n0,0,0,0\n")
    ds = build.Dataset("mine", raw / "mine")
    ran: list[str] = []
    fake = _fake_stages(root, ran)

    everything = ["ingest", "identify", "validate", "indices", "control", "diagnose"]
    assert build.build_dataset(ds, root, run=fake, say=lambda s: None) == everything
    assert build.build_dataset(ds, root, run=fake, say=lambda s: None) == []
    (raw / "mine" / "a.csv").write_text("time,psi,r,delta\n0,0,0,1\n")
    assert build.build_dataset(ds, root, run=fake, say=lambda s: None) == everything

    extra = tmp_path / "indices_helper.py"
    extra.write_text("X = 1\n")
    real = build.import_closure

    def closure(*mods):
        files = real(*mods)
        return files + [extra] if "pipeline.cli.indices" in mods else files

    monkeypatch.setattr(build, "import_closure", closure)
    assert build.build_dataset(ds, root, run=fake, say=lambda s: None) == ["indices", "control"]
    assert build.build_dataset(ds, root, run=fake, say=lambda s: None) == []
    extra.write_text("X = 2\n")
    assert build.build_dataset(ds, root, run=fake, say=lambda s: None) == ["indices", "control"]


def test_the_build_reads_the_files_the_description_names(tmp_path):
    """`make pipeline` hands ingest the files a dataset.toml names, as `ingest --dataset NAME` reads
    them: from its ``files_dir``, matching its ``files`` globs, without the runs marked ``skip``.
    Found 2026-11-26: the build listed the folder's own top level, so a description pointing at its
    files elsewhere gave "no tank files", and files its globs left out were ingested."""
    from pipeline.dataset import load_dataset

    raw = tmp_path / "raw"
    (raw / "mine").mkdir(parents=True)
    elsewhere = tmp_path / "logger_export"
    elsewhere.mkdir()
    for name in ("zz20_s.csv", "zz10_s.csv", "zz10_p.csv", "calibration.csv"):
        (elsewhere / name).write_text("time,psi,r,delta\n0,0,0,0\n")
    (raw / "mine" / "stray.csv").write_text("time,psi,r,delta\n0,0,0,0\n")
    (raw / "mine" / "dataset.toml").write_text('[data]\nscale = 1\nfiles_dir = "../../logger_export"\n'
                                               'files = ["zz*"]\n\n[runs.zz10_p]\nskip = true\n')
    ds = build.Dataset("mine", raw / "mine")
    names = [p.name for p in build.raw_files(ds)]
    assert names == ["zz10_s.csv", "zz20_s.csv"]
    assert names == [p.name for p in load_dataset("mine", raw, write_missing=False).raw_files()]
    (call,) = build._ingest_calls(ds, tmp_path / "proc")
    assert [Path(a).resolve() for a in call["files"]] == [(elsewhere / n).resolve() for n in names]


def test_the_build_and_ingest_skip_the_same_files(tmp_path):
    """One list of what is not tank data (pipeline.dataset.NOT_TANK_SUFFIXES): a notebook, a script,
    a spreadsheet, a page or a document beside the runs is neither listed by the build nor read by
    ingest, in a user's folder and among files dropped straight into data/raw ('local')."""
    from pipeline.dataset import NOT_TANK_SUFFIXES, is_tank_file

    raw = tmp_path / "raw"
    (raw / "mine").mkdir(parents=True)
    others = ["analysis.ipynb", "plot.py", "log.xlsx", "old.xls", "report.html", "notes.docx", "README.md",
              ".hidden.csv"]
    for folder in (raw / "mine", raw):
        for name in ["zz20_s.csv", *others]:
            (folder / name).write_text("time,psi,r,delta\n0,0,0,0\n")
    assert {Path(n).suffix for n in others if not n.startswith(".")} <= NOT_TANK_SUFFIXES
    for ds in (build.Dataset("mine", raw / "mine"), build.Dataset(build.LOCAL, raw)):
        assert [p.name for p in build.raw_files(ds)] == ["zz20_s.csv"], ds.name
        assert [p.name for p in sorted(ds.raw.iterdir()) if p.is_file() and is_tank_file(p)] == ["zz20_s.csv"]
    assert [d.name for d in build.discover(raw, tmp_path / "none")] == ["virtual", "mine", build.LOCAL]


def test_a_failing_stage_stops_only_what_reads_its_outputs(tmp_path):
    """A stage whose command fails (identify on a campaign of turning circles alone: no zigzag to
    identify from) stops validate, indices and control, which read its outputs, and nothing else: the
    diagnosis, which reads only the runs, is built.  Then one error names the stage, what was not run
    and what ran; the next build tries the failed stage and its dependents again, not the rest."""
    from pipeline.errors import PipelineError

    raw, root = tmp_path / "raw", tmp_path / "proc"
    (raw / "mine").mkdir(parents=True)
    (raw / "mine" / "a.csv").write_text("time,psi,r,delta\n0,0,0,0\n")
    (raw / "mine" / "dataset.toml").write_text("[data]\nscale = 1\n")
    ran: list[str] = []
    fake = _fake_stages(root, ran, fail=("identify",))

    ds = build.Dataset("mine", raw / "mine")
    with pytest.raises(PipelineError) as err:
        build.build_dataset(ds, root, run=fake, say=lambda s: None)
    assert ran == ["ingest", "identify", "diagnose"]
    assert str(err.value) == ("dataset 'mine': stage identify failed (exit 2, see above); not run, they read "
                              "its outputs: validate, indices, control; ran ingest, diagnose")
    ran.clear()
    with pytest.raises(PipelineError):
        build.build_dataset(ds, root, run=fake, say=lambda s: None)
    assert ran == ["identify"]


def test_run_builds_the_other_datasets_when_one_fails(tmp_path, capsys):
    """`run --dataset A B`: a dataset that cannot be built (a folder of files that are not tank data)
    is one error line; the next dataset is built all the same; the exit status is 2."""
    from pipeline.cli import main

    raw = tmp_path / "raw"
    (raw / "bad").mkdir(parents=True)
    (raw / "bad" / "broken.csv").write_text("time,psi,r,delta\n0,0,0,oops\n")
    (raw / "bad" / "dataset.toml").write_text("[data]\nscale = 1\n")
    (raw / "good").mkdir()
    shutil.copy(ROOT / "tests" / "data" / "probes" / "clean.csv", raw / "good" / "zz.csv")
    (raw / "good" / "dataset.toml").write_text("[data]\nscale = 1\n")
    rc = main(["run", "--dataset", "bad", "good", "--raw", str(raw), "--root", str(tmp_path / "proc"),
               "--until", "ingest"])
    cap = capsys.readouterr()
    assert rc == 2
    assert "dataset 'bad': stage ingest failed" in cap.err and "[good] ran ingest" in cap.out
    assert cap.err.strip().splitlines()[-1] == "error: 1 of 2 dataset(s) not fully built: bad (see above)"
    assert (tmp_path / "proc" / "good" / "runs" / "index.json").is_file()
    assert not (tmp_path / "proc" / "bad" / "runs").exists()


def test_a_folder_without_description_is_told_and_given_one_once(tmp_path):
    """`make pipeline` (build_dataset) on a user's folder without a dataset.toml: one line says what was
    assumed and a dataset.toml to edit is written beside the files, before ingest's key, so the next
    build reruns nothing.  Found 2026-11-26: ingest is handed the files by the build, and then said
    nothing and wrote nothing (only `ingest --dataset NAME` without files did)."""
    raw, root = tmp_path / "raw", tmp_path / "proc"
    (raw / "mine").mkdir(parents=True)
    (raw / "mine" / "a.csv").write_text("time,psi,r,delta\n0,0,0,0\n")
    fake = _fake_stages(root, [])
    said: list[str] = []
    ds = build.Dataset("mine", raw / "mine")
    assert build.build_dataset(ds, root, run=fake, say=said.append)[0] == "ingest"
    notice = [s for s in said if "no dataset.toml" in s]
    assert len(notice) == 1 and "assumed model-scale files (scale 1)" in notice[0], said
    assert "scale = 1.0" in (raw / "mine" / "dataset.toml").read_text()
    said.clear()
    assert build.build_dataset(ds, root, run=fake, say=said.append) == [] and said == []


@pytest.mark.skipif(shutil.which("make") is None, reason="GNU make is not installed")
@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(),
                    reason="needs git and a git checkout to know which files are committed")
def test_make_clean_removes_outputs_and_keeps_every_committed_file(tmp_path):
    """`make clean` in a copy of the tree's data/ and reports/: the committed files (dataset.toml of
    the virtual and hsva datasets, .gitkeep) survive byte for byte; what the pipeline made is gone."""
    tracked = subprocess.run(["git", "ls-files", "data", "reports"], cwd=ROOT, capture_output=True,
                             text=True, check=True).stdout.split()
    assert "data/raw/virtual/dataset.toml" in tracked
    shutil.copy(ROOT / "Makefile", tmp_path / "Makefile")
    for rel in tracked:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / rel, tmp_path / rel)
    made = ["data/raw/virtual/kcs_zigzag_20_20_S.csv", "data/raw/virtual/.stamp",
            "data/processed/virtual/runs/index.json", "data/processed/virtual/.stamps/ingest",
            "reports/index.html", "reports/virtual/identification.html"]
    for rel in made:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("made by the pipeline")
    res = subprocess.run(["make", "--no-print-directory", "clean"], cwd=tmp_path,
                         env={**os.environ, "MAKEFLAGS": ""}, capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    for rel in tracked:
        assert (tmp_path / rel).is_file(), f"make clean deleted the committed file {rel}"
        assert (tmp_path / rel).read_bytes() == (ROOT / rel).read_bytes(), rel
    for rel in made:
        assert not (tmp_path / rel).exists(), f"make clean left {rel}"
    # and on a tree where the virtual tank never ran (no data/raw/virtual) it still succeeds
    shutil.rmtree(tmp_path / "data" / "raw" / "virtual")
    res = subprocess.run(["make", "--no-print-directory", "clean"], cwd=tmp_path,
                         env={**os.environ, "MAKEFLAGS": ""}, capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
