"""The report notebooks as a user opens them (make lab, docs/reports.md): jupytext percent files read as
notebooks and written back unchanged, pointed at a dataset by TANKTEST_DATASET, run without papermill's
injected parameters, and served as notebooks by JupyterLab on the loopback address."""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from report_catalog import make_catalog  # noqa: E402

from pipeline.report import nb  # noqa: E402
from pipeline.report.render import NOTEBOOKS, notebook_dir  # noqa: E402


def _copy_notebooks(tmp_path: Path) -> Path:
    dest = tmp_path / "notebooks"
    dest.mkdir()
    for name in NOTEBOOKS:
        shutil.copyfile(notebook_dir() / f"{name}.py", dest / f"{name}.py")
    return dest


def test_notebooks_round_trip_through_jupytexts_contents_manager(tmp_path):
    """Opened through jupytext's contents manager (what JupyterLab uses), each notebook is a notebook
    with the cells of its source; run (outputs, execution counts, the metadata JupyterLab adds) and saved,
    its file is byte for byte what it was."""
    import jupytext
    from jupytext import AsyncTextFileContentsManager

    folder = _copy_notebooks(tmp_path)
    cm = AsyncTextFileContentsManager(root_dir=str(tmp_path))

    async def round_trip(name: str) -> None:
        path = folder / f"{name}.py"
        before = path.read_bytes()
        model = await cm.get(f"notebooks/{name}.py", content=True)
        assert model["type"] == "notebook", name
        book = model["content"]
        assert [c["source"] for c in book["cells"]] == [c["source"] for c in jupytext.read(path).cells]
        assert any("parameters" in c["metadata"].get("tags", []) for c in book["cells"]), name
        book["metadata"]["kernelspec"] = {"name": "tanktest", "display_name": "tanktest (.venv)",
                                          "language": "python"}
        for k, cell in enumerate(book["cells"]):
            if cell["cell_type"] == "code":
                cell["execution_count"] = k + 1
                cell["outputs"] = [{"output_type": "stream", "name": "stdout", "text": "ran\n"}]
                cell["metadata"].update(scrolled=True, execution={"iopub.status.idle": "2026-01-01"})
        await cm.save(model, f"notebooks/{name}.py")
        assert path.read_bytes() == before, name

    for name in NOTEBOOKS:
        asyncio.run(round_trip(name))


def _parameters_cell(name: str) -> str:
    import jupytext

    book = jupytext.read(notebook_dir() / f"{name}.py")
    (cell,) = [c for c in book.cells if "parameters" in c.metadata.get("tags", [])]
    return cell.source


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_parameters_cell_reads_the_dataset_from_the_environment(name, monkeypatch):
    """TANKTEST_DATASET names the dataset (one line: `make lab D=NAME`); without it, the virtual tank;
    root '' means the project's processed data (nb.default_root)."""
    src = _parameters_cell(name)
    monkeypatch.setenv(nb.DATASET_ENV, "hsva #2")
    ns: dict = {}
    exec(compile(src, f"{name}.py parameters", "exec"), ns)     # noqa: S102 - the notebook's own cell
    assert ns["dataset"] == "hsva #2" and ns["root"] == ""
    monkeypatch.delenv(nb.DATASET_ENV)
    ns = {}
    exec(compile(src, f"{name}.py parameters", "exec"), ns)     # noqa: S102
    assert ns["dataset"] == "virtual"


def test_default_root_from_the_notebooks_folder(tmp_path, monkeypatch):
    """A kernel started by JupyterLab runs in notebooks/: the project's data/processed is found above it;
    TANKTEST_ROOT wins; with neither, the path named is the working folder's data/processed."""
    (tmp_path / "data" / "processed").mkdir(parents=True)
    (tmp_path / "notebooks").mkdir()
    monkeypatch.delenv(nb.ROOT_ENV, raising=False)
    monkeypatch.chdir(tmp_path / "notebooks")
    assert nb.default_root() == tmp_path / "data" / "processed"
    monkeypatch.chdir(tmp_path)
    assert nb.default_root() == tmp_path / "data" / "processed"
    monkeypatch.setenv(nb.ROOT_ENV, str(tmp_path / "elsewhere"))
    assert nb.default_root() == tmp_path / "elsewhere"
    monkeypatch.delenv(nb.ROOT_ENV)
    empty = tmp_path / "other" / "empty"                  # no data/processed here nor above
    empty.mkdir(parents=True)
    monkeypatch.chdir(empty)
    assert nb.default_root() == empty / "data" / "processed"
    assert nb.Data("", "x").cat.base == empty / "data" / "processed" / "x"


