"""Execute the parameterised notebooks with papermill and render them to self-contained HTML.

One report = one notebook (jupytext percent-format source ``notebooks/<name>.py``, reviewed and linted
as code) converted in memory to .ipynb (stable cell ids), executed for one dataset on the Jupyter
kernel named ``tanktest`` (the project's .venv Python), then converted by nbconvert to a single
HTML file: figures embedded as base64 PNG, no external scripts (require.js, MathJax and mermaid are
left out), code cells hidden behind a "show code" toggle (hidden also when scripts are disabled).

Before anything runs, every stage output a notebook reads is checked; a missing one is refused with
:class:`pipeline.errors.InputError` naming the file.  A notebook that fails while running becomes one
:class:`pipeline.errors.PipelineError` line (the notebook, the cell, the exception).  Outputs are
written atomically (:func:`pipeline.io.atomic_path`).
"""

from __future__ import annotations

import contextlib
import hashlib
import html
import json
import os
import re
import shutil
import stat
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

from pipeline.catalog import TIMING_FILE, Catalog, is_builtin_tank
from pipeline.errors import InputError, PipelineError
from pipeline.io import atomic_path, read_json, write_json
from pipeline.report import particulars

KERNEL_NAME = "tanktest"
# The notebook sources: ``notebooks/*.py`` in the source tree; in an installed (non-editable) package
# the same files are package data at ``pipeline/notebooks/`` (pyproject.toml maps the folder there).
_NOTEBOOK_DIRS = (Path(__file__).resolve().parents[1] / "notebooks",     # installed: pipeline/notebooks
                  Path(__file__).resolve().parents[2] / "notebooks")     # source tree: <repo>/notebooks
NOTEBOOKS = ("identification", "indices", "control", "diagnosis")
ALGORITHMS = ("srukf-ffm", "ffm-ukf")


def notebook_dir() -> Path:
    """The folder holding the notebook sources (installed package data first, then the source tree)."""
    for d in _NOTEBOOK_DIRS:
        if (d / f"{NOTEBOOKS[0]}.py").is_file():
            return d.resolve()
    raise InputError("notebook sources not found (looked in "
                     + ", ".join(str(d) for d in _NOTEBOOK_DIRS) + ")")


def notebook_source(notebook: str) -> Path:
    return notebook_dir() / f"{notebook}.py"


def load_notebook(notebook: str):
    """The jupytext percent source as a notebook node: kernel ``tanktest``, stable cell ids."""
    import jupytext

    src = notebook_source(notebook)
    if not src.is_file():
        raise InputError("notebook not found", file=src)
    book = jupytext.read(str(src), fmt="py:percent")
    for i, cell in enumerate(book.cells):      # stable ids: the same source gives the same notebook
        cell["id"] = f"cell-{i:02d}"
    book.metadata["kernelspec"] = {"name": KERNEL_NAME, "display_name": f"{KERNEL_NAME} (.venv)",
                                   "language": "python"}
    book.metadata["language_info"] = {"name": "python"}
    book.metadata.pop("jupytext", None)
    return book


def required_inputs(notebook: str, cat: Catalog) -> list[Path]:
    """Stage outputs that ``notebook`` reads (it reads nothing else).

    Parameters
    ----------
    notebook : str
        A report's name (notebooks/<name>.py).
    cat : Catalog
        The dataset's processed outputs.

    Returns
    -------
    list of Path
        The files, in the order of the stages.
    """
    runs = [cat.runs_index]
    ident = [cat.identify_dir(a) / f for a in ALGORITHMS for f in ("estimates.json", "trace.parquet")]
    table: dict[str, list[Path]] = {
        "identification": runs + ident + [cat.validate_dir / "metrics.json",
                                          cat.validate_dir / "predictions.parquet"],
        "indices": runs + [cat.indices_dir / "indices.json", cat.indices_dir / "zigzag.json"],
        "control": runs + [cat.indices_dir / "indices.json", cat.control_dir / "metrics.json",
                           cat.control_dir / "timeseries.parquet"],
        "diagnosis": runs + [cat.diagnose_dir / "diagnosis.json", cat.diagnose_dir / "series.parquet"],
    }
    if notebook not in table:
        raise InputError(f"unknown notebook {notebook!r} (known: {', '.join(NOTEBOOKS)})")
    return table[notebook]


