# %% [markdown]
# # Manoeuvring indices and zigzag analysis
# Second-order Nomoto indices from the identified parameters (paper Eq. 6) beside the Nomoto standard-test
# (graphical) K and T, in the layout of the paper's Table 7; ITTC zigzag and turning metrics with the IMO
# MSC.137(76) check.

# %% tags=["parameters"]
# Parameters (papermill injects the real values after this cell). In JupyterLab: `make lab D=NAME`,
# or type the dataset's name here (docs/reports.md).
import os
dataset = os.environ.get("TANKTEST_DATASET") or "virtual"   # data/processed/<dataset>/
root = ""                      # processed-data root ("": $TANKTEST_ROOT, else data/processed)
max_runs_plotted = 24         # zigzag runs drawn (all of them unless a dataset has more)


# %%
import numpy as np  # noqa: F401  (for analysts who dig further)
import pandas as pd
import matplotlib.pyplot as plt
from IPython.display import display
from pipeline.report import nb
page = nb.setup()
data = nb.Data(root, dataset)

ind = data.json("indices/indices.json")
zz = data.json("indices/zigzag.json")
t7 = data.csv("indices/table7.csv") if data.exists("indices/table7.csv") else None
runs = data.runs()
display(nb.banner(data, "Manoeuvring indices", {
    "autopilot designed from": (ind.get("control_model") or {}).get("source"),
    "graphical model": (ind.get("graphical_model") or {}).get("source"),
    "non-dimensional indices": ind.get("nondimensional_definition", "K' = K Lpp/U, T' = T U/Lpp")}))

# %% [markdown]
# ## Table 7: indices, dimensional and non-dimensional
# K' = K Lpp/U and T' = T U/Lpp (Lpp of the model, U the approach speed of the run the indices come
# from) are the same at model and full scale; they are what to compare with other ships and tanks.

# %%
from pipeline.model import PAPER_GRAPHICAL, PAPER_TABLE7, INDEX_NAMES
ident = ind.get("identified") or {}
iflags = ind.get("identified_flags") or {}
gm = ind.get("graphical_model") or {}
rows = []
for name in [*INDEX_NAMES, *(f"{n}_prime" for n in INDEX_NAMES)]:
    base = name.replace("_prime", "")
    unit = "-" if name.endswith("_prime") else ("1/s" if name == "K" else "s")
    row = {"index": f"{base}' ({unit})" if name.endswith("_prime") else f"{name} ({unit})"}
    for alg, block in ident.items():
        v = block.get(name) or {}
        lab = nb.ALG_LABEL.get(alg, alg)
        row[lab] = v.get("value")
        row[f"{lab} +-1 sigma"] = v.get("std")
        row[f"{lab} flags"] = nb.flag_marks(iflags.get(alg), base)
    row["graphical (ident. run)"] = gm.get(name) if base in ("K", "T") else None
    row[f"{data.paper_label} Table 7"] = PAPER_TABLE7.get(name)
    row[f"{data.paper_label} graphical"] = PAPER_GRAPHICAL.get(name)
    rows.append(row)
t7_shown = pd.DataFrame(rows).set_index("index")
page.table(t7_shown,
         "Nomoto indices from the identified parameters (paper Eq. 6) with one-sigma bounds propagated "
         "from the filter covariance, the graphical (standard test) K and T of the identification run, "
         "and the paper's values; dimensional first (K in 1/s, time constants in s), then "
         "non-dimensional. 'flags' names the trust checks a value fails (reasons in the table of "
         "flags below). Dimensional values at model scale.")
page.full_scale_rows(t7_shown, data, "Table 7's dimensional indices of this dataset (the paper's left out: "
                   "they are its KCS model's).", skip=tuple(c for c in t7_shown if c.startswith("paper")))
nb.paper_note(data)

