"""Helpers the report notebooks import: loading stage outputs, provenance banner, tables, figures.

The notebooks read ONLY stage outputs under ``<root>/<dataset>/`` (pipeline/catalog.py), through
:class:`Data`, which records every file it reads so the banner can list them with their SHA-256.
A missing file or column raises :class:`pipeline.errors.InputError` naming it (one line).

Units in every table and axis are those of docs/contract.md#run-data (s, m, m/s, deg, deg/s).
"""

from __future__ import annotations

import hashlib
import html as _html
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pipeline import paper
from pipeline.catalog import Catalog, is_builtin_tank
from pipeline.errors import InputError
from pipeline.io import read_frame, read_json
from pipeline.report import particulars

# The paper's figures (pipeline/paper.py; definitions docs/contract.md#metrics), shown beside ours:
# Tables 5 (the 20/20 zigzag) and 6 (the 10/10) by (zigzag, algorithm).
PAPER_TABLES_5_6 = {(amp, alg): row for amp, table in (("20/20", "table5"), ("10/10", "table6"))
                    for alg, row in paper.TABLES_5_6[table]["rows"].items()}
PAPER_IDENT_SECONDS = paper.IDENT_SECONDS    # s, identification time for the paper's window
PAPER_SHIP = paper.SHIP                      # the paper's ship: its values are for it alone
PAPER = paper.REFERENCE
ALG_LABEL = {"srukf-ffm": "SR-UKF-FFM", "ffm-ukf": "FFM-UKF"}
ALG_COLOR = {"srukf-ffm": "tab:red", "ffm-ukf": "tab:blue"}
UNITS = {"v": "m/s", "r": "deg/s", "psi": "deg", "delta": "deg", "u": "m/s", "time": "s",
         "x0": "m", "y0": "m"}

class Page:
    """The numbering of one report page: figures and tables numbered 1, 2, ... in the order shown.

    Made by :func:`setup` and held by the notebook (``page = nb.setup()``, then ``page.show(fig,
    caption)``, ``page.table(df, caption)``): the numbers live in this object, so two pages built in
    one process number their figures independently.
    """

    def __init__(self) -> None:
        self.figures = 0
        self.tables = 0

    def table(self, df: pd.DataFrame, caption: str, precision: int = 4, index: bool = True) -> None:
        """:func:`render_table` with the next table number (then :attr:`tables`)."""
        self.tables += 1
        render_table(df, caption, self.tables, precision=precision, index=index)

    def show(self, fig, caption: str) -> None:
        """:func:`render_figure` with the next figure number (then :attr:`figures`)."""
        self.figures += 1
        render_figure(fig, caption, self.figures)

    def flags_table(self, groups: list[tuple[str, list[dict] | None]], caption: str) -> int:
        """One table of every flag (:func:`flag_rows`).  Returns the number of flags (0: a note says
        that no check failed)."""
        rows = flag_rows(groups)
        if rows:
            self.table(pd.DataFrame(rows).set_index(["set", "check"]), caption)
        else:
            note("No trust check failed for the numbers in this report.")
        return len(rows)

    def full_scale_rows(self, df: pd.DataFrame, data: Data, caption: str,
                        skip: tuple[str, ...] = ()) -> None:
        """For full-scale data, the table of :func:`full_scale_frame`; nothing for model-scale data."""
        got = full_scale_frame(df, data, caption, skip)
        if got is not None:
            self.table(*got)


def setup() -> Page:
    """Plot and display defaults: inline PNG (embedded as base64 in the HTML), readable sizes, text in
    figures taken literally (no mathtext).  Returns the page's :class:`Page` (figure and table
    numbers from 1)."""
    import matplotlib as mpl

    try:
        from matplotlib_inline.backend_inline import set_matplotlib_formats
        set_matplotlib_formats("png")
    except ImportError:   # pragma: no cover - older IPython
        pass
    mpl.rcParams.update({
        "figure.figsize": (10, 4), "figure.dpi": 90, "savefig.dpi": 90, "axes.grid": True,
        "grid.alpha": 0.3, "axes.titlesize": 11, "axes.labelsize": 10, "legend.fontsize": 9,
        "lines.linewidth": 1.2, "figure.constrained_layout.use": True,
        # run ids, test and ship names come from the user's files: '$x$' in one of them is text, never
        # matplotlib mathtext (an unknown '$\\macro$' would stop the page); no figure uses mathtext
        "text.parse_math": False,
    })
    pd.set_option("display.precision", 4)
    return Page()


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


