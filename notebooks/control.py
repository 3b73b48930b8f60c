# %% [markdown]
# # CGSA course-keeping autopilot
# Closed-loop gain-shaping (CGSA) autopilot designed from the identified Nomoto indices (and from the
# graphical K, T for comparison), simulated with wind, waves and rudder angle and rate limits (paper Figs
# 4 and 5).

# %% tags=["parameters"]
# Parameters (papermill injects the real values after this cell). In JupyterLab: `make lab D=NAME`,
# or type the dataset's name here (docs/reports.md).
import os
dataset = os.environ.get("TANKTEST_DATASET") or "virtual"   # data/processed/<dataset>/
root = ""                      # processed-data root ("": $TANKTEST_ROOT, else data/processed)
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
refused = bool(cm.get("refused"))
seed = seed_shown if seed_shown is not None else (ts["seed"].iloc[0] if len(ts) else None)
basis = cm.get("design_basis") or {}
display(nb.banner(data, "Course-keeping control", {
    "autopilot designed from": basis.get("source") or (ind.get("control_model") or {}).get("source"),
    "graphical model": (ind.get("graphical_model") or {}).get("source"),
    **{k: cfg[k] for k in ("tw", "setpoint", "duration", "dt", "rudder_max", "rudder_rate", "wind_rudder",
                           "seeds", "seed") if k in cfg},
    "wave seed shown": seed, "plants": ", ".join(p for p, v in (cm.get("plants") or {}).items()
                                                 if isinstance(v, dict) and v.get("used"))}))

# %% [markdown]
# ## Which indices the autopilot is designed from, and why

# %%
if refused:
    nb.note("The autopilot is NOT designed for this dataset: " + str(cm.get("reason")))
else:
    nb.note("Designed from: " + str(basis.get("basis") or basis.get("source") or "not stated"))
for n_ in cm.get("notes") or []:
    if not str(n_).startswith("designed from:"):
        nb.note(n_)
groups = [("indices used by the design", basis.get("flags"))]
groups += [(f"not used: {r.get('candidate')}",
            [{"check": "rejected", "subject": "", "reason": r.get("reasons")}])
           for r in basis.get("rejected") or []]
n_flags = nb.flags_table(groups, "Trust flags of the indices the design uses (shown, never used "
                         "silently) and the index sets that were not used, with the reason.")

# %% [markdown]
# ## Designs and loop margins

# %%
designs = cm.get("designs") or {}
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
    row["flags"] = nb.flag_marks(d.get("flags"))
    rows.append(row)
if rows:
    nb.table(pd.DataFrame(rows).set_index("design"),
             "CGSA designs (Kp deg of rudder per deg of heading error, Kd deg per deg/s) and the loop "
             "figures on the Nomoto plant the design is for: gain and phase margins, crossover, "
             "closed-loop bandwidth, sensitivity peak Ms (inf: the phase never reaches -180 deg).")
nb.full_scale_rows(pd.DataFrame({n: {f"{k} ({u})": d[k] for k, u in (("K", "1/s"), ("T", "s"), ("T1", "s"),
                                                                ("T2", "s"), ("T3", "s"), ("Tw", "s"),
                                                                ("Kd", "s"), ("filter_tau", "s"))
                                       if isinstance(d.get(k), (int, float))} for n, d in designs.items()}),
                   data, "The designs' indices, time constants and Kd (deg per deg/s, so in s).")
dflags = [(f"design {n}", d.get("flags")) for n, d in designs.items() if d.get("flags")]
if dflags:
    n_flags += nb.flags_table(dflags, "Designs whose loop fails a robustness check, with the reason.")
bode = {n: d["bode_nomoto_plant"] for n, d in designs.items()
        if isinstance(d.get("bode_nomoto_plant"), dict)}
if bode:
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for n, b in bode.items():
        w = np.asarray(b["omega"], dtype=float)
        axes[0].semilogx(w, np.asarray(b["mag_db"], dtype=float), label=n)
        axes[1].semilogx(w, np.asarray(b["phase_deg"], dtype=float), label=n)
    axes[0].axhline(0, color="k", lw=0.8)
    axes[1].axhline(-180, color="k", lw=0.8)
    axes[0].set_ylabel("|L| (dB)")
    axes[1].set_ylabel("phase of L (deg)")
    axes[1].set_xlabel("frequency (rad/s)")
    nb.legend_outside(axes[0])
    nb.show(fig, "Open-loop Bode diagram of each design on the Nomoto plant. The phase margin is the "
            "distance of the phase from -180 deg where the gain crosses 0 dB.")

# %% [markdown]
# ## Course change from 0 to the set course with wind and waves (paper Figs 4 and 5)

# %%
sel = ts[ts["seed"] == seed] if seed is not None else ts.iloc[0:0]
for plant, sub in sel.groupby("plant", sort=False):
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for design, s_ in sub.groupby("design", sort=False):
        line, = axes[0].plot(s_.time, s_.psi, label=f"{design}")
        axes[1].plot(s_.time, s_.delta, color=line.get_color(), lw=0.9)
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
    nb.time_axes(axes, data)
    nb.legend_outside(axes[0])
    plant_name = {"nomoto": "Nomoto model of the design indices",
                  "kcs": "nonlinear KCS of the virtual tank"}.get(plant, plant)
    axes[0].set_title(f"plant: {plant_name}, wave seed {seed}")
    nb.show(fig, f"Plant: {plant_name}. Heading (top, paper Fig. 4) and actual rudder (bottom, paper "
            "Fig. 5) for each design, one wave realisation. Look at the rise to the set course, the "
            "overshoot, and the rudder needed to hold course against the steady wind moment.")

