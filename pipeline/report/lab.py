"""``make lab``: JupyterLab on this project, the report notebooks opening as notebooks.

``python -m pipeline.report.lab [--dataset NAME] [JUPYTER LAB OPTIONS ...]`` (docs/reports.md):

* makes sure the ``tanktest`` kernel runs this environment's Python (:func:`render.ensure_kernel`);
* makes JupyterLab open ``.py`` files as notebooks on a double click (jupytext's "Jupytext Notebook"
  viewer) in THIS environment only: one settings file in its ``share/jupyter/lab/settings/overrides.d``
  (the user's own JupyterLab settings, which take precedence, are not touched);
* starts ``jupyter lab`` on the project folder at ``notebooks/``, listening on the loopback address only
  (127.0.0.1, with Jupyter's token), new kernels ``tanktest``;
* ``--dataset NAME`` sets ``TANKTEST_DATASET``, which the notebooks' parameters cell reads: every
  notebook opened then shows that dataset (``data/processed/NAME``).

The notebooks are jupytext percent files: jupytext's contents manager (a server extension enabled when
jupytext is installed) reads them as notebooks and writes them back as the same percent text, outputs
left out, so opening, running and saving one changes nothing but what the user edits.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from pipeline.io import atomic_path
from pipeline.report import nb
from pipeline.report.render import KERNEL_NAME, ensure_kernel, notebook_dir

# JupyterLab's per-environment settings defaults (jupyterlab_server: app_settings_dir/overrides.d)
OVERRIDES_FILE = "tanktest-jupytext.json"
OVERRIDES = {"@jupyterlab/docmanager-extension:plugin": {"defaultViewers": {"python": "Jupytext Notebook"}}}


def app_settings_dir(prefix: str | Path = sys.prefix) -> Path:
    """JupyterLab's application settings folder of the environment at ``prefix``."""
    return Path(prefix) / "share" / "jupyter" / "lab" / "settings"


def write_overrides(prefix: str | Path = sys.prefix) -> Path:
    """Write the default-viewer setting (``.py`` opens as a notebook) for the environment at ``prefix``;
    returns the file.  Atomic; the same content every time."""
    path = app_settings_dir(prefix) / "overrides.d" / OVERRIDES_FILE
    text = json.dumps(OVERRIDES, indent=2, sort_keys=True) + "\n"
    if path.is_file() and path.read_text(encoding="utf-8") == text:
        return path
    with atomic_path(path, suffix=".json") as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def lab_command(project: Path, extra: list[str]) -> list[str]:
    """The ``jupyter lab`` command line: this Python, the project folder, loopback only."""
    return [sys.executable, "-m", "jupyterlab", f"--ServerApp.root_dir={project}",
            "--ServerApp.ip=127.0.0.1", "--LabApp.default_url=/lab/tree/notebooks",
            f"--MappingKernelManager.default_kernel_name={KERNEL_NAME}", *extra]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m pipeline.report.lab", allow_abbrev=False,
                                description="JupyterLab on this project; the report notebooks open as "
                                            "notebooks (other options go to jupyter lab)")
    p.add_argument("--dataset", default=None,
                   help=f"the dataset the notebooks open on (sets {nb.DATASET_ENV}; default: virtual)")
    args, extra = p.parse_known_args(argv)
    project = notebook_dir().parent
    ensure_kernel()
    settings = write_overrides()
    env = dict(os.environ)
    if args.dataset:
        env[nb.DATASET_ENV] = args.dataset
    print(f"lab: notebooks in {project / 'notebooks'} open as notebooks ({settings}); dataset "
          f"{env.get(nb.DATASET_ENV) or 'virtual'} (data/processed/<dataset>)", flush=True)
    os.chdir(project)
    os.execvpe(sys.executable, lab_command(project, extra), env)
    return 0   # pragma: no cover - exec does not return


if __name__ == "__main__":
    sys.exit(main())
