"""Write notebooks/*.ipynb (run ``python -m pipeline.report._build_notebooks`` after editing).

The notebooks are committed as plain .ipynb; this script is their source so that they stay small,
consistent and reviewable.  Each has a cell tagged ``parameters`` (papermill injects the dataset and
the processed root after it) and reads only stage outputs, through :mod:`pipeline.report.nb`.
"""

from __future__ import annotations

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

NOTEBOOK_DIR = Path(__file__).resolve().parents[2] / "notebooks"

PARAMS_COMMON = '''# Parameters (papermill injects the real values after this cell)
dataset = "virtual"            # data/processed/<dataset>/
root = "data/processed"        # processed-data root
'''

SETUP = '''import numpy as np  # noqa: F401  (for analysts who dig further)
import pandas as pd
import matplotlib.pyplot as plt
from IPython.display import display
from pipeline.report import nb
nb.setup()
data = nb.Data(root, dataset)
'''


def _nb(cells: list) -> nbformat.NotebookNode:
    book = new_notebook(cells=cells)
    for i, cell in enumerate(book.cells):      # stable ids: rebuilding gives the same files
        cell["id"] = f"cell-{i:02d}"
    book.metadata["kernelspec"] = {"name": "tanktest", "display_name": "tanktest (.venv)",
                                   "language": "python"}
    book.metadata["language_info"] = {"name": "python"}
    return book


def _params(extra: str = "") -> nbformat.NotebookNode:
    cell = new_code_cell(PARAMS_COMMON + extra)
    cell.metadata["tags"] = ["parameters"]
    return cell


def md(text: str):
    return new_markdown_cell(text.strip())


def code(text: str):
    return new_code_cell(text.strip())