DATASET_ENV = "TANKTEST_DATASET"   # the dataset a notebook opens on in JupyterLab (make lab D=NAME)
ROOT_ENV = "TANKTEST_ROOT"         # the processed-data root, when not this project's data/processed


def default_root() -> Path:
    """The processed-data root a notebook reads when its ``root`` parameter is empty: ``$TANKTEST_ROOT``
    if set, else ``data/processed`` under the working folder or, for a notebook opened in JupyterLab
    (whose kernel runs in ``notebooks/``), under its parent.  A folder that does not exist is returned as
    it is, so the first read names it."""
    env = os.environ.get(ROOT_ENV)
    if env:
        return Path(env)
    here = Path.cwd()
    for base in (here, here.parent):
        if (base / "data" / "processed").is_dir():
            return base / "data" / "processed"
    return here / "data" / "processed"


class Data:
    """Read-only access to one dataset's stage outputs; remembers what was read.

    ``root``: the processed-data root ('' or None: :func:`default_root`); ``dataset``: its folder name.
    """

    def __init__(self, root: str | Path | None, dataset: str):
        self.cat = Catalog(root=Path(root) if root else default_root(), dataset=dataset)
        self.used: list[Path] = []
        self._index: dict | None = None

    @property
    def dataset(self) -> str:
        return self.cat.dataset

    def path(self, rel: str | Path) -> Path:
        return self.cat.base / rel

    def _use(self, rel: str | Path) -> Path:
        p = self.path(rel)
        if not p.is_file():
            raise InputError("stage output missing (run that stage first)", file=p)
        if p not in self.used:
            self.used.append(p)
        return p

    def exists(self, rel: str | Path) -> bool:
        return self.path(rel).is_file()

    def json(self, rel: str | Path) -> Any:
        return read_json(self._use(rel))

    def frame(self, rel: str | Path, columns: tuple[str, ...] = ()) -> pd.DataFrame:
        p = self._use(rel)
        df, _ = read_frame(p)
        for c in columns:
            if c not in df.columns:
                raise InputError("column missing from stage output", file=p, column=c)
        return df

    def csv(self, rel: str | Path) -> pd.DataFrame:
        return pd.read_csv(self._use(rel))

    # runs (ingest outputs)
    @property
    def index(self) -> dict:
        if self._index is None:
            self._index = self.json("runs/index.json")
        return self._index

    @property
    def provenance(self) -> str:
        return str(self.index.get("provenance", "unknown"))

    @property
    def builtin_tank(self) -> bool:
        """The runs are the built-in virtual tank's (:func:`pipeline.catalog.is_builtin_tank`)."""
        self.runs()                               # no runs listed: refused, as every page does
        return is_builtin_tank(self.index)

    @property
    def ships(self) -> list[str]:
        """The ship names the runs give (sorted, distinct; empty when none is named)."""
        runs = self.runs()
        return sorted({str(x) for x in runs["ship"].dropna()}) if "ship" in runs.columns else []

    @property
    def full_scale(self) -> float | None:
        """Froude scale (full/model, -) when the user's files are at full scale, else None
        (:func:`pipeline.report.particulars.full_scale_factor`)."""
        return particulars.full_scale_factor(self.index)

    @property
    def paper_label(self) -> str:
        """Column label of the paper's values: 'paper' beside the KCS, 'paper (KCS)' beside another
        ship (or one not named), so the paper's ship is never taken for this dataset's."""
        return "paper" if self.ships == [PAPER_SHIP] else f"paper ({PAPER_SHIP})"

    @property
    def source_label(self) -> str:
        """Legend label of the logged signals: says plainly whether they are measured, the built-in
        virtual tank's, or a user's own simulated runs."""
        if self.provenance != "virtual":
            return "tank (measured)"
        return "virtual tank (logged)" if self.builtin_tank else "simulated (logged)"

    def runs(self) -> pd.DataFrame:
        """The runs index as a table (one row per run)."""
        df = pd.DataFrame(self.index.get("runs", []))
        if df.empty:
            raise InputError("no runs listed", file=self.cat.runs_index)
        return df

    def run(self, run_id: str) -> pd.DataFrame:
        entry = next((r for r in self.index.get("runs", []) if r.get("run_id") == run_id), None)
        name = Path((entry or {}).get("file") or f"{run_id}.parquet").name
        return self.frame(Path("runs") / name, ("time", "psi", "r", "delta"))

    def run_label(self, run_id: str) -> str:
        entry = next((r for r in self.index.get("runs", []) if r.get("run_id") == run_id), {})
        name = entry.get("test_name")
        return f"{run_id} ({name})" if name else str(run_id)

    def short_label(self, run_id: str) -> str:
        """Compact label for axes: '20/20 S' for a zigzag, 'turn 35 P', else the run_id."""
        entry = next((r for r in self.index.get("runs", []) if r.get("run_id") == run_id), {})
        side = {"starboard": " S", "port": " P"}.get(entry.get("first_side") or "", "")
        if entry.get("kind") == "zigzag" and entry.get("rudder_deg") is not None:
            return f"{entry['rudder_deg']:g}/{entry.get('heading_deg') or 0:g}{side}"
        if entry.get("kind") == "turning" and entry.get("rudder_deg") is not None:
            return f"turn {entry['rudder_deg']:g}{side}"
        return str(run_id)

    def amplitude(self, run_id: str) -> str | None:
        """'20/20' style label of a zigzag run from the runs index, else None."""
        entry = next((r for r in self.index.get("runs", []) if r.get("run_id") == run_id), {})
        if entry.get("kind") != "zigzag" or entry.get("rudder_deg") is None:
            return None
        return f"{entry['rudder_deg']:g}/{entry.get('heading_deg') or 0:g}"


    def sort_key(self, run_id: str) -> tuple:
        """Table order of a run (:func:`run_sort_key`)."""
        entry = next((r for r in self.index.get("runs", []) if r.get("run_id") == run_id), {"run_id": run_id})
        return run_sort_key(entry)