def _cannot_run(stage: str, cat: Catalog) -> str | None:
    """Why ``stage`` cannot have run on this dataset, where its runs index says so, else None: the
    identification and the stages built on it need a zigzag (pipeline.runinfo.choose_runs,
    pipeline.indices.stage.build) unless ``[roles] identify`` names another run (identify and
    validate then run; the indices still need a zigzag)."""
    if stage not in ("identify", "validate", "indices", "control") or not Path(cat.runs_index).is_file():
        return None
    index = read_json(cat.runs_index)
    if any(e.get("kind") == "zigzag" for e in index.get("runs") or []):
        return None
    named = (index.get("roles") or {}).get("identify")
    if named and stage in ("identify", "validate"):
        return None
    return ("it has no zigzag run" + ("" if named else " and its dataset.toml names no [roles] identify")
            + f", so the {stage} stage does not run on it; its diagnosis report does (--notebooks diagnosis)")


def check_inputs(notebook: str, cat: Catalog) -> None:
    """Check that ``notebook`` can run on the dataset of ``cat``.

    Parameters
    ----------
    notebook : str
        A report's name.
    cat : Catalog
        The dataset's processed outputs.

    Raises
    ------
    InputError
        Naming the first stage output of ``notebook`` that is missing, and why the stage cannot run
        where the data say so.
    """
    for path in required_inputs(notebook, cat):
        if not Path(path).is_file():
            stage = Path(path).relative_to(cat.base).parts[0] if cat.base in Path(path).parents else "?"
            stage = {"runs": "ingest", "diagnose": "diagnose"}.get(stage, stage)
            why = _cannot_run(stage, cat)
            raise InputError(f"stage output missing for the {notebook} report of dataset '{cat.dataset}'"
                             + (f": {why}" if why else f" (run `python -m pipeline {stage} --dataset "
                                                      f"{cat.dataset}` first)"), file=path)


# ----------------------------------------------------------------------------------------- kernel
def _same_python(argv0: str) -> bool:
    a, b = Path(argv0), Path(sys.executable)
    if os.path.normpath(a.absolute()) == os.path.normpath(b.absolute()):
        return True
    # python vs python3 in the same environment's bin directory
    return a.parent.absolute() == b.parent.absolute() and a.name.startswith("python")


def ensure_kernel(name: str = KERNEL_NAME, install: Callable[[list[str]], object] | None = None) -> Path:
    """Make sure the Jupyter kernel ``name`` exists and runs this Python (``sys.executable``).

    A missing kernelspec is installed from ``sys.executable`` into ``sys.prefix`` (as the Makefile
    does: ``python -m ipykernel install --sys-prefix --name tanktest``), never from whatever Python
    is first on PATH.  A kernelspec that points at another Python is reinstalled when it lives in
    this environment, refused otherwise.

    Parameters
    ----------
    name : str
        The kernel's name.
    install : callable, optional
        Runs an install command (a list of arguments); None: a subprocess.

    Returns
    -------
    Path
        The kernelspec directory.
    """
    from jupyter_client.kernelspec import KernelSpecManager, NoSuchKernel

    install = install or (lambda cmd: subprocess.run(cmd, check=True, capture_output=True))
    cmd = [sys.executable, "-m", "ipykernel", "install", "--sys-prefix", "--name", name,
           "--display-name", f"{name} (.venv)"]
    ksm = KernelSpecManager()
    try:
        spec = ksm.get_kernel_spec(name)
    except NoSuchKernel:
        spec = None
    if spec is not None and _same_python(spec.argv[0]):
        return Path(spec.resource_dir)
    in_env = spec is not None and Path(sys.prefix).absolute() in Path(spec.resource_dir).absolute().parents
    if spec is not None and not in_env:
        raise PipelineError(f"kernel '{name}' runs {spec.argv[0]}, not this environment's "
                            f"{sys.executable}; remove it or reinstall with: {' '.join(cmd)}",
                            file=spec.resource_dir)
    try:
        install(cmd)
    except (subprocess.CalledProcessError, OSError) as exc:
        raise PipelineError(f"could not install the Jupyter kernel '{name}' ({exc})") from None
    try:
        spec = KernelSpecManager().get_kernel_spec(name)
    except NoSuchKernel:
        raise PipelineError(f"Jupyter kernel '{name}' is still missing after: {' '.join(cmd)}") from None
    if not _same_python(spec.argv[0]):
        raise PipelineError(f"kernel '{name}' still runs {spec.argv[0]}, not {sys.executable}",
                            file=spec.resource_dir)
    return Path(spec.resource_dir)