# ------------------------------------------------------------------------------ identification
IDENTIFICATION = [
    md("# Online identification of the sway-yaw model\n"
       "SR-UKF-FFM (our square-root UKF with fuzzy fading memory) beside the FFM-UKF baseline "
       "(filterpy UKF, same fuzzy forgetting factor), as in the paper's Figs 2-3 and Tables 4-6."),
    _params('algorithms = ["srukf-ffm", "ffm-ukf"]   # algorithms shown, in this order\n'
            'zoom_seconds = None          # if set, the time-series figures show only the first N s\n'
            'max_heldout_plotted = 3       # held-out runs drawn (10/10 and 20/20 first)\n'),
    code(SETUP + '''
est = {a: data.json(f"identify/{a}/estimates.json") for a in algorithms}
trace = {a: data.frame(f"identify/{a}/trace.parquet", ("time", "delta", "r", "psi"))
         for a in algorithms}
metrics = data.json("validate/metrics.json")
pred = data.frame("validate/predictions.parquet",
                  ("algorithm", "run_id", "mode", "time", "r", "psi", "delta", "r_pred", "psi_pred"))
# v (sway) is optional: a dataset without a sway measurement has no v panel
ident_run = metrics.get("ident_run") or est[algorithms[0]].get("run_id")
settings = {"identification run": data.run_label(ident_run),
            "samples": est[algorithms[0]].get("samples"),
            **{f"{a} settings": est[a].get("settings", {}) for a in algorithms}}
display(nb.banner(data, "Online identification and validation", settings))
'''),
    md("## Online prediction against the tank data\n"
       "Identification window: the filter's one-step prediction of each sample made before it is "
       "seen; after the window, the validation predictions (one-step: the filter continues from "
       "the identified state; free-run: the identified model simulated from the measured initial "
       "state, driven only by the measured rudder)."),
    code('''
def series_figure(run_id, mode, title):
    fig, axes = plt.subplots(4, 1, figsize=(10, 8.5), sharex=True)
    first = True
    for a in algorithms:
        p = pred[(pred.algorithm == a) & (pred.run_id == run_id) & (pred["mode"] == mode)]
        parts = []
        if run_id == ident_run and mode == "one-step":
            parts.append(trace[a])
        parts.append(p)
        if not any(len(x) for x in parts):
            continue
        for ax, c in zip(axes[:3], ("v", "r", "psi"), strict=True):
            if first:
                for x in parts:
                    if c in x:
                        ax.plot(x["time"], x[c], color="0.3", lw=1.0,
                                label=data.source_label if x is parts[0] else None)
            for x in parts:
                col = f"{c}_pred"
                if col in x and c in x:
                    ax.plot(x["time"], x[col], color=nb.ALG_COLOR.get(a), lw=0.9, alpha=0.85,
                            label=f"{nb.ALG_LABEL.get(a, a)} {mode}" if x is parts[0] else None)
            ax.set_ylabel(nb.label(c))
        if first:
            for x in parts:
                axes[3].plot(x["time"], x["delta"], color="k", lw=1.0)
        first = False
    axes[3].set_ylabel(nb.label("delta"))
    axes[3].set_xlabel(nb.label("time"))
    if run_id == ident_run and len(trace[algorithms[0]]):
        for ax in axes:
            ax.axvline(trace[algorithms[0]]["time"].iloc[-1], color="g", ls=":", lw=1)
    if zoom_seconds:
        axes[0].set_xlim(0, zoom_seconds)
    axes[1].legend(loc="upper right", ncol=3)
    axes[0].set_title(title)
    return fig

held = [r for r in dict.fromkeys(pred.run_id) if r != ident_run]
held.sort(key=lambda r: (data.amplitude(r) not in ("10/10", "20/20"), r))   # the paper's runs first
ordered = [ident_run] + held[:max_heldout_plotted]
if len(held) > max_heldout_plotted:
    nb.note(f"{len(held) - max_heldout_plotted} more held-out runs are in the tables below, not drawn "
            f"(max_heldout_plotted = {max_heldout_plotted}).")
for rid in ordered:
    lab = data.run_label(rid)
    if rid == ident_run:
        fig = series_figure(rid, "one-step", f"Identification run {lab}: one-step prediction")
        nb.show(fig, f"Identification run {lab} (paper Fig. 2): measured v, r, psi (grey) and the "
                "one-step predictions of both filters; the dotted green line ends the identification "
                "window. Look for how quickly the predictions lock on to the data and how closely "
                "they follow it after the window.")
    else:
        fig = series_figure(rid, "one-step", f"Held-out run {lab}: one-step prediction")
        nb.show(fig, f"Held-out run {lab} (paper Fig. 3): one-step predictions of both filters "
                "against the tank data, with the parameters identified on the identification run.")
    if (pred.run_id == rid).any() and (pred["mode"] == "free-run").any():
        fig = series_figure(rid, "free-run", f"{lab}: free-run simulation")
        nb.show(fig, f"{lab}: free-run simulation of the identified models from the measured "
                "initial state, driven only by the measured rudder. This is the honest test of a "
                "model: errors accumulate in heading instead of being corrected every step.")
'''),
    md("## Parameter convergence\nEstimates of the six parameters over the identification window "
       "with one-sigma bands from the filter covariance; dashed: the paper's Table 4."),
    code('''
from pipeline.model import PAPER_TABLE4, PARAM_NAMES
fig, axes = plt.subplots(2, 3, figsize=(11, 5.5), sharex=True)
for ax, p in zip(axes.flat, PARAM_NAMES, strict=True):
    for a in algorithms:
        tr = trace[a]
        if p not in tr:
            continue
        ax.plot(tr["time"], tr[p], color=nb.ALG_COLOR.get(a), label=nb.ALG_LABEL.get(a, a))
        if f"{p}_std" in tr:
            ax.fill_between(tr["time"], tr[p] - tr[f"{p}_std"], tr[p] + tr[f"{p}_std"],
                            color=nb.ALG_COLOR.get(a), alpha=0.18, lw=0)
    ax.axhline(PAPER_TABLE4[p], color="k", ls="--", lw=0.9, label="paper Table 4")
    ax.set_title(p)
    lo = min(float(np.nanpercentile(trace[a][p], 2)) for a in algorithms if p in trace[a])
    hi = max(float(np.nanpercentile(trace[a][p], 98)) for a in algorithms if p in trace[a])
    pad = 0.2 * (hi - lo + 1e-9)
    ax.set_ylim(min(lo, PAPER_TABLE4[p]) - pad, max(hi, PAPER_TABLE4[p]) + pad)
for ax in axes[1]:
    ax.set_xlabel(nb.label("time"))
axes[0, 0].legend()
nb.show(fig, "Parameter estimates with one-sigma bands (model of SPEC section 5 in data units: "
        "a11, a22 in 1/s; a12 in m/deg/s; a21 in deg/m/s; b11 in m/s^2 per deg; b21 in 1/s^2). "
        "A converged estimate is flat with a narrow band; the paper's values are for its KCS "
        "tank data and need not match another data set.")

rows = []
for p in PARAM_NAMES:
    row = {"parameter": p}
    for a in algorithms:
        e = est[a]
        cov = np.asarray(e.get("covariance") or np.full((6, 6), np.nan), dtype=float)
        k = PARAM_NAMES.index(p)
        row[f"{nb.ALG_LABEL.get(a, a)}"] = e["parameters"][p]
        row[f"{nb.ALG_LABEL.get(a, a)} std"] = float(np.sqrt(cov[k, k])) if cov.shape == (6, 6) else np.nan
    row["paper Table 4"] = PAPER_TABLE4[p]
    rows.append(row)
nb.table(pd.DataFrame(rows).set_index("parameter"),
         f"Identified parameters after {est[algorithms[0]].get('samples')} samples (one-sigma from "
         "the final filter covariance), beside the paper's Table 4.")
'''),
    md("## Forgetting factor and filter consistency"),
    code('''
fig, axes = plt.subplots(2, 1, figsize=(10, 5), sharex=True)
for a in algorithms:
    tr = trace[a]
    if "f" in tr:
        axes[0].plot(tr["time"], tr["f"], color=nb.ALG_COLOR.get(a), label=nb.ALG_LABEL.get(a, a))
    if "nis" in tr:
        axes[1].plot(tr["time"], tr["nis"], color=nb.ALG_COLOR.get(a), lw=0.7, alpha=0.8,
                     label=f"{nb.ALG_LABEL.get(a, a)} (mean {np.nanmean(tr['nis']):.2f})")
axes[0].set_ylabel("forgetting factor f (-)")
axes[0].set_ylim(0.945, 1.005)
axes[1].axhline(3.0, color="k", ls="--", lw=0.8, label="expected mean (3 measurements)")
axes[1].set_ylabel("NIS (-)")
axes[1].set_yscale("log")
axes[1].set_xlabel(nb.label("time"))
for ax in axes:
    ax.legend(loc="upper right")
nb.show(fig, "Top: the fuzzy forgetting factor f (always within [0.95, 1]); it drops when the "
        "innovations grow, which lets the filter forget old data. Bottom: normalised innovation "
        "squared; a consistent filter averages about 3 (the number of measurements).")
'''),
    md("## Validation errors (paper Tables 5 and 6)\n"
       "MSE of v (m/s)^2, MSE of r (deg/s)^2, MAE of psi (deg) over the validation samples. "
       "The paper's Table 5 is its identification run (20/20 zigzag) after the identification "
       "window, Table 6 the 10/10 zigzag; both one-step (online)."),
    code('''
m = pd.DataFrame(metrics["rows"])
for c in ("mse_v", "mse_r", "mae_psi"):
    m[c] = pd.to_numeric(m[c], errors="coerce")
m["zigzag"] = m["run_id"].map(data.amplitude)
labels = {"mse_v": "MSE v", "mse_r": "MSE r", "mae_psi": "MAE psi"}
# Table 5: the rest of the identification run (the paper's 20/20) and any other 20/20 run;
# Table 6: the 10/10 runs.  Other held-out runs are in the full table below.
in5 = (m["segment"] == "identification-rest") | (m["zigzag"] == "20/20")
groups = ((5, "20/20", in5), (6, "10/10", ~in5 & (m["zigzag"] == "10/10")))
for mode in ("one-step", "free-run"):
    for tab, amp, mask in groups:
        sub = m[(m["mode"] == mode) & mask]
        if sub.empty:
            continue
        rows = []
        for _, r in sub.iterrows():
            row = {"algorithm": nb.ALG_LABEL.get(r.algorithm, r.algorithm), "run": r.run_id,
                   "zigzag": r.zigzag, "segment": r.get("segment", "")}
            for c, name in labels.items():
                row[name] = r[c]
                row[f"{name} paper"] = nb.PAPER_TABLES_5_6.get((amp, r.algorithm), {}).get(c, np.nan)
            row["samples"] = r.get("samples")
            rows.append(row)
        nb.table(pd.DataFrame(rows).set_index("algorithm"),
                 f"{mode} errors, layout of the paper's Table {tab} ({amp} zigzag"
                 + (", identification run after the window" if tab == 5 else "") + "); "
                 "'paper' columns: the paper's one-step values"
                 + (", for scale only" if mode == "free-run" else ""))
all_rows = m[["algorithm", "run_id", "segment", "mode", "mse_v", "mse_r", "mae_psi", "samples"]]
nb.table(all_rows.set_index(["mode", "run_id", "algorithm"]).sort_index(),
         "All validation rows of validate/metrics.json (every held-out run, both modes).")
'''),
    md("## Timing"),
    code('''
rows = []
for a in algorithms:
    t = est[a].get("timing", {})
    rows.append({"algorithm": nb.ALG_LABEL.get(a, a), "samples": est[a].get("samples"),
                 "filter loop (s)": t.get("seconds_total"),
                 "per step (us)": 1e6 * t["seconds_per_step"] if t.get("seconds_per_step") else np.nan,
                 "paper (s)": nb.PAPER_IDENT_SECONDS if a == "srukf-ffm" else np.nan})
tt = pd.DataFrame(rows).set_index("algorithm")
nb.table(tt, "Identification time: the filter loop alone (no start-up, compilation or file I/O). "
         "The paper's 0.377 s is for 585 samples on its hardware.")
if len(algorithms) == 2 and all(est[a].get("timing", {}).get("seconds_per_step") for a in algorithms):
    per_step = [est[a]["timing"]["seconds_per_step"] for a in algorithms]
    ratio = per_step[1] / per_step[0]
    nb.note(f"{nb.ALG_LABEL.get(algorithms[0])} is {ratio:.0f} times faster per step than "
            f"{nb.ALG_LABEL.get(algorithms[1])} on the same samples.")
'''),
]


