# %% [markdown]
# # Online identification of the sway-yaw model
# SR-UKF-FFM (our square-root UKF with fuzzy fading memory) beside the FFM-UKF baseline (filterpy UKF,
# same fuzzy forgetting factor), as in the paper's Figs 2-3 and Tables 4-6.

# %% tags=["parameters"]
# Parameters (papermill injects the real values after this cell). In JupyterLab: `make lab D=NAME`,
# or type the dataset's name here (docs/reports.md).
import os
dataset = os.environ.get("TANKTEST_DATASET") or "virtual"   # data/processed/<dataset>/
root = ""                      # processed-data root ("": $TANKTEST_ROOT, else data/processed)
algorithms = ["srukf-ffm", "ffm-ukf"]   # algorithms shown, in this order
zoom_seconds = None          # if set, the time-series figures show only the first N s
max_heldout_plotted = 3       # held-out runs drawn (10/10 and 20/20 first)


# %%
import numpy as np  # noqa: F401  (for analysts who dig further)
import pandas as pd
import matplotlib.pyplot as plt
from IPython.display import display
from pipeline.report import nb
page = nb.setup()
data = nb.Data(root, dataset)

est = {a: data.json(f"identify/{a}/estimates.json") for a in algorithms}
trace = {a: data.frame(f"identify/{a}/trace.parquet", ("time", "delta", "r", "psi"))
         for a in algorithms}
metrics = data.json("validate/metrics.json")
pred = data.frame("validate/predictions.parquet",
                  ("algorithm", "run_id", "mode", "time", "r", "psi", "delta", "r_pred", "psi_pred"))
# v (sway) is optional: a dataset without a sway measurement has no v panel
ident_run = metrics.get("ident_run") or est[algorithms[0]].get("run_id")
window_s = float(trace[algorithms[0]]["time"].iloc[-1] - trace[algorithms[0]]["time"].iloc[0]) \
    if len(trace[algorithms[0]]) > 1 else None
settings = {"identification run": data.run_label(ident_run),
            "samples": est[algorithms[0]].get("samples"),
            "identification window, model scale (s)": window_s,
            **({f"identification window, full scale 1:{data.full_scale:g} (s)":
                window_s * data.full_scale ** 0.5} if data.full_scale and window_s else {}),
            **{f"{a} settings": est[a].get("settings", {}) for a in algorithms}}
display(nb.banner(data, "Online identification and validation", settings))


# %% [markdown]
# ## Online prediction against the tank data
# Identification window: the filter's one-step prediction of each sample made before it is seen; after the
# window, the validation predictions (one-step: the filter continues from the identified state; free-run:
# the identified model simulated from the measured initial state, driven only by the measured rudder).

# %%
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
    nb.time_axes(axes, data)
    if run_id == ident_run and len(trace[algorithms[0]]):
        for ax in axes:
            ax.axvline(trace[algorithms[0]]["time"].iloc[-1], color="g", ls=":", lw=1)
    if zoom_seconds:
        axes[0].set_xlim(0, zoom_seconds)
    nb.legend_outside(axes[1])
    axes[0].set_title(title)
    return fig


def residual_figure(run_id, title):
    """Measured minus one-step prediction: where the predictions sit on the data, the errors show."""
    fig, axes = plt.subplots(2, 1, figsize=(10, 4.5), sharex=True)
    for a in algorithms:
        p = pred[(pred.algorithm == a) & (pred.run_id == run_id) & (pred["mode"] == "one-step")]
        parts = ([trace[a]] if run_id == ident_run else []) + [p]
        for k, x in enumerate(parts):
            for ax, c in zip(axes, ("r", "psi"), strict=True):
                if f"{c}_pred" in x and c in x:
                    ax.plot(x["time"], x[c] - x[f"{c}_pred"], color=nb.ALG_COLOR.get(a), lw=0.7, alpha=0.8,
                            label=nb.ALG_LABEL.get(a, a) if k == 0 else None)
    axes[0].set_ylabel("r residual (deg/s)")
    axes[1].set_ylabel("psi residual (deg)")
    axes[1].set_xlabel(nb.label("time"))
    nb.time_axes(axes, data)
    if run_id == ident_run and len(trace[algorithms[0]]):
        for ax in axes:
            ax.axvline(trace[algorithms[0]]["time"].iloc[-1], color="g", ls=":", lw=1)
    nb.legend_outside(axes[0])
    axes[0].set_title(title)
    return fig

held = [r for r in dict.fromkeys(pred.run_id) if r != ident_run]
held.sort(key=lambda r: (data.amplitude(r) not in ("10/10", "20/20"), data.sort_key(r)))   # paper's first
ordered = [ident_run] + held[:max_heldout_plotted]
if len(held) > max_heldout_plotted:
    nb.note(f"{len(held) - max_heldout_plotted} more held-out runs are in the tables below, not drawn "
            f"(max_heldout_plotted = {max_heldout_plotted}).")