# ------------------------------------------------------------------------------------------- HTML
_TEMPLATE = r"""
{%- extends 'lab/index.html.j2' -%}
{%- block html_head_js -%}{%- endblock html_head_js -%}
{%- block html_head_js_mathjax -%}{%- endblock html_head_js_mathjax -%}
{%- block html_head_js_mermaidjs -%}{%- endblock html_head_js_mermaidjs -%}
{%- block jupyter_widgets -%}{%- endblock jupyter_widgets -%}
{% block extra_css %}
<style>
body:not(.show-code) .jp-CodeCell .jp-Cell-inputWrapper { display: none; }
body:not(.show-code) .jp-InputPrompt, body:not(.show-code) .jp-OutputPrompt { visibility: hidden; }
#code-toggle { position: fixed; top: 8px; right: 12px; z-index: 10; font: 13px sans-serif;
  padding: 3px 8px; border: 1px solid #888; border-radius: 4px; background: #f4f4f4; cursor: pointer; }
@media print { #code-toggle { display: none; } }
</style>
{% endblock extra_css %}
{% block body_footer %}
<button id="code-toggle" type="button" onclick="toggleCode(this)">show code</button>
<script>
function toggleCode(b) {
  var on = document.body.classList.toggle('show-code');
  b.textContent = on ? 'hide code' : 'show code';
}
</script>
{{ super() }}
{% endblock body_footer %}
"""

_EXTERNAL = re.compile(r"""<(?:script|link|img|iframe)\b[^>]*\b(?:src|href)\s*=\s*["']?(?:https?:)?//""",
                       re.IGNORECASE)


def to_html(nb, title: str = "tanktest report") -> str:
    """Render an executed notebook to one self-contained HTML page (see module docstring).

    Parameters
    ----------
    nb : nbformat.NotebookNode
        The executed notebook.
    title : str
        The page's title.

    Returns
    -------
    str
        The HTML page (figures inline, no external resource).
    """
    from jinja2 import DictLoader
    from nbconvert import HTMLExporter

    exporter = HTMLExporter(extra_loaders=[DictLoader({"tanktest_report.html.j2": _TEMPLATE})],
                            template_file="tanktest_report.html.j2", embed_images=True)
    body, _ = exporter.from_notebook_node(nb, resources={"metadata": {"name": title}})
    m = _EXTERNAL.search(body)
    if m:   # never ship a page that fetches anything
        raise PipelineError(f"rendered HTML would load an external resource: {m.group(0)[:80]}")
    return body


# -------------------------------------------------------------------------------------- execution
@dataclass
class Report:
    notebook: str
    dataset: str
    html: Path
    seconds: float
    provenance: str
    runs: int
    ship: str = ""            # one-line ship and scale summary (pipeline.report.particulars.summary)
    fingerprint: str = ""     # SHA-256 of everything the page depends on (see fingerprint())
    skipped: bool = False     # True: the page was up to date and not rendered again
    builtin_tank: bool = False  # the runs are the built-in tank's (pipeline.catalog.is_builtin_tank)
    # what the dataset says of itself: ship, scale, tank, source, provenance, description file
    # (pipeline.report.particulars.identity); tells two datasets of one ship apart on the index
    identity: dict = field(default_factory=dict)


# Stage folders each notebook reads (every file in them counts for "changed").
READS = {"identification": ("runs", "identify", "validate"), "indices": ("runs", "indices"),
         "control": ("runs", "indices", "control"), "diagnosis": ("runs", "diagnose")}