# ------------------------------------------------------------------------------------- indices
INDICES = [
    md("# Manoeuvring indices and zigzag analysis\n"
       "Second-order Nomoto indices from the identified parameters (paper Eq. 6) beside the Nomoto "
       "standard-test (graphical) K and T, in the layout of the paper's Table 7; ITTC zigzag and "
       "turning metrics with the IMO MSC.137(76) check."),
    _params('max_runs_plotted = 8          # zigzag runs drawn (in runs-index order)\n'),
    code(SETUP + '''
ind = data.json("indices/indices.json")
zz = data.json("indices/zigzag.json")
t7 = data.csv("indices/table7.csv") if data.exists("indices/table7.csv") else None
runs = data.runs()
display(nb.banner(data, "Manoeuvring indices", {
    "control model": (ind.get("control_model") or {}).get("source"),
    "graphical model": (ind.get("graphical_model") or {}).get("source")}))
'''),
    md("## Table 7: indices"),
    code('''
from pipeline.model import PAPER_GRAPHICAL, PAPER_TABLE7, INDEX_NAMES
rows = []
for name in INDEX_NAMES:
    row = {"index": f"{name} ({'1/s' if name == 'K' else 's'})"}
    for alg, block in (ind.get("identified") or {}).items():
        v = block.get(name, {})
        row[f"{nb.ALG_LABEL.get(alg, alg)}"] = v.get("value") if isinstance(v, dict) else v
        row[f"{nb.ALG_LABEL.get(alg, alg)} std"] = v.get("std") if isinstance(v, dict) else np.nan
    gm = ind.get("graphical_model") or {}
    row["graphical"] = gm.get(name, np.nan) if name in ("K", "T") else np.nan
    row["paper Table 7"] = PAPER_TABLE7[name]
    row["paper graphical"] = PAPER_GRAPHICAL.get(name, np.nan)
    rows.append(row)
nb.table(pd.DataFrame(rows).set_index("index"),
         "Nomoto indices (K in deg/s of yaw rate per deg of rudder, time constants in s) from the "
         "identified parameters with one-sigma bounds propagated from the filter covariance, beside "
         "the graphical (standard test) K and T of the identification run and the paper's values.")
if t7 is not None:
    nb.table(t7, "indices/table7.csv as written by the indices stage.", index=False)
g = pd.DataFrame(ind.get("graphical") or [])
if not g.empty and "run_id" in g:
    g["zigzag"] = g["run_id"].map(data.amplitude)
    first = [c for c in ("run_id", "zigzag", "method", "K", "T") if c in g]
    rest = [c for c in g.columns if c not in first and pd.api.types.is_numeric_dtype(g[c])]
    nb.table(g[first + rest].set_index([c for c in ("run_id", "method") if c in g]),
             "First-order K (1/s) and T (s) per zigzag run: 'standard' is the Nomoto standard-test "
             "(graphical) method, 'integral' the least-squares integral method. They change with the "
             "amplitude because the real ship is not linear.")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    ids = list(dict.fromkeys(g.run_id))
    for ax, q in zip(axes, ("K", "T"), strict=True):
        if q not in g:
            continue
        for meth, sub in g.groupby("method") if "method" in g else [("", g)]:
            ax.plot([ids.index(r) for r in sub.run_id], sub[q], "o", label=meth)
        ax.set_xticks(range(len(ids)))
        ax.set_xticklabels([data.short_label(r) for r in ids], rotation=45, ha="right", fontsize=8)
        ax.set_xlabel("zigzag run (rudder/heading, first side)")
        ax.axhline(PAPER_GRAPHICAL[q], color="k", ls="--", lw=0.8, label="paper graphical")
        ident = (ind.get("control_model") or {}).get(q)
        if ident is not None:
            ax.axhline(ident, color="tab:red", ls=":", lw=1.0, label="identified (control model)")
        ax.set_ylabel(f"{q} ({'1/s' if q == 'K' else 's'})")
    axes[0].legend(fontsize=8)
    nb.show(fig, "First-order K and T per run and method, with the identified (SR-UKF-FFM) values "
            "used by the autopilot and the paper's graphical values. The spread between runs shows "
            "how amplitude-specific the graphical indices are.")
'''),
    md("## Zigzag and turning metrics with the IMO check"),
    code('''
WANT = [("first_overshoot_deg", "1st overshoot (deg)"), ("second_overshoot_deg", "2nd overshoot (deg)"),
        ("third_overshoot_deg", "3rd overshoot (deg)"), ("time_to_check_yaw_s", "check yaw (s)"),
        ("initial_turning_time_s", "initial turning (s)"), ("period_s", "period (s)"),
        ("advance_L", "advance (L)"), ("transfer_L", "transfer (L)"),
        ("tactical_diameter_L", "tactical diam. (L)"), ("steady_diameter_L", "steady diam. (L)"),
        ("steady_speed_ratio", "steady speed ratio (-)"), ("steady_yaw_rate_deg_s", "steady r (deg/s)")]
def lookup(flat, key):
    hits = sorted((k for k in flat if (k == key or k.endswith("." + key))
                   and isinstance(flat[k], (int, float)) and not isinstance(flat[k], bool)), key=len)
    return flat[hits[0]] if hits else None
rows, crit = [], []
for rec in nb.records(zz):
    rid = rec.get("run_id", "?")
    flat = nb.flatten({k: v for k, v in rec.items() if k not in ("imo", "imo_check")})
    row = {"run": rid, "test": rec.get("test_name") or rec.get("kind") or ""}
    for key, lab in WANT:
        v = lookup(flat, key)
        if v is not None:
            row[lab] = v
    imo = rec.get("imo") or rec.get("imo_check") or {}
    row["IMO"] = ({True: "pass", False: "FAIL", None: "n/a"}.get(imo.get("pass"), str(imo.get("pass")))
                  if isinstance(imo, dict) else str(imo))
    if rec.get("errors"):
        row["note"] = "; ".join(map(str, rec["errors"]))
    rows.append(row)
    for c in (imo.get("criteria") or []) if isinstance(imo, dict) else []:
        crit.append({"run": rid, **{k: c.get(k) for k in ("name", "value", "limit", "unit", "pass")}})
ztab = pd.DataFrame(rows)
if ztab.empty:
    nb.note("indices/zigzag.json holds no per-run records.")
else:
    nb.table(ztab.set_index("run"), "ITTC 7.5-04-02-01 metrics per run (overshoot angles deg, "
             "times s, turning-circle distances in ship lengths) and the IMO MSC.137(76) verdict.")
if crit:
    nb.table(pd.DataFrame(crit).set_index("run"), "IMO criteria per run: value against limit.")
'''),
    md("## The zigzags"),
    code('''
zig = runs[runs["kind"] == "zigzag"] if "kind" in runs else runs
for _, r in zig.head(max_runs_plotted).iterrows():
    df = data.run(r.run_id)
    fig, ax = plt.subplots(figsize=(10, 3.2))
    ax.plot(df.time, df.psi, color="tab:blue", label=nb.label("psi"))
    ax.plot(df.time, df.delta, color="k", lw=1.0, label=nb.label("delta"))
    head = r.get("heading_deg")
    if head is not None and np.isfinite(head):
        for sgn in (1, -1):
            ax.axhline(sgn * head, color="0.5", ls=":", lw=0.8)
    ax.set_xlabel(nb.label("time"))
    ax.set_ylabel("angle (deg)")
    ax.set_title(data.run_label(r.run_id))
    ax.legend(loc="upper right")
    nb.show(fig, f"Zigzag {data.run_label(r.run_id)}: heading and rudder; dotted lines mark the "
            "heading triggers. Overshoots are how far the heading goes past the trigger after "
            "each rudder execute.")
turn = runs[runs["kind"] == "turning"] if "kind" in runs else runs.iloc[0:0]
if len(turn):
    fig, ax = plt.subplots(figsize=(6, 6))
    for _, r in turn.iterrows():
        df = data.run(r.run_id)
        if "x0" in df and "y0" in df:
            lpp = r.get("lpp") or 1.0
            ax.plot((df.y0 - df.y0.iloc[0]) / lpp, (df.x0 - df.x0.iloc[0]) / lpp,
                    label=data.run_label(r.run_id))
    ax.set_aspect("equal")
    ax.set_xlabel("y0 / L (-)")
    ax.set_ylabel("x0 / L (-)")
    ax.legend()
    nb.show(fig, "Turning-circle tracks in ship lengths from the approach point (x0 up, y0 to the "
            "right: starboard turns go right); advance, transfer and tactical diameter in the table "
            "above are read from these.")
'''),
]