for rid in ordered:
    lab = data.run_label(rid)
    if rid == ident_run:
        fig = series_figure(rid, "one-step", f"Identification run {lab}: one-step prediction")
        page.show(fig, f"Identification run {lab} (paper Fig. 2): measured v, r, psi (grey) and the "
                "one-step predictions of both filters; the dotted green line ends the identification "
                "window. Look for how quickly the predictions lock on to the data and how closely "
                "they follow it after the window.")
    else:
        fig = series_figure(rid, "one-step", f"Held-out run {lab}: one-step prediction")
        page.show(fig, f"Held-out run {lab} (paper Fig. 3): one-step predictions of both filters "
                "against the tank data, with the parameters identified on the identification run.")
    fig = residual_figure(rid, f"{lab}: one-step residuals (measured minus predicted)")
    page.show(fig, f"{lab}: one-step prediction errors of yaw rate and heading. The one-step predictions "
            "above lie on the data, so their errors are drawn here at their own scale: noise-like "
            "residuals mean the filter tracks the run; a pattern that follows the rudder means it lags.")
    if (pred.run_id == rid).any() and (pred["mode"] == "free-run").any():
        fig = series_figure(rid, "free-run", f"{lab}: free-run simulation")
        page.show(fig, f"{lab}: free-run simulation of the identified models from the measured "
                "initial state, driven only by the measured rudder. This is the honest test of a "
                "model: errors accumulate in heading instead of being corrected every step.")

# %% [markdown]
# ## Parameter convergence
# Estimates of the six parameters over the identification window with one-sigma bands from the filter
# covariance; dashed: the paper's Table 4.

# %%
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
    ax.axhline(PAPER_TABLE4[p], color="k", ls="--", lw=0.9, label=f"{data.paper_label} Table 4")
    ax.set_title(p)
    lo = min(float(np.nanpercentile(trace[a][p], 2)) for a in algorithms if p in trace[a])
    hi = max(float(np.nanpercentile(trace[a][p], 98)) for a in algorithms if p in trace[a])
    pad = 0.2 * (hi - lo + 1e-9)
    ax.set_ylim(min(lo, PAPER_TABLE4[p]) - pad, max(hi, PAPER_TABLE4[p]) + pad)
for ax in axes[1]:
    ax.set_xlabel(nb.label("time"))
for col in axes.T:
    nb.time_axes(col, data)