def fingerprint(notebook: str, cat: Catalog) -> str:
    """SHA-256 over the notebook source, the report code and every file of the stage folders the
    notebook reads (relative path and content; a stage's ``timing.json``, which no page shows, left
    out).  Same fingerprint = same page (byte-reproducible)."""
    h = hashlib.sha256()
    code = [notebook_source(notebook)] + sorted(Path(__file__).parent.glob("*.py"))
    files = [(f"code/{p.name}", p) for p in code]
    for stage in READS.get(notebook, ()):
        d = cat.base / stage
        if d.is_dir():
            files += [(str(p.relative_to(cat.base)), p) for p in sorted(d.rglob("*"))
                      if p.is_file() and not p.name.startswith(".") and p.name != TIMING_FILE]
    for rel, path in files:
        h.update(rel.encode() + b"\0")
        with open(path, "rb") as fh:
            for chunk in iter(lambda fh=fh: fh.read(1 << 20), b""):
                h.update(chunk)
        h.update(b"\0")
    return h.hexdigest()


# A render's scratch folder: ``<tmp>/tanktest-report-<pid>-<random>/``, mode 0700, holding the
# notebook before and after execution, the kernel's stderr log and the kernel's connection file
# (ports and the message-signing key).  The process id in the name lets a later render tell a folder
# left by a killed render (its process gone) from one in use (see remove_stale_scratch).
SCRATCH_PREFIX = "tanktest-report-"
_SCRATCH_NAME = re.compile(re.escape(SCRATCH_PREFIX) + r"(\d+)-[A-Za-z0-9_]+$")


def remove_stale_scratch(base: str | Path | None = None) -> list[Path]:
    """Remove the scratch folders that killed renders left in ``base`` (default: the system temporary
    folder); returns what was removed.

    Only folders this module makes are touched: named ``tanktest-report-<pid>-<random>``, a real
    folder (not a symbolic link), owned by this user, and whose process ``<pid>`` no longer exists.
    A render running at the same time (its process alive, this process included) keeps its folder.
    """
    from pipeline.io import _pid_alive

    base = Path(base if base is not None else tempfile.gettempdir())
    removed: list[Path] = []
    try:
        entries = sorted(base.iterdir())
    except OSError:
        return removed
    for item in entries:
        m = _SCRATCH_NAME.match(item.name)
        if not m:
            continue
        try:
            st = item.lstat()
        except OSError:
            continue
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or _pid_alive(int(m[1])):
            continue
        shutil.rmtree(item, ignore_errors=True)
        if not item.exists():
            removed.append(item)
    return removed


@contextlib.contextmanager
def scratch_dir():
    """A fresh scratch folder for one render (see SCRATCH_PREFIX), removed when the block ends;
    stale folders of killed renders are removed first."""
    remove_stale_scratch()
    path = Path(tempfile.mkdtemp(prefix=f"{SCRATCH_PREFIX}{os.getpid()}-"))
    try:
        yield path
    finally:
        shutil.rmtree(path, ignore_errors=True)


def execute(notebook: str, cat: Catalog | None, kernel: str = KERNEL_NAME, extra: dict | None = None):
    """Execute ``notebooks/<notebook>.py`` for ``cat`` with papermill; returns the notebook node.

    ``cat`` None: no parameters are injected, so the notebook runs on its own parameters cell, as it
    does when opened in JupyterLab (the dataset from ``TANKTEST_DATASET``, docs/reports.md).

    The kernel's connection file is written in the render's scratch folder (:func:`scratch_dir`),
    never in the shared Jupyter runtime folder, so nothing of a render outlives it: a normal render
    removes the folder, a killed one leaves it for the next render to remove."""
    import nbformat
    import papermill as pm
    from papermill.exceptions import PapermillExecutionError
    from traitlets.config import Config

    src = notebook_source(notebook)
    book = load_notebook(notebook)
    params = ({} if cat is None else {"dataset": cat.dataset, "root": str(Path(cat.root).absolute())}) \
        | (extra or {})
    with scratch_dir() as tmpdir:
        tmp = Path(tmpdir) / f"{notebook}-out.ipynb"
        source_nb = Path(tmpdir) / f"{notebook}.ipynb"
        nbformat.write(book, str(source_nb))
        log = Path(tmpdir) / "kernel-stderr.txt"
        # nbclient makes (and so shuts down and cleans up) the kernel manager; only its connection
        # file's place is set
        config = Config()
        config.KernelManager.connection_file = str(Path(tmpdir) / "kernel.json")
        try:
            # The kernel inherits file descriptor 2; its start-up/shutdown chatter goes to a log
            # that is only quoted when the kernel itself fails.
            with _stderr_to(log):
                pm.execute_notebook(str(source_nb), str(tmp), parameters=params, kernel_name=kernel,
                                    progress_bar=False, log_output=False, cwd=os.getcwd(), config=config)
        except PapermillExecutionError as exc:
            evalue = " ".join(str(exc.evalue).split())
            raise PipelineError(f"notebook failed in cell {exc.exec_count}: {exc.ename}: {evalue}",
                                file=src) from None
        except Exception as exc:  # noqa: BLE001 - kernel start/death: any type, one line out
            lines = [ln for ln in log.read_text(errors="replace").splitlines() if ln.strip()] \
                if log.is_file() else []
            last = f" (kernel said: {lines[-1].strip()[:200]})" if lines else ""
            raise PipelineError(f"could not execute on kernel '{kernel}': {type(exc).__name__}: "
                                f"{' '.join(str(exc).split())[:300]}{last}", file=src) from None
        nb = nbformat.read(str(tmp), as_version=4)
    return nb