@pytest.mark.slow
def test_a_notebook_runs_on_its_own_parameters_cell(tmp_path, monkeypatch):
    """Executed as JupyterLab runs it (render.execute without injected parameters), the indices notebook
    reads the dataset TANKTEST_DATASET names under TANKTEST_ROOT.  When execute returns, its kernel has
    been shut down and its scratch folder removed (a process rendering many pages keeps no kernels)."""
    import contextlib
    import importlib

    from test_report_security import _processes_using

    rr = importlib.import_module("pipeline.report.render")
    used = []
    real_scratch = rr.scratch_dir

    @contextlib.contextmanager
    def watched():
        with real_scratch() as d:
            used.append(d)
            yield d

    monkeypatch.setattr(rr, "scratch_dir", watched)
    root = tmp_path / "proc"
    make_catalog(root, "lab set", "measured", ship="KVLCC2")
    monkeypatch.setenv(nb.DATASET_ENV, "lab set")
    monkeypatch.setenv(nb.ROOT_ENV, str(root))
    book = rr.execute("indices", None)
    (scratch,) = used
    assert not scratch.exists()
    deadline = time.monotonic() + 30            # a bound on the kernel's exit, not a measured time
    while _processes_using(scratch) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _processes_using(scratch), "the notebook's kernel outlived execute"
    assert not [c for c in book.cells if "injected-parameters" in c.metadata.get("tags", [])]
    outputs = [o for c in book.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    html = " ".join(o.get("data", {}).get("text/html", "") for o in outputs)
    assert "dataset <code>lab set</code>" in html and "MEASURED tank data" in html


def test_lab_settings_open_python_files_as_notebooks(tmp_path):
    from pipeline.report import lab

    path = lab.write_overrides(tmp_path)
    assert path == tmp_path / "share" / "jupyter" / "lab" / "settings" / "overrides.d" / lab.OVERRIDES_FILE
    doc = json.loads(path.read_text())
    assert doc["@jupyterlab/docmanager-extension:plugin"]["defaultViewers"] == {"python": "Jupytext Notebook"}
    stamp = path.stat().st_mtime_ns
    assert lab.write_overrides(tmp_path) == path and path.stat().st_mtime_ns == stamp   # written once
    cmd = lab.lab_command(Path("/p"), ["--no-browser"])
    assert cmd[:3] == [sys.executable, "-m", "jupyterlab"] and "--ServerApp.ip=127.0.0.1" in cmd
    assert cmd[-1] == "--no-browser"


def _get(url: str, token: str) -> dict:
    req = urllib.request.Request(url, headers={"Authorization": f"token {token}"})
    with urllib.request.urlopen(req, timeout=10) as r:       # noqa: S310 - loopback, our server
        return json.loads(r.read())


@pytest.mark.slow
def test_lab_serves_the_notebooks_as_notebooks(tmp_path):
    """Smoke check, bounded: JupyterLab as `make lab` starts it, on 127.0.0.1, a free port and a token,
    its settings in a temporary folder: /api/contents gives notebooks/identification.py as a notebook;
    the lab setting opens .py files with the Jupytext Notebook viewer; the server stops on SIGTERM."""
    from pipeline.report import lab

    settings = lab.app_settings_dir(tmp_path / "prefix")
    lab.write_overrides(tmp_path / "prefix")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    token = "tanktest-smoke-" + os.urandom(8).hex()
    env = {**os.environ, "JUPYTER_RUNTIME_DIR": str(tmp_path / "runtime"),
           "JUPYTER_CONFIG_DIR": str(tmp_path / "config"), nb.DATASET_ENV: "virtual"}
    project = notebook_dir().parent
    cmd = lab.lab_command(project, ["--no-browser", f"--ServerApp.port={port}", "--ServerApp.port_retries=0",
                                    f"--IdentityProvider.token={token}",
                                    f"--LabApp.app_settings_dir={settings}",
                                    f"--LabApp.user_settings_dir={tmp_path / 'user-settings'}",
                                    f"--LabApp.workspaces_dir={tmp_path / 'workspaces'}",
                                    *(["--allow-root"] if os.geteuid() == 0 else [])])    # a root container
    proc = subprocess.Popen(cmd, env=env, cwd=project, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 90          # a bound on the start-up, not a measured time
        while True:
            assert proc.poll() is None, "jupyter lab exited"
            try:
                _get(f"{base}/api/status", token)
                break
            except (urllib.error.URLError, ConnectionError, OSError):
                assert time.monotonic() < deadline, "jupyter lab did not answer within 90 s"
                time.sleep(0.2)
        model = _get(f"{base}/api/contents/notebooks/identification.py?type=notebook&content=1", token)
        assert model["type"] == "notebook" and model["format"] == "json"
        assert any("TANKTEST_DATASET" in "".join(c["source"]) for c in model["content"]["cells"])
        plugin = _get(f"{base}/lab/api/settings/@jupyterlab/docmanager-extension:plugin", token)
        # the environment's override becomes the setting's default (the user's own settings still win)
        assert plugin["schema"]["properties"]["defaultViewers"]["default"] == {"python": "Jupytext Notebook"}
        with pytest.raises(urllib.error.HTTPError) as exc:       # the token is required
            urllib.request.urlopen(f"{base}/api/contents/notebooks", timeout=10)    # noqa: S310
        assert exc.value.code == 403
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