# ----------------------------------------------------------------------------------------- banner
def _kv_table(rows: list[tuple[str, Any]]) -> str:
    cells = "".join(f"<tr><th style='text-align:left'>{esc(k)}</th>"
                    f"<td style='text-align:left'>{esc(v)}</td></tr>" for k, v in rows)
    return f"<table>{cells}</table>"


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, (list, tuple)):
        return "(" + ", ".join(_fmt(x) for x in v) + ")"
    return "" if v is None else str(v)


def flatten(obj: Any, prefix: str = "") -> dict[str, Any]:
    """Nested dicts to one level with dotted keys (lists of scalars kept as they are)."""
    out: dict[str, Any] = {}
    if isinstance(obj, dict):
        for k, v in obj.items():
            out.update(flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    else:
        out[prefix] = obj
    return out


def banner(data: Data, title: str, settings: dict[str, Any] | None = None):
    """The provenance banner every report starts with (returns an IPython HTML object).

    Provenance in large type (VIRTUAL TANK in red, measured in green), the runs with their source
    files and SHA-256 (from runs/index.json), the stage outputs read with their SHA-256, settings.
    """
    from IPython.display import HTML

    prov = data.provenance
    runs = data.runs()
    ships = data.ships
    if data.builtin_tank:
        box = ("#b00020", "VIRTUAL TANK: simulated data, NOT measured",
               "Every figure and table below comes from the built-in virtual tank (3-DOF MMG model of "
               "the KCS at model scale 1:37.89, SIMMAN 2020 deep water), run through the same stages "
               "as measured data.")
    elif prov == "virtual":   # a user's simulated runs: not the built-in tank, whatever their ship
        box = ("#b00020", "SIMULATED data, NOT measured",
               f"The runs of dataset {data.dataset!r} say they are simulated (ship: "
               f"{', '.join(ships) or 'not stated'}); they are not the built-in KCS tank.  Every figure "
               "and table below comes from them, run through the same stages as measured data.")
    elif prov == "measured":
        box = ("#1b5e20", "MEASURED tank data", "Runs measured in a towing tank (free-running model).")
    else:
        box = ("#e65100", f"{prov.upper()} data: measured and virtual runs mixed",
               "Check the provenance column of the run table.")
    cols = [c for c in ("run_id", "test_name", "provenance", "source_file", "source_format",
                        "source_sha256", "dt", "duration", "samples") if c in runs.columns]
    run_rows = "".join("<tr>" + "".join(f"<td style='text-align:left'>{esc(r[c])}</td>"
                                        for c in cols) + "</tr>" for _, r in runs.iterrows())
    run_head = "".join(f"<th style='text-align:left'>{esc(c)}</th>" for c in cols)
    files = [(str(p.relative_to(data.cat.base)), _sha256(p)) for p in data.used]
    file_rows = "".join(f"<tr><td style='text-align:left'>{esc(f)}</td>"
                        f"<td style='text-align:left'><code>{esc(s)}</code></td></tr>" for f, s in files)
    flat = flatten(settings or {})
    # No wall clock on the page: it is a function of its inputs alone (the same inputs give the same
    # bytes); when it was rendered and how long it took are in reports/timing.json (docs/reports.md)
    ship = esc(particulars.summary(data.index))
    ship_rows = _kv_table(particulars.rows(data.index))
    ident = particulars.identity(data.index)
    said = " &middot; ".join(f"<b>{esc(k.capitalize())}:</b> {esc(ident[k])}"
                             for k in ("tank", "source", "provenance", "described in"))
    text = f"""
<div style="border:3px solid {box[0]};border-radius:6px;padding:10px 14px;margin:4px 0 12px 0">
<div style="font-size:1.8em;font-weight:bold;color:{box[0]}">{esc(box[1])}</div>
<div style="margin:4px 0 8px 0">{esc(box[2])}</div>
<div><b>{esc(title)}</b> &middot; dataset <code>{esc(data.dataset)}</code> &middot;
{len(runs)} runs &middot; reproduces and extends Meng et al., Ocean Engineering 294 (2024) 116853</div>
<div style="margin:6px 0 2px 0;font-size:1.1em"><b>Ship and scale:</b> {ship}</div>
<div class="dataset-identity">{said}</div>
<div class="scale-note" style="margin:2px 0"><b>Scale:</b> {esc(particulars.scale_sentence(data.index))}</div>
<details><summary>Particulars (from runs/index.json)</summary>{ship_rows}</details>
<details><summary>Runs: source files and SHA-256</summary>
<table><tr>{run_head}</tr>{run_rows}</table></details>
<details><summary>Stage outputs this report read ({len(files)} files, SHA-256)</summary>
<table><tr><th style='text-align:left'>file (under {esc(str(data.cat.base))})</th>
<th style='text-align:left'>SHA-256</th></tr>{file_rows}</table></details>
<details><summary>Settings</summary>{_kv_table(list(flat.items()))}</details>
</div>"""
    return HTML(text)


# ---------------------------------------------------------------------------------- tables, figs
def esc(value: Any) -> str:
    """THE escaping path for data-derived text in the reports: any value to HTML-safe text.

    Run ids come from file names and test/ship names from file headers, so they may hold markup;
    everything a report writes as HTML from data goes through here (tables, captions, notes,
    figure captions, the banner).  Quotes are escaped too, so the result is safe in attributes.
    """
    return _html.escape(_fmt(value) if not isinstance(value, str) else value, quote=True)


def render_table(df: pd.DataFrame, caption: str, number: int, *, precision: int = 4,
                 index: bool = True) -> None:
    """Display ``df`` as table ``number``, captioned, in HTML (numbers to ``precision`` significant
    digits).

    Every cell, index label, column label and the caption go through :func:`esc` (data-derived
    strings never become markup).  The table id is fixed (``tab<N>``, N = ``number``) and cells carry
    no ids, so the same inputs give the same bytes.
    """
    from IPython.display import HTML, display

    def fmt(x):
        if isinstance(x, (float, np.floating)):
            if not math.isfinite(x):
                return "–"
            return f"{x:.{precision}g}"
        if isinstance(x, (bool, np.bool_)):
            return "yes" if x else "no"
        return "–" if x is None else esc(x)

    def fmt_label(x):
        return esc("" if x is None else x)

    from pandas.io.formats.style import Styler

    styler = Styler(df, uuid=f"tab{number}", cell_ids=False).format(fmt)
    styler = styler.format_index(fmt_label, axis=0).format_index(fmt_label, axis=1)
    styler = styler.set_caption(f"Table {number}. {esc(caption)}")
    styler = styler.set_table_styles([{"selector": "caption", "props": "caption-side: top; "
                                       "text-align: left; font-weight: bold; padding: 4px 0;"}])
    # words read left to right, numbers stay right-aligned (class selectors: no cell ids needed)
    text = {c: [{"selector": "td", "props": "text-align: left;"},
                {"selector": "th", "props": "text-align: left;"}]
            for c in df.columns if not pd.api.types.is_numeric_dtype(df[c])}
    if text:
        styler = styler.set_table_styles(text, overwrite=False)
    if not index:
        styler = styler.hide(axis="index")
    display(HTML(styler.to_html()))


def plain_log_ticks(fig) -> None:
    """Label every logarithmic axis of ``fig`` with plain numbers (0.01, 0.1, 1, 10): matplotlib's
    default log labels are mathtext, which :func:`setup` turns off, so they would print as source."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    for ax in fig.axes:
        for axis, scale in ((ax.xaxis, ax.get_xscale()), (ax.yaxis, ax.get_yscale())):
            if scale == "log":
                axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
                axis.set_minor_formatter(NullFormatter())


def render_figure(fig, caption: str, number: int) -> None:
    """Display a figure (PNG) as figure ``number`` with a caption that says what to see; closes it."""
    import matplotlib.pyplot as plt
    from IPython.display import HTML, display

    plain_log_ticks(fig)
    display(fig)
    plt.close(fig)
    display(HTML(f"<p style='margin:0 0 1.2em 0'><b>Figure {number}.</b> {esc(caption)}</p>"))


def note(text: str) -> None:
    """A short paragraph of HTML-escaped text (e.g. what is absent and why)."""
    from IPython.display import HTML, display

    display(HTML(f"<p><i>{esc(text)}</i></p>"))


def time_axes(axes, data: Data) -> None:
    """Label the shared time axis of a figure with its scale: 'time, model scale (s)' on the bottom
    axes and, for full-scale data (:attr:`Data.full_scale`), a second axis on top of the first axes in
    full-scale seconds (t_full = t_model sqrt(scale)).  ``axes``: one Axes or a sequence, top first."""
    axs = list(np.ravel(axes)) if not hasattr(axes, "plot") else [axes]
    lam = data.full_scale
    if lam is None:
        return
    k = math.sqrt(lam)
    axs[-1].set_xlabel("time, model scale (s)")
    top = axs[0].secondary_xaxis("top", functions=(lambda t: t * k, lambda t: t / k))
    top.set_xlabel(f"time, full scale 1:{lam:g} (s)")


def with_full_scale(df: pd.DataFrame, data: Data, columns: tuple[str, ...] | None = None) -> pd.DataFrame:
    """``df`` with, for full-scale data, a full-scale column after each column whose label ends in a
    Froude-scaled unit ('rise time (s)' gets 'rise time, full scale (s)'; m/s gets kn); the model
    columns are relabelled '..., model scale (unit)'.  ``columns`` limits which columns (default: all
    that qualify).  Model-scale data: ``df`` unchanged."""
    lam = data.full_scale
    if lam is None:
        return df
    out = {}
    for c in df.columns:
        conv = particulars.full_scale_label(str(c), lam) if columns is None or c in columns else None
        if conv is None:
            out[c] = df[c]
            continue
        name = str(c)[: str(c).rindex("(")].rstrip()
        out[f"{name}, model scale {str(c)[str(c).rindex('('):]}"] = df[c]
        factor = particulars.full_scale_label(str(c), lam, 1.0)[1]      # Froude scaling is linear
        out[conv[0]] = pd.to_numeric(df[c], errors="coerce") * factor
    return pd.DataFrame(out, index=df.index)


def full_scale_frame(df: pd.DataFrame, data: Data, caption: str,
                     skip: tuple[str, ...] = ()) -> tuple[pd.DataFrame, str] | None:
    """The full-scale table of :meth:`Page.full_scale_rows` and its caption: the rows of ``df`` whose
    index label ends in a Froude-scaled unit ('T1 (s)'), at full scale 1:lambda (times x sqrt lambda,
    rates / sqrt lambda), columns ``skip`` left out; None for model-scale data or when no row scales."""
    lam = data.full_scale
    if lam is None:
        return None
    rows = {}
    for lab, row in df.drop(columns=[c for c in skip if c in df.columns]).iterrows():
        conv = particulars.full_scale_label(str(lab), lam)
        if conv is None:
            continue
        factor = particulars.full_scale_label(str(lab), lam, 1.0)[1]
        rows[conv[0]] = pd.to_numeric(row, errors="coerce") * factor
    if not rows:
        return None
    # columns with no number (flags, words) say nothing at full scale
    return (pd.DataFrame.from_dict(rows, orient="index").dropna(axis=1, how="all"),
            f"{caption} At full scale 1:{lam:g} (Froude: times x {math.sqrt(lam):.3g}, rates / "
            f"{math.sqrt(lam):.3g}).")


def paper_note(data: Data) -> None:
    """Say whose the paper's values are when this dataset's ship is not the paper's."""
    if data.ships != [PAPER_SHIP]:
        note(f"The paper's values are for its ship, the {PAPER_SHIP} ({PAPER}), not for this dataset's "
             f"{', '.join(data.ships) or 'ship (not named)'}.")


def label(name: str) -> str:
    """Axis label with unit, e.g. 'r (deg/s)'."""
    return f"{name} ({UNITS[name]})" if name in UNITS else name


def pick(df: pd.DataFrame, *names: str) -> str | None:
    """The first of ``names`` that is a column of ``df`` (for columns the contract leaves open)."""
    return next((n for n in names if n in df.columns), None)


def records(obj: Any, key: str = "run_id") -> list[dict]:
    """A JSON collection as a list of dicts: a list, ``{"runs": [...]}``, or ``{id: {...}}``."""
    if isinstance(obj, list):
        return [r for r in obj if isinstance(r, dict)]
    if isinstance(obj, dict):
        for k in ("runs", "rows", "items", "results"):
            if isinstance(obj.get(k), list):
                return [r for r in obj[k] if isinstance(r, dict)]
            if isinstance(obj.get(k), dict):
                return records(obj[k], key)
        out = []
        for k, v in obj.items():
            if isinstance(v, dict):
                out.append({key: k, **v})
        return out
    return []


# ------------------------------------------------------------------------- reviewer-facing helpers
def legend_outside(ax, **kw) -> None:
    """Legend to the right of the axes, never over the curves."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0,
                  frameon=False, **kw)


def num(x: Any, digits: int = 3, unit: str = "") -> str:
    """A number as plain text for sentences ('n/a' for None/NaN), with its unit."""
    if x is None or isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)):
        return "n/a" if x is None else str(x)
    if not math.isfinite(float(x)):
        return "n/a"
    return f"{float(x):.{digits}g}" + (f" {unit}" if unit else "")


CHECK_LABEL = {"relative_uncertainty": "uncertain", "invalid_draws": "invalid draws", "nis": "NIS",
               "sign": "sign", "ill_conditioned": "ill-conditioned", "prime_unavailable": "no K', T'",
               "excitation": "excitation", "phase_margin": "phase margin", "rejected": "not used",
               "nis_mean": "NIS", "innovation_whiteness": "innovations not white"}


def flag_marks(flags: list[dict] | None, subject: str | None = None) -> str:
    """Short text for a table cell: the checks that failed (for ``subject``, or the whole set)."""
    out = []
    for f in flags or []:
        subj = str(f.get("subject", ""))
        if subject is None or subj == "filter" or subject in {x.strip() for x in subj.split(",")}:
            lab = CHECK_LABEL.get(str(f.get("check")), str(f.get("check")).replace("_", " "))
            if lab not in out:
                out.append(lab)
    return ", ".join(out)


def flag_rows(groups: list[tuple[str, list[dict] | None]]) -> list[dict[str, Any]]:
    """The rows of a flags table: set, check (its reader's label), about what, the reason."""
    return [{"set": name, "check": CHECK_LABEL.get(str(f.get("check")), str(f.get("check"))),
             "about": f.get("subject", ""), "reason": f.get("reason", "")}
            for name, flags in groups for f in flags or []]


def conclusion(points: list[str]) -> None:
    """The short conclusion that ends every report (escaped plain-text points)."""
    from IPython.display import HTML, display

    items = "".join(f"<li>{esc(p)}</li>" for p in points if p)
    display(HTML("<div class='conclusion' style='border-left:4px solid #555;padding:4px 12px;margin:12px 0'>"
                 f"<ul style='margin:4px 0'>{items}</ul></div>"))


def run_sort_key(entry: dict) -> tuple:
    """Order of runs in tables: zigzags by rudder angle then heading trigger then side, then turning
    circles by rudder angle, then the rest by run id."""
    kind = {"zigzag": 0, "turning": 1}.get(entry.get("kind") or "", 2)
    rud = entry.get("rudder_deg") or 0.0
    head = entry.get("heading_deg") or 0.0
    side = {"starboard": 0, "port": 1}.get(entry.get("first_side") or "", 2)
    return (kind, float(rud), float(head), side, str(entry.get("run_id")))
