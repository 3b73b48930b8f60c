# %% [markdown]
# # CGSA course-keeping autopilot
# Closed-loop gain-shaping (CGSA) autopilot designed from the identified Nomoto indices (and from the
# graphical K, T for comparison), simulated with wind, waves and rudder angle and rate limits (paper Figs
# 4 and 5).

# %% tags=["parameters"]
# Parameters (papermill injects the real values after this cell)
dataset = "virtual"            # data/processed/<dataset>/
root = "data/processed"        # processed-data root
seed_shown = None              # wave seed drawn in the figures (None: the first)


# %%
import numpy as np  # noqa: F401  (for analysts who dig further)
import pandas as pd
import matplotlib.pyplot as plt
from IPython.display import display
from pipeline.report import nb
nb.setup()
data = nb.Data(root, dataset)

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

# %% [markdown]
# ## Designs and loop margins

# %%
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

# %% [markdown]
# ## Course change from 0 to the set course with wind and waves (paper Figs 4 and 5)

# %%
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

# %% [markdown]
# ## Metrics over wave seeds, beside the paper

# %%
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
