"""Output locations and directory sets (docs/contract.md#bad-input)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from pipeline.cli import main
from pipeline.io import atomic_dir, clean_stale_temporaries, set_manifest_path

ROOT = Path(__file__).resolve().parents[1]
GOOD = "# test: zigzag 10/10 starboard\ntime,psi,r,delta\n" + "\n".join(
    f"{k * 0.08:.2f},{k * 0.08:.4f},1.0,5.0" for k in range(80)) + "\n"

STAGES = [
    ["ingest", "{raw}"],
    ["identify", "{raw}"],
    ["diagnose", "--train", "{raw}", "--validate", "{raw}"],
    ["control"],
    ["report"],
    ["tank"],
]


@pytest.mark.parametrize("argv", STAGES, ids=lambda a: a[0])
@pytest.mark.parametrize("where", ["file", "through_file"])
def test_out_that_cannot_be_a_folder_is_one_line_exit_2(argv, where, tmp_path, capsys):
    raw = tmp_path / "good.csv"
    raw.write_text(GOOD)
    blocker = tmp_path / "afile"
    blocker.write_text("keep me")
    out = blocker if where == "file" else blocker / "sub"
    rc = main([a.format(raw=raw) for a in argv] + ["--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert err.startswith("error: ") and "\n" not in err and "afile" in err
    assert "Traceback" not in err
    assert blocker.read_text() == "keep me"


def test_out_not_writable_is_one_line_exit_2(tmp_path, capsys, monkeypatch):
    raw = tmp_path / "good.csv"
    raw.write_text(GOOD)
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    if os.access(ro, os.W_OK):      # root ignores permission bits: the check itself is what is tested
        real = os.access
        monkeypatch.setattr(os, "access", lambda p, m: False if Path(p) == ro else real(p, m))
    rc = main(["ingest", str(raw), "--out", str(ro / "runs")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "no write permission" in err and "\n" not in err


def test_os_error_while_writing_is_one_line(tmp_path, capsys, monkeypatch):
    raw = tmp_path / "good.csv"
    raw.write_text(GOOD)

    def full(*a, **k):
        raise OSError(28, "No space left on device", str(tmp_path / "x"))

    monkeypatch.setattr("pipeline.cli.ingest.write_run", full)
    rc = main(["ingest", str(raw), "--out", str(tmp_path / "runs")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "No space left" in err and "\n" not in err
    assert not (tmp_path / "runs").exists()


def test_directory_set_replaced_whole_stale_files_gone(tmp_path):
    dest = tmp_path / "diag"
    with atomic_dir(dest) as tmp:
        (tmp / "diagnosis.json").write_text("1")
        (tmp / "freerun_a.png").write_text("old plot")
    with atomic_dir(dest) as tmp:
        (tmp / "diagnosis.json").write_text("2")
        (tmp / "freerun_b.png").write_text("new plot")
    assert sorted(p.name for p in dest.iterdir()) == ["diagnosis.json", "freerun_b.png"]
    assert (dest / "diagnosis.json").read_text() == "2"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".diag.set.json", "diag"]


def test_failed_block_leaves_previous_set(tmp_path):
    dest = tmp_path / "est"
    with atomic_dir(dest) as tmp:
        (tmp / "estimates.json").write_text("run A")
        (tmp / "trace.parquet").write_text("trace A")
    with pytest.raises(RuntimeError):
        with atomic_dir(dest) as tmp:
            (tmp / "estimates.json").write_text("run B")
            raise RuntimeError("killed between the two files")
    assert {p.name: p.read_text() for p in dest.iterdir()} == {"estimates.json": "run A",
                                                                "trace.parquet": "trace A"}


def test_users_own_files_in_out_are_kept(tmp_path):
    dest = tmp_path / "mine"
    dest.mkdir()
    (dest / "notes.txt").write_text("user")
    with atomic_dir(dest) as tmp:
        (tmp / "a.json").write_text("1")
        (tmp / "a.png").write_text("p")
    with atomic_dir(dest) as tmp:
        (tmp / "a.json").write_text("2")
    assert sorted(p.name for p in dest.iterdir()) == ["a.json", "notes.txt"]     # a.png: stale, removed
    assert set_manifest_path(dest).exists()


def test_killed_run_temporaries_cleaned_at_next_start(tmp_path):
    """A run SIGKILLed inside the block leaves .out.<pid>.*; the next start removes it."""
    dest = tmp_path / "out"
    script = textwrap.dedent(f"""
        import os, signal
        from pipeline.io import atomic_dir
        with atomic_dir({str(dest)!r}) as tmp:
            (tmp / "estimates.json").write_text("half")
            os.kill(os.getpid(), signal.SIGKILL)
    """)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, timeout=60)
    assert proc.returncode != 0
    left = [p.name for p in tmp_path.iterdir()]
    assert left and all(n.startswith(".out.out.") for n in left)       # the killed run's temporary
    assert not dest.exists()
    with atomic_dir(dest) as tmp:
        (tmp / "estimates.json").write_text("whole")
    assert sorted(p.name for p in tmp_path.iterdir()) == [".out.set.json", "out"]


def test_old_set_restored_after_kill_between_renames(tmp_path):
    dest = tmp_path / "out"
    # a run killed between 'dest -> .old' and 'tmp -> dest' of the fallback swap (pid 2**22+1 is unused)
    old = tmp_path / f".out.old.{2 ** 22 + 1}.abc"
    old.mkdir()
    (old / "a.json").write_text("good")
    clean_stale_temporaries(dest)
    assert (dest / "a.json").read_text() == "good"


def test_live_process_temporary_is_kept(tmp_path):
    mine = tmp_path / f".out.out.{os.getpid()}.xyz"
    mine.mkdir()
    clean_stale_temporaries(tmp_path / "out")
    assert mine.exists()


def test_fallback_swap_without_renameat2(tmp_path, monkeypatch):
    monkeypatch.setattr("pipeline.io._exchange", lambda a, b: False)
    test_directory_set_replaced_whole_stale_files_gone(tmp_path)


def test_out_is_the_working_directory(tmp_path, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    with atomic_dir(".") as tmp:
        (tmp / "estimates.json").write_text("1")
    assert (work / "estimates.json").read_text() == "1" and Path.cwd() == work