nb.legend_outside(axes[0, 2])
page.show(fig, "Parameter estimates with one-sigma bands (the model of docs/identification.md in data units: "
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
    row[f"{data.paper_label} Table 4"] = PAPER_TABLE4[p]
    rows.append(row)
page.table(pd.DataFrame(rows).set_index("parameter"),
         f"Identified parameters after {est[algorithms[0]].get('samples')} samples (one-sigma from "
         "the final filter covariance), model scale, beside the paper's Table 4.")
nb.paper_note(data)

# %% [markdown]
# ## Forgetting factor and filter consistency

# %%
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
nb.time_axes(axes, data)
for ax in axes:
    nb.legend_outside(ax)
page.show(fig, "Top: the fuzzy forgetting factor f (always within [0.95, 1]); it drops when the "
        "innovations grow, which lets the filter forget old data. Bottom: normalised innovation "
        "squared; a consistent filter averages about 3 (the number of measurements).")

# %% [markdown]
# ## Validation errors (paper Tables 5 and 6)
# MSE of v (m/s)^2, MSE of r (deg/s)^2, MAE of psi (deg) over the validation samples. The paper's Table 5
# is its identification run (20/20 zigzag) after the identification window, Table 6 the 10/10 zigzag; both
# one-step (online).

# %%
m = pd.DataFrame(metrics["rows"])
for c in ("mse_v", "mse_r", "mae_psi"):
    m[c] = pd.to_numeric(m[c], errors="coerce")
m["zigzag"] = m["run_id"].map(data.amplitude)
labels = {"mse_v": "MSE v", "mse_r": "MSE r", "mae_psi": "MAE psi"}
rows = []
keys = m[["run_id", "segment", "algorithm"]].drop_duplicates()
for _, k in keys.iterrows():
    sub = m[(m.run_id == k.run_id) & (m.segment == k.segment) & (m.algorithm == k.algorithm)]
    amp = data.amplitude(k.run_id)
    table_no = 5 if (k.segment == "identification-rest" or amp == "20/20") else 6 if amp == "10/10" else None
    row = {"run": data.short_label(k.run_id) + (" (after window)" if k.segment == "identification-rest"
                                                else ""),
           "filter": nb.ALG_LABEL.get(k.algorithm, k.algorithm),
           "_o": (k.segment != "identification-rest", data.sort_key(k.run_id),
                  algorithms.index(k.algorithm) if k.algorithm in algorithms else 99)}
    for mode, tag in (("one-step", "one-step"), ("free-run", "free-run")):
        r = sub[sub["mode"] == mode]
        for c, name in labels.items():
            row[f"{tag} {name}"] = float(r[c].iloc[0]) if len(r) else None
    paper = nb.PAPER_TABLES_5_6.get((amp, k.algorithm)) if table_no else None
    for c, name in labels.items():
        row[f"{data.paper_label} {name}"] = (paper or {}).get(c)
    row[f"{data.paper_label} table"] = f"Table {table_no}" if paper else ""
    rows.append(row)
val = pd.DataFrame(rows).sort_values("_o").drop(columns="_o").set_index(["run", "filter"])
page.table(val, "Validation errors of both filters on every held-out stretch, the identification run after "
         "its window first, then the other runs by rudder angle and side: MSE of v (m/s)^2, MSE of r "
         "(deg/s)^2, MAE of psi (deg), one-step (online, what the paper's Tables 5 and 6 report) and "
         "free-run (the model simulated from the measured initial state), with the paper's one-step "
         "values where it has the same test (20/20: Table 5, 10/10: Table 6).")
nb.paper_note(data)

# %% [markdown]
# ## Timing

# %%
nb.note("The filter loop's wall time of each algorithm is kept beside its estimates, in "
        "identify/<algorithm>/timing.json (seconds_total, seconds_per_step), not on this page: a computer "
        "time differs from run to run, and the same data give the same page. python -m pipeline bench "
        f"compares the two filters on one machine as a ratio; the paper's {nb.PAPER_IDENT_SECONDS} s is "
        "for 585 samples on its hardware.")

# %% [markdown]
# ## Which numbers can be trusted

# %%
from pipeline.indices.trust import identify_side_flags
n_flags = page.flags_table([(nb.ALG_LABEL.get(a, a),
                           (metrics.get("flags") or {}).get(a, identify_side_flags(est[a])))
                          for a in algorithms],
                         "Trust checks of the identification that failed, with the reason (the validation "
                         "errors above come from these estimates).")

# %% [markdown]
# ## Conclusion

# %%
free = m[m["mode"] == "free-run"].groupby("algorithm")["mae_psi"].mean().reindex(algorithms).dropna()
one = m[m["mode"] == "one-step"].groupby("algorithm")["mae_psi"].mean().reindex(algorithms).dropna()
best = free.idxmin() if len(free) else None
cons = {a: (est[a].get("consistency") or {}) for a in algorithms}
points = []
if best is not None:
    each = ", ".join(f"{nb.ALG_LABEL.get(a, a)} {nb.num(v, 3)} deg" for a, v in free.items())
    tie = len(free) > 1 and (free.max() - free.min()) <= 0.01 * free.min()
    points.append(f"Held out, free-run: mean MAE of psi {each}; "
                  + ("the two filters predict the unseen runs equally well (within 1 %)." if tie else
                     f"{nb.ALG_LABEL.get(best, best)} predicts the unseen runs best."))
if len(one):
    points.append("One-step (online) MAE of psi: " + ", ".join(f"{nb.ALG_LABEL.get(a, a)} {nb.num(v, 3)} deg"
                                                          for a, v in one.items()) + ".")
for a in algorithms:
    c = cons[a]
    band = c.get("nis_95_band")
    if c.get("nis_mean") is not None and band:
        ok = band[0] <= c["nis_mean"] <= band[1]
        n_eff = (f" over {float(c['nis_n_eff']):.0f} effectively independent steps"
                 if c.get("nis_n_eff") is not None else "")
        white = c.get("whiteness") or {}
        not_white = [k for k, w in white.items() if not w.get("white", True)]
        if not_white:
            ok = False
            n_eff += f", innovations of {', '.join(not_white)} not white"
        points.append(f"{nb.ALG_LABEL.get(a, a)}: mean NIS {nb.num(c['nis_mean'])} against the band "
                      f"[{nb.num(band[0])}, {nb.num(band[1])}]{n_eff}: "
                      + ("consistent." if ok else
                         "NOT consistent, so its parameter uncertainties are not to be trusted."))
for a in algorithms:
    ne = est[a].get("noise_estimate") or {}
    rq = [(k, ne.get(k) or {}) for k in ("R", "Q")]
    if all(d.get("std") for _, d in rq):
        units = {"v": "m/s", "r": "deg/s", "psi": "deg"}
        txt = "; ".join(f"{k} one-sigma " + ", ".join(f"{n} {nb.num(v, 3)} {units.get(n, '')}"
                                                       for n, v in d["std"].items()) + f" ({d.get('method')})"
                        for k, d in rq)
        scale = rq[1][1].get("scale")
        points.append(f"Noise settings of {nb.ALG_LABEL.get(a, a)}: {txt}"
                      + (f"; scale c = {nb.num(scale, 3)}." if scale is not None else "."))
        break
nb.conclusion(points)
