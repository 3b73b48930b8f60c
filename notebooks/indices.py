# %% [markdown]
# # Manoeuvring indices and zigzag analysis
# Second-order Nomoto indices from the identified parameters (paper Eq. 6) beside the Nomoto standard-test
# (graphical) K and T, in the layout of the paper's Table 7; ITTC zigzag and turning metrics with the IMO
# MSC.137(76) check.

# %% tags=["parameters"]
# Parameters (papermill injects the real values after this cell)
dataset = "virtual"            # data/processed/<dataset>/
root = "data/processed"        # processed-data root
max_runs_plotted = 8          # zigzag runs drawn (in runs-index order)


# %%
import numpy as np  # noqa: F401  (for analysts who dig further)
import pandas as pd
import matplotlib.pyplot as plt
from IPython.display import display
from pipeline.report import nb
nb.setup()
data = nb.Data(root, dataset)

ind = data.json("indices/indices.json")
zz = data.json("indices/zigzag.json")
t7 = data.csv("indices/table7.csv") if data.exists("indices/table7.csv") else None
runs = data.runs()
display(nb.banner(data, "Manoeuvring indices", {
    "control model": (ind.get("control_model") or {}).get("source"),
    "graphical model": (ind.get("graphical_model") or {}).get("source")}))

# %% [markdown]
# ## Table 7: indices

# %%
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

# %% [markdown]
# ## The zigzags

# %%
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