g = pd.DataFrame(ind.get("graphical") or [])
if not g.empty and "run_id" in g:
    g["order"] = g["run_id"].map(data.sort_key)
    g = g.sort_values(["order", "method"]).drop(columns="order")
    g["zigzag"] = g["run_id"].map(data.short_label)
    g["flags"] = [nb.flag_marks(f) for f in g.get("flags", [[]] * len(g))]
    cols = [c for c in ("run_id", "method", "zigzag", "K", "T", "K_prime", "T_prime", "K_std", "T_std",
                        "rudder_offset_deg", "flags") if c in g]
    shown = g[cols].rename(columns={"K": "K (1/s)", "T": "T (s)", "K_prime": "K' (-)", "T_prime": "T' (-)",
                                    "K_std": "K +-1 sigma", "T_std": "T +-1 sigma",
                                    "rudder_offset_deg": "rudder offset (deg)"})
    page.table(nb.with_full_scale(shown.set_index(["run_id", "method"]), data, ("K (1/s)", "T (s)")),
             "First-order K and T per zigzag run, sorted by rudder angle, heading trigger and first side: "
             "'standard' is the Nomoto standard-test (graphical) method, 'integral' the least-squares "
             "integral method (with its one-sigma bounds). They change with the amplitude because the "
             "ship is not linear.")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    ids = list(dict.fromkeys(g.run_id))
    primed = "K_prime" in g and g["K_prime"].notna().any()
    for ax, q in zip(axes, ("K_prime", "T_prime") if primed else ("K", "T"), strict=True):
        for meth, sub in g.groupby("method"):
            ax.plot([ids.index(r) for r in sub.run_id], sub[q], "o", label=meth)
        bad = g[[bool(f) for f in g["flags"]]]
        if len(bad):
            ax.plot([ids.index(r) for r in bad.run_id], bad[q], "x", color="k", ms=10, label="flagged")
        ax.set_xticks(range(len(ids)))
        ax.set_xticklabels([data.short_label(r) for r in ids], rotation=45, ha="right", fontsize=8)
        ax.set_xlabel("zigzag run (rudder/heading, first side)")
        cm_v = (ind.get("control_model") or {}).get(q)
        if cm_v is not None:
            ax.axhline(cm_v, color="tab:red", ls=":", lw=1.0, label="autopilot design")
        ax.set_ylabel(f"{q[0]}' (-)" if primed else f"{q} ({'1/s' if q == 'K' else 's'})")
    nb.legend_outside(axes[1])
    page.show(fig, ("Non-dimensional K' and T'" if primed else "K and T (no Lpp or speed for K', T')")
            + " per run and method (crosses: flagged values), with the "
            "values the autopilot is designed from. The spread between runs shows how amplitude-specific "
            "the first-order indices are.")

# %% [markdown]
# ## Which numbers can be trusted

# %%
cm = ind.get("control_model") or {}
groups = [(f"identified {nb.ALG_LABEL.get(a, a)}", fl) for a, fl in iflags.items()]
groups.append(("graphical model (identification run)", gm.get("flags")))
for r in ind.get("graphical") or []:
    groups.append((f"{r.get('method')} method, run {r.get('run_id')}", r.get("flags")))
n_flags = page.flags_table(groups, "Every trust check that failed, with its reason. A flagged number is "
                         "shown but not used silently: the autopilot basis below says what was used.")
nb.note("Autopilot designed from: " + str(cm.get("basis") or cm.get("source") or "not stated"))
dm = cm.get("design_model") or {}
if dm.get("identified") or dm.get("graphical"):
    from pipeline.indices.design_model import decision_table
    rows_dm, cap = decision_table(dm)
    page.table(pd.DataFrame(rows_dm).set_index("model"),
             cap + " The filter's consistency flags above judge its stated uncertainty, not whether its "
             "model predicts.")

# %% [markdown]
# ## Zigzag and turning metrics with the IMO check

# %%
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
for rec in sorted(nb.records(zz), key=lambda r: data.sort_key(r.get("run_id"))):
    rid = rec.get("run_id", "?")
    flat = nb.flatten({k: v for k, v in rec.items() if k not in ("imo", "imo_check")})
    row = {"run": rid, "test": data.short_label(rid)}
    for key, lab in WANT:
        v = lookup(flat, key)
        if v is not None:
            row[lab] = v
    imo = rec.get("imo") or rec.get("imo_check") or {}
    verdict = imo.get("pass") if isinstance(imo, dict) else None
    row["IMO"] = {True: "pass", False: "FAIL"}.get(verdict, "not assessed")
    row["note"] = "; ".join(map(str, rec.get("errors") or []))
    rows.append(row)
    for c in (imo.get("criteria") or []) if isinstance(imo, dict) else []:
        crit.append({"run": rid, "criterion": c.get("name"), "value": c.get("value"),
                     "limit": c.get("limit"), "unit": c.get("unit"),
                     "verdict": {True: "pass", False: "FAIL"}.get(c.get("pass"), "not assessed")})
ztab = pd.DataFrame(rows)
if ztab.empty:
    nb.note("The indices stage found no zigzag or turning-circle runs to analyse.")
else:
    if not ztab["note"].any():
        ztab = ztab.drop(columns="note")
    page.table(nb.with_full_scale(ztab.set_index("run"), data),
             "ITTC 7.5-04-02-01 metrics per run, zigzags by rudder angle then turning circles (overshoot "
             "angles deg, times s, turning-circle distances in ship lengths) and the IMO MSC.137(76) "
             "verdict.")