# %% [markdown]
# ## Metrics over wave seeds, beside the paper

# %%
paper = cm.get("paper") or {}
order = ["rise_time", "rise_time_10_90", "max_deviation", "steady_mae", "max_rudder", "steady_rudder_min",
         "steady_rudder_max", "mean_rudder", "rudder_rms", "rudder_energy", "rudder_reversals", "max_rate"]
names = {"rise_time": "rise time (s)", "rise_time_10_90": "rise time 10-90 % (s)",
         "max_deviation": "max deviation (deg)", "steady_mae": "steady MAE (deg)",
         "max_rudder": "max rudder (deg)", "steady_rudder_min": "steady rudder min (deg)",
         "steady_rudder_max": "steady rudder max (deg)", "mean_rudder": "mean rudder (deg)",
         "rudder_rms": "rudder rms (deg)", "rudder_energy": "rudder energy (deg^2 s)",
         "rudder_reversals": "rudder reversals (-)", "max_rate": "max rudder rate (deg/s)",
         "reach_time": "reach time (s)"}
pmap = {k: paper.get(k) for k in ("rise_time", "max_deviation", "steady_mae", "steady_rudder_min",
                                  "steady_rudder_max", "mean_rudder")}
if "max_rudder_below" in paper:
    pmap["max_rudder"] = f"< {paper['max_rudder_below']:g}"
results = nb.records(cm.get("results") or [], key="plant")
table = {}
for res in results:
    stats = res.get("stats") or res.get("metrics") or {}
    col = f"{res.get('plant')} / {res.get('design')}"
    for n in stats:
        st = stats[n] if isinstance(stats[n], dict) else {"mean": stats[n]}
        mean, std = st.get("mean"), st.get("std")
        table.setdefault(n, {})[col] = (f"{nb.num(mean, 4)} +- {nb.num(std, 2)}" if std is not None
                                        else nb.num(mean, 4))
if table:
    keys = [n for n in order if n in table] + [n for n in table if n not in order]
    rows = [{"metric": names.get(n, n.replace("_", " ")), **table[n],
             data.paper_label: "" if pmap.get(n) is None else str(pmap.get(n))} for n in keys]
    nseeds = results[0].get("seeds", "?")
    nb.table(pd.DataFrame(rows).set_index("metric"),
             "Every plant and design in one table (columns plant / design): mean +- standard deviation "
             f"over {nseeds} wave seeds, in the order of the paper's metrics; the paper's figures beside "
             "them "
             "(its single run, Table 7 indices, Tw = 3 s).")
    nb.paper_note(data)
    nb.full_scale_rows(pd.DataFrame({f"{r.get('plant')} / {r.get('design')}":
                                     {names.get(n, n): (v.get("mean") if isinstance(v, dict) else v)
                                      for n, v in (r.get("stats") or r.get("metrics") or {}).items()}
                                     for r in results}),
                       data, "Mean metrics of the table above that scale with the ship.")
defs = cm.get("definitions")
if defs:
    def _txt(v):
        return "; ".join(f"{k}: {x}" for k, x in v.items()) if isinstance(v, dict) else str(v)
    nb.table(pd.DataFrame({"definition": {names.get(k, k.replace("_", " ")): _txt(v)
                                          for k, v in defs.items()}}),
             "How each metric is measured by the control stage.")
val = cm.get("identification_value") or {}
rows = []
for plant, block in val.items():
    for k, v in (block.get("metrics") or {}).items():
        rows.append({"plant": plant, "metric": names.get(k, k.replace("_", " ")),
                     "mean difference": v.get("mean"), "std": v.get("std")})
if rows:
    nb.table(pd.DataFrame(rows).set_index(["plant", "metric"]),
             "The value of identification: identified-design minus graphical-design metrics, paired over "
             "the same wave seeds (negative = the identified design is faster or closer to course).")

# %% [markdown]
# ## Conclusion

# %%
points = []
if refused:
    points.append("No autopilot was designed: " + str(cm.get("reason")))
else:
    points.append("Designed from: " + str(basis.get("source") or "not stated") + ".")
    for res in results:
        st = res.get("stats") or {}
        rt, md = (st.get("rise_time") or {}).get("mean"), (st.get("max_deviation") or {}).get("mean")
        mr = (st.get("max_rudder") or {}).get("mean")
        rt_full = (f" model scale, {nb.num(rt * data.full_scale ** 0.5, 3, 's')} full scale"
                   if data.full_scale and isinstance(rt, (int, float)) else "")
        points.append(f"{res.get('plant')} / {res.get('design')}: rise time {nb.num(rt, 3, 's')}{rt_full}, "
                      f"max deviation {nb.num(md, 3, 'deg')}, max rudder {nb.num(mr, 3, 'deg')} "
                      f"({data.paper_label}: 24 s, 1.46 deg, < 25 deg).")
    if n_flags:
        points.append(f"{n_flags} trust flags concern the design's indices; see the table above.")
nb.conclusion(points)