# ------------------------------------------------------------------------------------- control
CONTROL = [
    md("# CGSA course-keeping autopilot\n"
       "Closed-loop gain-shaping (CGSA) autopilot designed from the identified Nomoto indices "
       "(and from the graphical K, T for comparison), simulated with wind, waves and rudder angle "
       "and rate limits (paper Figs 4 and 5)."),
    _params('seed_shown = None              # wave seed drawn in the figures (None: the first)\n'),
    code(SETUP + '''
ind = data.json("indices/indices.json")
cm = data.json("control/metrics.json")
ts = data.frame("control/timeseries.parquet", ("plant", "design", "seed", "time", "psi", "delta"))
cfg = cm.get("config") or {}
seed = seed_shown if seed_shown is not None else ts["seed"].iloc[0]
display(nb.banner(data, "Course-keeping control", {
    "control model (indices)": ind.get("control_model"), "graphical model": ind.get("graphical_model"),
    **{k: cfg[k] for k in ("tw", "setpoint", "duration", "dt", "rudder_max", "rudder_rate", "wind_rudder",
                           "seeds", "seed") if k in cfg},
    "wave seed shown": seed, "plants": [p for p, v in (cm.get("plants") or {}).items()
                                        if isinstance(v, dict) and v.get("used")]}))
for n_ in cm.get("notes") or []:
    nb.note(n_)
'''),
    md("## Designs and loop margins"),
    code('''
designs = cm.get("designs") or cm.get("design") or {}
rows = []
for name, d in designs.items():
    row = {"design": name}
    for k in ("order", "K", "T", "T1", "T2", "T3", "Tw", "Kp", "Kd", "filter_tau"):
        if k in d:
            row[k] = d[k]
    loop = d.get("loop_nomoto_plant") or d.get("loop") or d
    for k, lab in (("gain_margin_db", "GM (dB)"), ("phase_margin_deg", "PM (deg)"),
                   ("gain_crossover", "crossover (rad/s)"), ("bandwidth", "bandwidth (rad/s)"),
                   ("Ms", "Ms (-)")):
        if k in loop:
            row[lab] = loop[k] if loop[k] is not None else np.inf
    rows.append(row)
nb.table(pd.DataFrame(rows).set_index("design"),
         "CGSA designs (Kp deg of rudder per deg of heading error, Kd deg per deg/s) and the loop "
         "figures on the identified Nomoto plant: gain and phase margins, crossover, closed-loop "
         "bandwidth, sensitivity peak Ms (inf or empty: no phase crossover).")
bode = {n: d["bode_nomoto_plant"] for n, d in designs.items()
        if isinstance(d.get("bode_nomoto_plant"), dict)}
if bode:
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for n, b in bode.items():
        w = np.asarray(b["omega"], dtype=float)
        axes[0].semilogx(w, np.asarray(b["mag_db"], dtype=float), label=n)
        axes[1].semilogx(w, np.asarray(b["phase_deg"], dtype=float), label=n)
    axes[0].axhline(0, color="k", lw=0.8)
    axes[1].axhline(-180, color="k", lw=0.8)
    axes[0].set_ylabel("|L| (dB)")
    axes[1].set_ylabel("phase of L (deg)")
    axes[1].set_xlabel("frequency (rad/s)")
    axes[0].legend()
    nb.show(fig, "Open-loop Bode diagram of each design on the identified Nomoto plant. The phase "
            "margin is the distance of the phase from -180 deg where the gain crosses 0 dB.")
else:
    nb.note("control/metrics.json holds no Bode data.")
'''),
    md("## Course change from 0 to the set course with wind and waves (paper Figs 4 and 5)"),
    code('''
sel = ts[ts["seed"] == seed]
for plant, sub in sel.groupby("plant", sort=False):
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for design, s in sub.groupby("design", sort=False):
        line, = axes[0].plot(s.time, s.psi, label=f"{design}")
        axes[1].plot(s.time, s.delta, color=line.get_color(), lw=0.9, label=f"{design}")
    if "psi_ref" in sub:
        s0 = sub[sub.design == sub.design.iloc[0]]
        axes[0].plot(s0.time, s0.psi_ref, "k--", lw=0.9, label="set course")
    lim = cfg.get("rudder_max")
    if lim:
        for sg in (1, -1):
            axes[1].axhline(sg * lim, color="0.5", ls=":", lw=0.8)
    axes[0].set_ylabel(nb.label("psi"))
    axes[1].set_ylabel(nb.label("delta"))
    axes[1].set_xlabel(nb.label("time"))
    axes[0].legend(loc="lower right")
    axes[1].legend(loc="upper right")
    axes[0].set_title(f"plant: {plant}, wave seed {seed}")
    nb.show(fig, f"Plant '{plant}': heading (top, paper Fig. 4) and actual rudder (bottom, paper "
            "Fig. 5) for each design, one wave realisation. Look at the rise to the set course, the "
            "overshoot, and the rudder needed to hold course against the steady wind moment.")
'''),
    md("## Metrics over wave seeds, beside the paper"),
    code('''
paper = cm.get("paper") or {}
order = ["rise_time", "rise_time_10_90", "max_deviation", "steady_mae", "max_rudder", "steady_rudder_min",
         "steady_rudder_max", "mean_rudder", "rudder_rms", "rudder_energy", "rudder_reversals", "max_rate"]
units = {"rise_time": "s", "rise_time_10_90": "s", "max_deviation": "deg", "steady_mae": "deg",
         "max_rudder": "deg", "steady_rudder_min": "deg", "steady_rudder_max": "deg", "mean_rudder": "deg",
         "rudder_rms": "deg", "rudder_energy": "deg^2 s", "rudder_reversals": "-", "max_rate": "deg/s",
         "reach_time": "s"}
pmap = {k: paper.get(k) for k in ("rise_time", "max_deviation", "steady_mae", "steady_rudder_min",
                                  "steady_rudder_max", "mean_rudder")}
pmap["max_rudder"] = (f"< {paper['max_rudder_below']:g}" if "max_rudder_below" in paper
                     else paper.get("max_rudder"))
for res in nb.records(cm.get("results") or [], key="plant"):
    stats = res.get("stats") or res.get("metrics") or {}
    names = [n for n in order if n in stats] + [n for n in stats if n not in order]
    rows = []
    for n in names:
        s = stats[n] if isinstance(stats[n], dict) else {"mean": stats[n]}
        rows.append({"metric": f"{n} ({units[n]})" if n in units else n,
                     "mean": s.get("mean"), "std": s.get("std"), "worst": s.get("worst"),
                     "paper": "" if pmap.get(n) is None else str(pmap.get(n))})
    nb.table(pd.DataFrame(rows).set_index("metric"),
             f"Plant '{res.get('plant')}', design '{res.get('design')}': mean, standard deviation and "
             f"worst case over {res.get('seeds', '?')} wave seeds; the paper's figures beside them "
             "(its single run, Table 7 indices, Tw = 3 s).")
defs = cm.get("definitions")
if defs:
    nb.table(pd.DataFrame({"definition": {k: str(v) for k, v in defs.items()}}),
             "Metric definitions used by the control stage.")
val = cm.get("identification_value") or {}
for plant, block in val.items():
    rows = [{"metric": k, "mean difference": v.get("mean"), "std": v.get("std")}
            for k, v in (block.get("metrics") or {}).items()]
    if rows:
        nb.table(pd.DataFrame(rows).set_index("metric"),
                 f"The value of identification on plant '{plant}': identified-design minus "
                 "graphical-design metrics, paired over the same wave seeds (negative = identified "
                 "design faster or closer to course).")
'''),
]