@contextlib.contextmanager
def _stderr_to(path: Path):
    """Redirect file descriptor 2 (inherited by the kernel process) to ``path`` for the block."""
    sys.stderr.flush()
    saved = os.dup(2)
    with open(path, "wb") as fh:
        os.dup2(fh.fileno(), 2)
        try:
            yield
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)


def render(notebook: str, cat: Catalog, out_dir: Path, kernel: str = KERNEL_NAME) -> Report:
    """Check inputs, execute, convert; write ``out_dir/<notebook>-<dataset>.html`` atomically.

    Parameters
    ----------
    notebook, cat
        The report's name and the dataset's outputs, as for :func:`required_inputs`.
    out_dir : Path
        The reports' folder.
    kernel : str
        The Jupyter kernel that executes the notebook.

    Returns
    -------
    Report
        The page, its dataset's provenance and ship, its render time (s) and fingerprint.

    Raises
    ------
    InputError
        A stage output the notebook needs is missing (:func:`check_inputs`).
    """
    check_inputs(notebook, cat)
    t0 = time.perf_counter()
    fp = fingerprint(notebook, cat)
    nb = execute(notebook, cat, kernel)
    for i, cell in enumerate(nb.cells):     # papermill's injected-parameters cell has a random id
        cell["id"] = f"cell-{i:02d}"
    body = to_html(nb, title=f"{notebook} report: {cat.dataset}")
    dest = Path(out_dir) / f"{notebook}-{cat.dataset}.html"
    with atomic_path(dest, suffix=".html") as tmp:
        tmp.write_text(body, encoding="utf-8")
        tmp.chmod(0o644)
    index = read_json(cat.runs_index)
    return Report(notebook, cat.dataset, dest, time.perf_counter() - t0,
                  str(index.get("provenance", "unknown")), len(index.get("runs", [])),
                  ship=particulars.summary(index), fingerprint=fp, builtin_tank=is_builtin_tank(index),
                  identity=particulars.identity(index))


# ------------------------------------------------------------------------------------------ index
def _manifest(out_dir: Path) -> dict[str, dict]:
    path = Path(out_dir) / "reports.json"
    if not path.is_file():
        return {}
    try:
        return {e["file"]: e for e in json.loads(path.read_text()).get("reports", [])}
    except (json.JSONDecodeError, KeyError, TypeError, AttributeError):
        return {}


def _write_timing(out_dir: Path, reports: Sequence[Report], stamp: str, files: set[str]) -> None:
    """Record the render time (s) and wall clock of every page rendered now in ``out_dir/timing.json``:
    ``{"reports": {FILE: {"seconds", "rendered" (local time, YYYY-MM-DD HH:MM:SS)}}}`` (entries of pages
    kept unchanged stay; entries of pages gone are dropped).  The pages, reports.json and index.html
    hold no clock, so the same inputs give the same bytes (docs/reports.md)."""
    path = Path(out_dir) / TIMING_FILE
    try:
        doc = json.loads(path.read_text())
        known = doc["reports"] if isinstance(doc, dict) and isinstance(doc.get("reports"), dict) else {}
    except (OSError, ValueError):
        known = {}                                   # none yet, or torn: timings are not results
    for r in reports:
        if not r.skipped:
            known[r.html.name] = {"seconds": round(r.seconds, 2), "rendered": stamp}
    write_json(path, {"reports": {k: known[k] for k in sorted(known) if k in files}})