if crit:
    page.table(pd.DataFrame(crit).set_index(["run", "criterion"]),
             "IMO criteria per run, in the order of the table above: value against limit.")

# %% [markdown]
# ## The zigzags

# %%
zig = runs[runs["kind"] == "zigzag"] if "kind" in runs else runs
zig = zig.assign(_o=zig["run_id"].map(data.sort_key)).sort_values("_o")
drawn = zig.head(max_runs_plotted)
if len(zig) > len(drawn):
    nb.note(f"{len(zig) - len(drawn)} zigzag runs are not drawn (max_runs_plotted = {max_runs_plotted}): "
            + ", ".join(map(str, zig.run_id.iloc[len(drawn):])))
if len(drawn):
    ncol = 2
    nrow = (len(drawn) + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(11, 2.4 * nrow + 0.6), squeeze=False)
    for ax, (_, r) in zip(list(axes.flat)[:len(drawn)], drawn.iterrows(), strict=True):
        df = data.run(r.run_id)
        ax.plot(df.time, df.psi, color="tab:blue", label=nb.label("psi"))
        ax.plot(df.time, df.delta, color="k", lw=1.0, label=nb.label("delta"))
        head = r.get("heading_deg")
        if head is not None and np.isfinite(head):
            for sgn in (1, -1):
                ax.axhline(sgn * head, color="0.5", ls=":", lw=0.8)
        ax.set_title(data.run_label(r.run_id), fontsize=9)
        ax.set_ylabel("angle (deg)")
    for ax in axes.flat[len(drawn):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel(nb.label("time"))
    for col in axes.T:
        nb.time_axes(col, data)
    h, lab = axes.flat[0].get_legend_handles_labels()
    fig.legend(h, lab, loc="outside lower center", ncol=2, frameon=False)
    page.show(fig, f"All {len(drawn)} zigzags drawn, in the order of the tables: heading (blue) and rudder "
            "(black); dotted lines mark the heading triggers. Overshoots are how far the heading goes "
            "past the trigger after each rudder execute.")
turn = runs[runs["kind"] == "turning"] if "kind" in runs else runs.iloc[0:0]
if len(turn):
    fig, ax = plt.subplots(figsize=(7.5, 6))
    for _, r in turn.iterrows():
        df = data.run(r.run_id)
        if "x0" in df and "y0" in df:
            lpp = r.get("lpp") or 1.0
            ax.plot((df.y0 - df.y0.iloc[0]) / lpp, (df.x0 - df.x0.iloc[0]) / lpp,
                    label=data.short_label(r.run_id))
    ax.set_aspect("equal")
    ax.set_xlabel("y0 / L (-)")
    ax.set_ylabel("x0 / L (-)")
    nb.legend_outside(ax)
    page.show(fig, "Turning-circle tracks in ship lengths from the approach point (x0 up, y0 to the "
            "right: starboard turns go right); advance, transfer and tactical diameter in the table "
            "above are read from these.")

# %% [markdown]
# ## Conclusion

# %%
k_p, t_p = cm.get("K_prime"), cm.get("T_prime")
imo_fail = [r["run"] for r in rows if r.get("IMO") == "FAIL"]
imo_pass = [r["run"] for r in rows if r.get("IMO") == "pass"]
nb.conclusion([
    ("The autopilot is NOT designed: " + str(cm.get("reason"))) if cm.get("refused") else
    f"The autopilot is designed from {cm.get('source')}: K = {nb.num(cm.get('K'), 3, '1/s')}, "
    f"T = {nb.num(cm.get('T'), 3, 's')} (K' = {nb.num(k_p)}, T' = {nb.num(t_p)})"
    + (f"; at full scale 1:{data.full_scale:g}: K = {nb.num(cm['K'] / data.full_scale ** 0.5, 3, '1/s')}, "
       f"T = {nb.num(cm['T'] * data.full_scale ** 0.5, 3, 's')}."
       if data.full_scale and isinstance(cm.get("K"), (int, float)) and isinstance(cm.get("T"), (int, float))
       else "."),
    f"{n_flags} trust checks failed; flagged numbers are marked in the tables and their reasons listed."
    if n_flags else "Every index passed its trust checks.",
    f"IMO MSC.137(76): {len(imo_pass)} runs pass, {len(imo_fail)} fail"
    + (f" ({', '.join(imo_fail)})" if imo_fail else "") + ".",
    "Graphical K and T vary with the zigzag amplitude: the ship is not linear, so first-order indices "
    "hold only near the amplitude they come from." if len(g) else "",
])
