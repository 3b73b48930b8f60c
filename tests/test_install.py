"""A non-editable ``pip install .`` can render reports: the notebooks ship as package data.

A fresh venv gets the package from a wheel built out of this tree (``--no-deps``); the dependencies
come from the test's own environment through a ``.pth`` path line (a plain path: no ``.pth`` files of
that environment run, so an editable install there cannot leak in).  ``tanktest report`` then runs
from a folder outside the source tree, and the package it imports must be the installed copy.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from report_catalog import make_catalog  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_non_editable_install_renders_a_report(tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    py = venv / "bin" / "python"
    site = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               check=True, capture_output=True, text=True).stdout.strip())
    (site / "deps-from-test-env.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    src = tmp_path / "src"      # a clean copy: no build/ or egg-info left in the working tree
    shutil.copytree(ROOT, src, symlinks=True,
                    ignore=shutil.ignore_patterns(".git", ".venv", "data", "reports", "build", "*.egg-info",
                                                  "__pycache__", ".pytest_cache", ".ruff_cache"))
    # the dependencies' data files (nbconvert templates, ...) are where this environment keeps them
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["JUPYTER_PATH"] = str(Path(sys.prefix) / "share" / "jupyter")
    res = subprocess.run([str(py), "-m", "pip", "install", "--quiet", "--no-deps", str(src)],
                         env=env, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    assert (site / "pipeline" / "notebooks" / "indices.py").is_file()
    shutil.rmtree(src)                                          # nothing of the source tree remains
    work = tmp_path / "work"
    work.mkdir()
    where = subprocess.run([str(py), "-c", "import pipeline; print(pipeline.__file__)"], cwd=work, env=env,
                           check=True, capture_output=True, text=True).stdout.strip()
    assert Path(where).is_relative_to(site), where
    make_catalog(work / "proc", "tiny", "virtual")
    tanktest = venv / "bin" / "tanktest"
    assert tanktest.read_text().startswith(f"#!{py}")          # the console script runs the new venv
    cmd = [str(tanktest),
           "report", "--datasets", "tiny", "--root", "proc", "--out", "out", "--notebooks", "indices",
        "--kernel", "tanktest-installed-test"]
    res = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    page = (work / "out" / "indices-tiny.html").read_text(encoding="utf-8")
    assert "VIRTUAL TANK" in page and "Traceback" not in page