def write_index(out_dir: Path, reports: Sequence[Report]) -> Path:
    """Merge ``reports`` into ``out_dir/reports.json`` and (re)write ``out_dir/index.html``.

    One section per dataset: its provenance (VIRTUAL TANK or measured), ship and scale, then what its
    dataset.toml says of it (ship, scale, tank, source, provenance, the file: Report.identity), which
    tells two datasets of one ship apart, then one link per report (URL-quoted file name).  Entries
    whose HTML file no longer exists are dropped.
    Neither holds a clock: the page depends only on the manifest, so the same reports give the same
    bytes; render times and wall clocks go to ``out_dir/timing.json`` (:data:`TIMING_FILE`).

    Parameters
    ----------
    out_dir : Path
        The reports' folder.
    reports : sequence of Report
        The pages rendered (or kept) now.

    Returns
    -------
    Path
        index.html.
    """
    out_dir = Path(out_dir)
    manifest_path = out_dir / "reports.json"
    # an older manifest's clock fields are not carried over (they now live in timing.json)
    entries = {k: {f: v for f, v in e.items() if f not in ("seconds", "rendered")}
               for k, e in _manifest(out_dir).items()}
    stamp = time.strftime("%Y-%m-%d %H:%M:%S")
    for r in reports:
        if r.skipped and r.html.name in entries:
            continue
        entries[r.html.name] = {"file": r.html.name, "notebook": r.notebook, "dataset": r.dataset,
                                "provenance": r.provenance, "runs": r.runs, "ship": r.ship,
                                "fingerprint": r.fingerprint, "builtin_tank": r.builtin_tank,
                                "identity": r.identity}
    order = {n: i for i, n in enumerate(NOTEBOOKS)}
    rows = sorted((e for e in entries.values() if (out_dir / e["file"]).is_file()),
                  key=lambda e: (e["dataset"], order.get(e["notebook"], 99), e["notebook"]))
    write_json(manifest_path, {"reports": rows})
    _write_timing(out_dir, reports, stamp, {e["file"] for e in rows})
    esc = html.escape
    sections = []
    for ds in dict.fromkeys(e["dataset"] for e in rows):
        group = [e for e in rows if e["dataset"] == ds]
        prov = group[0]["provenance"]
        label = ("<b class='virtual'>VIRTUAL TANK (simulated, not measured)</b>"
                 if prov == "virtual" and group[0].get("builtin_tank")
                 else "<b class='virtual'>SIMULATED data (not measured; not the built-in KCS tank)</b>"
                 if prov == "virtual"
                 else "<b class='measured'>measured tank data</b>" if prov == "measured"
                 else f"<b class='mixed'>{esc(prov)} data</b>")
        # the file name holds the dataset's name, which may hold '#', '?', '%' or spaces: URL-quoted
        # (a relative path of one segment), then HTML-escaped for the attribute
        items = "\n".join(f"<li><a href='{esc(quote(e['file'], safe=''))}'>{esc(e['notebook'])}</a></li>"
                          for e in group)
        ident = group[0].get("identity") or {}
        said = "".join(f"<tr><th>{esc(k)}</th><td>{esc(ident.get(k) or particulars.NOT_GIVEN)}</td></tr>"
                       for k in ("ship", "scale", "tank", "source", "provenance", "described in"))
        sections.append(f"<h2>Dataset <code>{esc(ds)}</code></h2>\n"
                        f"<p>{label} &middot; {group[0]['runs']} runs<br>"
                        f"<b>Ship and scale:</b> {esc(group[0].get('ship') or 'not given')}</p>\n"
                        f"<table class='identity'>{said}</table>\n"
                        f"<ul>\n{items}\n</ul>")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>tanktest reports</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto;line-height:1.6}}