# ------------------------------------------------------------------------------------ diagnosis
DIAGNOSIS = [
    md("# Diagnosis: what the linear model gets wrong\n"
       "The linear sway-yaw model (SPEC section 5) fitted on training runs is simulated free-run on "
       "held-out runs; each candidate effect (rudder offset, nonlinear yaw damping, rudder delay, "
       "speed loss) is tried as an extension and kept only when the held-out gain is real."),
    _params('max_runs_plotted = 6          # validation runs drawn\n'),
    code(SETUP + '''
dg = data.json("diagnose/diagnosis.json")
series = data.frame("diagnose/series.parquet", ("run_id", "time", "psi"))
display(nb.banner(data, "Model diagnosis", {"training runs": dg.get("training_runs"),
                                            "validation runs": dg.get("validation_runs"),
                                            **(dg.get("settings") or {})}))
'''),
    code('''
from IPython.display import HTML
gain = (dg.get("gain") or {}).get("mae_psi_relative_reduction")
cause = dg.get("cause", "?")
base_v = (dg.get("baseline") or {}).get("validation") or {}
ext_v = (dg.get("extended") or {}).get("validation") or {}
def f3(x):
    return f"{x:.3g}" if isinstance(x, (int, float)) else "?"
msg = (f"<div style='font-size:1.3em;margin:6px 0'>Cause: <b>{cause}</b>"
       + (f" &middot; held-out free-run MAE of psi reduced by <b>{100 * gain:.0f} %</b>"
          f" ({f3(base_v.get('mae_psi_deg'))} deg to {f3(ext_v.get('mae_psi_deg'))} deg)"
          if isinstance(gain, (int, float)) and cause != "none"
          else " (no effect brings a real held-out gain)")
       + "</div>")
display(HTML(msg))
if dg.get("summary"):
    nb.note(dg["summary"])
rows = []
for f in dg.get("findings") or []:
    est = f.get("estimate") or {}
    rows.append({"effect": f.get("effect"), "significant": f.get("significant"),
                 "validation_gain": f.get("validation_gain"),
                 "worth_in_extended": f.get("validation_gain_in_extended"),
                 "estimate": ", ".join(f"{k} = {v:.4g}" if isinstance(v, (int, float)) else f"{k} = {v}"
                                       for k, v in est.items()),
                 "evidence": f.get("evidence")})
if rows:
    nb.table(pd.DataFrame(rows).set_index("effect"),
             "Every effect tried, largest held-out gain first: validation_gain is the relative "
             "reduction of the mean free-run MAE of psi on the validation runs; significant needs both "
             "a real gain and an estimate clearly different from zero. worth_in_extended (effects of "
             "the extended model): the held-out gain of the extended model over the same model "
             "refitted without that effect.")
vrows = []
for name, block in (("baseline (linear)", dg.get("baseline") or {}),
                    ("extended: " + " + ".join((dg.get("extended") or {}).get("effects") or ["none"]),
                     dg.get("extended") or {})):
    v = block.get("validation") or {}
    vrows.append({"model": name, **{k: x for k, x in v.items() if not isinstance(x, (list, dict))}})
nb.table(pd.DataFrame(vrows).set_index("model"),
         "Free-run errors on the validation runs (MAE psi deg, MSE r (deg/s)^2, MSE v (m/s)^2).")
per = []
for label_, key in (("baseline", "baseline"), ("extended", "extended")):
    for p in (dg.get(key) or {}).get("per_run") or []:
        per.append({"model": label_, **{k: v for k, v in p.items() if not isinstance(v, (list, dict))}})
if per:
    pt = pd.DataFrame(per)
    idx = [c for c in ("run_id", "run", "name") if c in pt][:1]
    nb.table(pt.set_index(idx + ["model"]).sort_index(),
             "Per validation run: free-run errors of the baseline and the extended model.")
'''),
    md("## Measured against baseline and extended model, free-run"),
    code('''
for rid in list(dict.fromkeys(series.run_id))[:max_runs_plotted]:
    s = series[series.run_id == rid]
    has_r = all(c in s for c in ("r", "r_baseline", "r_extended"))
    fig, axes = plt.subplots(3 if has_r else 2, 1, figsize=(10, 7.5 if has_r else 5.5), sharex=True)
    ax = axes[0]
    ax.plot(s.time, s.psi, color="0.2", label=data.source_label)
    for c, col, lab in (("psi_baseline", "tab:blue", "baseline (linear)"),
                        ("psi_extended", "tab:red", "extended")):
        if c in s:
            ax.plot(s.time, s[c], color=col, lw=1.0, label=lab)
    ax.set_ylabel(nb.label("psi"))
    ax.legend(loc="upper right")
    ax.set_title(data.run_label(rid))
    if has_r:
        axes[1].plot(s.time, s.r, color="0.2")
        axes[1].plot(s.time, s.r_baseline, color="tab:blue", lw=1.0)
        axes[1].plot(s.time, s.r_extended, color="tab:red", lw=1.0)
        axes[1].set_ylabel(nb.label("r"))
    axr = axes[-1]
    for c, col, lab in (("psi_baseline", "tab:blue", "baseline residual"),
                        ("psi_extended", "tab:red", "extended residual")):
        if c in s:
            axr.plot(s.time, s.psi - s[c], color=col, lw=1.0, label=lab)
    if "delta" in s:
        ax2 = axr.twinx()
        ax2.plot(s.time, s.delta, color="0.6", lw=0.8)
        ax2.set_ylabel(nb.label("delta") + ", grey")
        ax2.grid(False)
    axr.set_ylabel("psi residual (deg)")
    axr.set_xlabel(nb.label("time"))
    axr.legend(loc="upper left")
    nb.show(fig, f"Validation run {data.run_label(rid)}: free-run heading (and yaw rate) of the "
            "baseline linear model and of the extended model against the measurement; bottom, the "
            "heading residuals (measured minus model) with the rudder in grey. A residual that grows "
            "or follows the rudder is what the model gets wrong; the extended model should flatten it.")
'''),
]

NOTEBOOKS = {"identification": IDENTIFICATION, "indices": INDICES, "control": CONTROL,
             "diagnosis": DIAGNOSIS}


def build() -> list[Path]:
    NOTEBOOK_DIR.mkdir(exist_ok=True)
    out = []
    for name, cells in NOTEBOOKS.items():
        path = NOTEBOOK_DIR / f"{name}.ipynb"
        nbformat.write(_nb(cells), str(path))
        out.append(path)
    return out



if __name__ == "__main__":
    for p in build():
        print("written", p)