.virtual{{color:#b00020}} .measured{{color:#1b5e20}} .mixed{{color:#e65100}}
table.identity th{{text-align:left;padding-right:1em;font-weight:normal;color:#555}}</style></head>
<body><h1>Tank-test pipeline reports</h1>
<p>Reproduction and extension of Meng et al., Ocean Engineering 294 (2024) 116853 (the paper's ship: the
KCS). One section per dataset: where its data come from, the ship, its scale, tank and source as its
dataset.toml gives them, then its reports.</p>
{chr(10).join(sections) if sections else "<p>no reports rendered yet</p>"}
</body></html>
"""
    dest = out_dir / "index.html"
    with atomic_path(dest, suffix=".html") as tmp:
        tmp.write_text(page, encoding="utf-8")
        tmp.chmod(0o644)
    return dest


def render_all(datasets: Sequence[str], notebooks: Sequence[str], out_dir: Path,
               root: Path = Path("data/processed"), kernel: str = KERNEL_NAME,
               keep_going: bool = False, progress: Callable[[str], None] | None = None,
               force: bool = True) -> tuple[list[Report], list[str]]:
    """Render every (dataset, notebook) pair.

    ``force=False`` re-renders only what changed: a page whose HTML exists and whose
    :func:`fingerprint` equals the one recorded in ``reports.json`` is kept (``Report.skipped``).
    All inputs are checked before any notebook runs: unless ``keep_going``, the first missing
    stage output raises InputError and nothing is written.  With ``keep_going`` the pairs whose
    inputs are present (and that run) are rendered and the others listed in ``errors``.

    Parameters
    ----------
    datasets : sequence of str
        Dataset names (folders of ``root``).
    notebooks : sequence of str
        Report names.
    out_dir : Path
        The reports' folder.
    root : Path
        The processed data's root.
    kernel : str
        The Jupyter kernel.
    keep_going : bool
        Render what can be rendered and list the rest, instead of stopping at the first error.
    progress : callable, optional
        Called with one line per page.
    force : bool
        Re-render pages that are up to date.

    Returns
    -------
    reports : list of Report
        The pages, rendered or kept.
    errors : list of str
        One line per pair that could not be rendered (``keep_going`` only).

    Raises
    ------
    InputError
        A missing stage output, unless ``keep_going``.
    """
    for nb in notebooks:
        if nb not in NOTEBOOKS:
            raise InputError(f"unknown notebook {nb!r} (known: {', '.join(NOTEBOOKS)})")
    pairs, errors = [], []
    for ds in datasets:
        for nb in notebooks:
            cat = Catalog(root=Path(root), dataset=ds)
            try:
                check_inputs(nb, cat)
                pairs.append((nb, cat))
            except InputError as exc:
                if not keep_going:
                    raise
                errors.append(str(exc))
    reports = []
    if not force:
        known = _manifest(out_dir)
        todo = []
        for nb, cat in pairs:
            dest = Path(out_dir) / f"{nb}-{cat.dataset}.html"
            entry = known.get(dest.name) or {}
            if dest.is_file() and entry.get("fingerprint") == fingerprint(nb, cat):
                reports.append(Report(nb, cat.dataset, dest, 0.0, entry.get("provenance", "unknown"),
                                      entry.get("runs", 0), entry.get("ship", ""), entry["fingerprint"],
                                      skipped=True, builtin_tank=entry.get("builtin_tank", False),
                                      identity=entry.get("identity") or {}))
            else:
                todo.append((nb, cat))
        pairs = todo
    if pairs:
        ensure_kernel(kernel)
    for nb, cat in pairs:
        if progress:
            progress(f"{nb}-{cat.dataset}")
        try:
            reports.append(render(nb, cat, out_dir, kernel))
        except PipelineError as exc:
            if not keep_going:
                if reports:
                    write_index(out_dir, reports)
                raise
            errors.append(str(exc))
    write_index(out_dir, reports)
    return reports, errors


def datasets_under(root: Path) -> list[str]:
    """Every dataset with processed runs under ``root`` (folders holding runs/index.json), sorted."""
    root = Path(root)
    if not root.is_dir():
        return []
    return sorted(p.name for p in root.iterdir() if (p / "runs" / "index.json").is_file())
