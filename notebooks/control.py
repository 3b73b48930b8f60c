# %% [markdown]
# # Course-keeping autopilot: the paper's CGSA and a PID with integral action
# The paper's closed-loop gain-shaping (CGSA) autopilot and the project's PID autopilot (integral action
# with anti-windup behind a third-order reference model), designed from the model that predicts the
# held-out runs better (identified or graphical), simulated with wind, waves and the steering gear's
# limits (paper Figs 4 and 5); the robustness of the sampled loop; and the identifier run inside the loop.

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
page = nb.setup()
data = nb.Data(root, dataset)

ind = data.json("indices/indices.json")
cm = data.json("control/metrics.json")
ts = data.frame("control/timeseries.parquet", ("plant", "design", "seed", "time", "psi", "delta"))
cfg = cm.get("config") or {}
refused = bool(cm.get("refused"))
seed = seed_shown if seed_shown is not None else (ts["seed"].iloc[0] if len(ts) else None)
basis = cm.get("design_basis") or {}
dmodel = cm.get("design_model") or {}
display(nb.banner(data, "Course-keeping control", {
    "autopilot designed from": dmodel.get("source") or basis.get("source")
    or (ind.get("control_model") or {}).get("source"),
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
elif dmodel.get("rule") and (dmodel.get("identified") or dmodel.get("graphical")):
    nb.note(f"Designed from: {dmodel.get('source')} ({dmodel.get('reason')}; the held-out comparison is "
            "below). The indices stage makes this one decision; the indices page shows the same.")
else:
    nb.note("Designed from: " + str(basis.get("basis") or basis.get("source") or "not stated"))
for n_ in cm.get("notes") or []:
    if not str(n_).startswith("designed from:"):
        nb.note(n_)
groups = [("indices used by the design", basis.get("flags"))]
groups += [(f"not used: {r.get('candidate')}",
            [{"check": "rejected", "subject": "", "reason": r.get("reasons")}])
           for r in basis.get("rejected") or []]
n_flags = page.flags_table(groups, "Trust flags of the indices the design uses (shown, never used "
                         "silently) and the index sets that were not used, with the reason.")

# %% [markdown]
# ## Which model is fit to design from: held-out prediction
# The filter's consistency (NIS, whiteness) says whether its stated uncertainty is right; whether its model
# is fit to design from is judged by prediction. Both candidates are run free from the measured initial
# state, driven by the measured rudder, over the same held-out runs.

# %%
if dmodel.get("identified") or dmodel.get("graphical"):
    from pipeline.indices.design_model import decision_table
    rows, cap = decision_table(dmodel)
    page.table(pd.DataFrame(rows).set_index("model"), cap)
elif dmodel:
    nb.note(f"Design model: {dmodel.get('source')} ({dmodel.get('rule')})")

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
    page.table(pd.DataFrame(rows).set_index("design"),
             "CGSA designs (Kp deg of rudder per deg of heading error, Kd deg per deg/s) and the loop "
             "figures on the Nomoto plant the design is for: gain and phase margins, crossover, "
             "closed-loop bandwidth, sensitivity peak Ms (inf: the phase never reaches -180 deg).")
page.full_scale_rows(pd.DataFrame({n: {f"{k} ({u})": d[k] for k, u in (("K", "1/s"), ("T", "s"), ("T1", "s"),
                                                                ("T2", "s"), ("T3", "s"), ("Tw", "s"),
                                                                ("Kd", "s"), ("filter_tau", "s"))
                                       if isinstance(d.get(k), (int, float))} for n, d in designs.items()}),
                   data, "The designs' indices, time constants and Kd (deg per deg/s, so in s).")
dflags = [(f"design {n}", d.get("flags")) for n, d in designs.items() if d.get("flags")]
if dflags:
    n_flags += page.flags_table(dflags, "Designs whose loop fails a robustness check, with the reason.")
def plain_log_ticks(ax):
    """Decade ticks as plain numbers (the pages take text literally, so no mathtext 10^n labels)."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())


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
    plain_log_ticks(axes[1])
    nb.legend_outside(axes[0])
    page.show(fig, "Open-loop Bode diagram of each design on the Nomoto plant. The phase margin is the "
            "distance of the phase from -180 deg where the gain crosses 0 dB.")

# %% [markdown]
# ## The project's autopilot
# PID by pole placement on the first-order model of the operating point (next section; double pole at
# wn = 1/Tw, the integrator a decade lower), conditional integration against wind-up, and Fossen's
# third-order reference model with a yaw-rate limit; the reference's motion is fed forward through the
# inverse Nomoto model.

# %%
ap = designs.get("autopilot")
if ap:
    keys_ = ("K", "T", "Kp", "Kd", "Ki", "wn", "zeta", "wr", "r_max")
    page.table(pd.DataFrame([{k: ap.get(k) for k in keys_}], index=["autopilot"]),
             "Autopilot gains: Kp deg/deg, Kd deg/(deg/s), Ki deg/(deg s); wn, wr rad/s; r_max deg/s. "
             + ("Kd clipped at 0 (the ship is faster than the loop)." if ap.get("kd_clipped") else ""))

# %% [markdown]
# ## Operating point: where the autopilot is designed
# Course keeping holds the rudder near its offset, where the ship answers as in its smallest zigzag, not
# the 20/20 one. The CGSA and the PID are designed from both bases and each sampled loop is scored on every
# plant; the rule picks the basis of the project's autopilot (the CGSA stays on the design model: the
# paper's chain).

# %%
op = cm.get("operating_point") or {}
if op:
    mrows = []
    for name, mdl in (op.get("models") or {}).items():
        mrows.append({"model": name.replace("_", " "), "K (1/s)": mdl.get("K"), "T (s)": mdl.get("T"),
                      "source": mdl.get("source")})
    page.table(pd.DataFrame(mrows).set_index("model"), "The models of the operating-point comparison.")
    orows = []
    for bname, kinds in (op.get("margins") or {}).items():
        for kind, blk in kinds.items():
            for plant, mm in (blk.get("plants") or {}).items():
                gm_ = mm.get("gain_margin_db")
                orows.append({"designed from": bname.replace("_", " "), "controller": kind.upper(),
                              "loop on": plant.replace("_", " "),
                              "PM (deg)": mm.get("phase_margin_deg"),
                              "GM (dB)": np.inf if gm_ is None else gm_,
                              "delay margin (s)": mm.get("delay_margin_s"),
                              "Ms (-)": mm.get("sensitivity_peak"),
                              "stable": mm.get("stable")})
    if orows:
        page.table(pd.DataFrame(orows).set_index(["designed from", "controller", "loop on"]),
                 f"Sampled-loop margins of both bases. Used for the autopilot: "
                 f"{str(op.get('used')).replace('_', ' ')} ({op.get('why')}). Rule: {op.get('rule')}.")

# %% [markdown]
# ## Robustness of the sampled loop
# Margins of the loop as it runs: sampled at the logging step with zero-order hold, the steering gear's
# lag and dead time, broken at the rudder command. On the design model; over draws of the identified
# parameters from the filter's covariance; on the ship linearised straight ahead (the course-keeping
# operating point) and at reduced speed (virtual KCS only); and a clean course step.

# %%
rob = cm.get("robustness") or {}
rows = []
sampled = {n: d["sampled_loop"] for n, d in designs.items() if isinstance(d.get("sampled_loop"), dict)}
for name, r in sampled.items():
    for where in ("design_model", "straight_ahead", "speed_0.75", "speed_0.50"):
        m = r.get(where)
        if isinstance(m, dict) and "phase_margin_deg" in m:
            gm = m.get("gain_margin_db")
            rows.append({"design": name, "loop": where.replace("_", " "),
                         "GM (dB)": np.inf if gm is None else gm,
                         "PM (deg)": m.get("phase_margin_deg"),
                         "delay margin (s)": m.get("delay_margin_s"),
                         "Ms (-)": m.get("sensitivity_peak"), "stable": m.get("stable")})
    dr = r.get("identified_draws")
    if dr:
        rows.append({"design": name, "loop": f"{dr['draws']} draws of the identified parameters",
                     "GM (dB)": dr.get("worst_gain_margin_db") or np.inf,
                     "PM (deg)": dr.get("worst_phase_margin_deg"),
                     "delay margin (s)": dr.get("worst_delay_margin_s"),
                     "Ms (-)": dr.get("worst_sensitivity_peak"), "stable": f"{dr['stable_fraction']:.1%}"})
if rows:
    page.table(pd.DataFrame(rows).set_index(["design", "loop"]),
             f"Sampled loop (dt {rob.get('dt_s')} s, servo lag {rob.get('servo_time_constant_s')} s, "
             f"dead time {rob.get('dead_time_s')} s = {rob.get('dead_time_samples')} samples). Draws: the "
             "worst margin over the stable draws and the share of draws whose closed loop is stable. "
             "GM inf: the phase never "
             "crosses -180 deg with |L| < 1.")
rows = []
for name, r in sampled.items():
    for where, m in r.items():
        if where.startswith("step_") and isinstance(m, dict):
            rows.append({"design": name, "plant": where[5:].replace("_", " "),
                         "overshoot (%)": m.get("overshoot_pct"),
                         "2 % settling (s)": m.get("settling_time_s")})
if rows:
    page.table(pd.DataFrame(rows).set_index(["design", "plant"]),
             f"A clean {cfg.get('step_deg', 10):g} deg course step (no wind, no waves): percent overshoot "
             "and "
             "2 % settling time, on the design model and on the nonlinear KCS at full and reduced speed "
             "(share of the approach speed).")
nyq = rob.get("nyquist") or {}
if nyq:
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    for name, d in nyq.items():
        re_, im_ = np.asarray(d["re"], float), np.asarray(d["im"], float)
        keep = np.hypot(re_, im_) < 5
        axes[0].plot(re_[keep], im_[keep], label=name)
        axes[1].semilogx(np.asarray(d["omega"], float), np.asarray(d["sens_db"], float), label=name)
    axes[0].plot([-1], [0], "k+", ms=12)
    axes[0].add_patch(plt.Circle((-1, 0), 0.5, fill=False, ls=":", color="0.5"))
    axes[0].set_xlim(-3, 1.5)
    axes[0].set_ylim(-3, 1.5)
    axes[0].set_aspect("equal")
    axes[0].set_xlabel("Re L")
    axes[0].set_ylabel("Im L")
    axes[1].axhline(20 * np.log10(2), color="0.5", ls=":", lw=0.8)
    axes[1].set_xlabel("frequency (rad/s)")
    axes[1].set_ylabel("|S| (dB)")
    plain_log_ticks(axes[1])
    nb.legend_outside(axes[1])
    page.show(fig, "Left: Nyquist plot of each design's sampled loop on the design model (|L| < 5 shown), "
            "the critical point -1 and the circle of radius 0.5 (Ms = 2). Right: sensitivity |S| = "
            "|1/(1 + L)| up to the Nyquist frequency; the dotted line is Ms = 2 (6 dB), the usual "
            "robustness bound.")

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
    page.show(fig, f"Plant: {plant_name}. Heading (top, paper Fig. 4) and actual rudder (bottom, paper "
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
    page.table(pd.DataFrame(rows).set_index("metric"),
             "Every plant and design in one table (columns plant / design): mean +- standard deviation "
             f"over {nseeds} wave seeds, in the order of the paper's metrics; the paper's figures beside "
             "them "
             "(its single run, Table 7 indices, Tw = 3 s).")
    nb.paper_note(data)
    page.full_scale_rows(pd.DataFrame({f"{r.get('plant')} / {r.get('design')}":
                                     {names.get(n, n): (v.get("mean") if isinstance(v, dict) else v)
                                      for n, v in (r.get("stats") or r.get("metrics") or {}).items()}
                                     for r in results}),
                       data, "Mean metrics of the table above that scale with the ship.")
defs = cm.get("definitions")
if defs:
    def _txt(v):
        return "; ".join(f"{k}: {x}" for k, x in v.items()) if isinstance(v, dict) else str(v)
    page.table(pd.DataFrame({"definition": {names.get(k, k.replace("_", " ")): _txt(v)
                                          for k, v in defs.items()}}),
             "How each metric is measured by the control stage.")
val = cm.get("identification_value") or {}
rows = []
for plant, block in val.items():
    for k, v in (block.get("metrics") or {}).items():
        rows.append({"plant": plant, "metric": names.get(k, k.replace("_", " ")),
                     "mean difference": v.get("mean"), "std": v.get("std")})
if rows:
    page.table(pd.DataFrame(rows).set_index(["plant", "metric"]),
             "The value of identification: identified-design minus graphical-design metrics, paired over "
             "the same wave seeds (negative = the identified design is faster or closer to course).")

# %% [markdown]
# ## The paper's case, and why its 0.86 deg cannot follow from a PD

# %%
pc = cm.get("paper_case")
if pc:
    nb.note(f"The paper's configuration (CGSA from the identified K, T, run on the identified model, wind "
            f"{pc.get('wind_rudder_deg')} deg and waves), {pc.get('seeds')} seeds: steady MAE "
            f"{nb.num(pc.get('steady_mae_mean'), 3, 'deg')} +- {nb.num(pc.get('steady_mae_std'), 2)} "
            f"against the paper's {pc.get('paper_steady_mae')} deg. {pc.get('why')}.")

# %% [markdown]
# ## Identification in the loop: adaptive CGSA through a speed change

# %%
ad = cm.get("adaptive")
if ad:
    sc = ad.get("scenario") or {}
    ru = ad.get("rule") or {}

    def fixed_vs_adaptive(stats: dict, label: str) -> pd.DataFrame:
        """One row per gain schedule (fixed, adaptive): each metric's mean +- std over the seeds."""
        rows = [{label: name, **{k.replace("_", " "): f"{nb.num(v.get('mean'), 3)} +- "
                                                      f"{nb.num(v.get('std'), 2)}"
                                 for k, v in ((stats or {}).get(name) or {}).items()}}
                for name in ("fixed", "adaptive")]
        return pd.DataFrame(rows).set_index(label)

    page.table(fixed_vs_adaptive(ad.get("stats"), "gains"),
             f"{sc.get('plant')}: course changes of +-{sc.get('course_step_deg')} deg every "
             f"{sc.get('course_step_every_s')} s, propeller cut at {sc.get('speed_change_s')} s to "
             f"{sc.get('speed_share')} of the approach speed; metrics after the cut, over seeds "
             f"{ad.get('seeds')} (the same for both). Rule against bursting: re-design every "
             f"{ru.get('period_s')} s only with a rudder sd over the last {ru.get('window_s')} s of at least "
             f"{ru.get('min_rudder_std_deg')} deg, a window mean NIS below {ru.get('max_nis_ratio')} x 3 and "
             f"positive K, T; each gain moves by at most {ru.get('max_gain_change', 0):.0%} per re-design.")
    g = pd.DataFrame(ad.get("gains_first_seed") or [])
    if len(g):
        fig, ax = plt.subplots(figsize=(10, 3.5))
        ax.step(g["t_s"], g["Kp"], where="post", label="Kp (deg/deg)")
        ax.step(g["t_s"], g["Kd"], where="post", label="Kd (deg per deg/s)")
        ax.axvline(sc.get("speed_change_s", 0), color="k", ls="--", lw=0.8)
        ax.set_xlabel(nb.label("time"))
        nb.legend_outside(ax)
        page.show(fig, "Adaptive gains on the first seed; the dashed line is the propeller cut. Flat "
                "stretches are re-designs refused by the rule (too little excitation, filter "
                "over-confident, no positive K, T).")
    pid_ad = ad.get("pid") or {}
    if pid_ad.get("stats"):
        page.table(fixed_vs_adaptive(pid_ad["stats"], "PID gains"),
                 f"The same scenario and seeds with the project's PID ({pid_ad.get('design')}), starting "
                 f"from K {nb.num((pid_ad.get('start') or {}).get('K'), 3)} 1/s, T "
                 f"{nb.num((pid_ad.get('start') or {}).get('T'), 3)} s (the operating-point model): its "
                 "integrator holds the wind, so a re-design from a larger K costs no steady offset.")
    kt = ad.get("K_tracking") or {}
    if kt.get("per_seed"):
        ro = ad.get("rudder_offset") or {}
        page.table(pd.DataFrame(kt["per_seed"]).set_index("seed"),
                 "Identified K (1/s) in the adaptive CGSA loop: mean over the 50 s before the speed change "
                 f"and over the last 100 s, and their ratio (speed share {kt.get('speed_share')}). "
                 "Rudder offset "
                 + ("removed: " + str(ro.get("method")) if ro.get("removed") else "not removed") + ".")

# %% [markdown]
# ## Conclusion

# %%
points = []
if refused:
    points.append("No autopilot was designed: " + str(cm.get("reason")))
else:
    points.append("Designed from: " + str(dmodel.get("source") or basis.get("source") or "not stated")
                  + (f" ({dmodel.get('reason')})." if dmodel.get("reason") else "."))
    if op:
        points.append(f"The autopilot (PID) is designed from the {str(op.get('used')).replace('_', ' ')} "
                      f"model: {op.get('why')}.")
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
    if ad:
        dif = (ad.get("difference") or {}).get("metrics") or {}
        points.append("In the loop through the speed change, adaptive minus fixed gains: largest overshoot "
                      f"{nb.num(dif.get('overshoot_max_deg'), 3, 'deg')}, rudder RMS "
                      f"{nb.num(dif.get('rudder_rms_deg'), 3, 'deg')}, heading MAE "
                      f"{nb.num(dif.get('heading_mae_deg'), 3, 'deg')} (mean over the paired seeds).")
        pdif = ((ad.get("pid") or {}).get("difference") or {}).get("metrics") or {}
        if pdif:
            points.append("The PID re-designed in the loop, adaptive minus fixed: largest overshoot "
                          f"{nb.num(pdif.get('overshoot_max_deg'), 3, 'deg')}, heading MAE "
                          f"{nb.num(pdif.get('heading_mae_deg'), 3, 'deg')}, rudder RMS "
                          f"{nb.num(pdif.get('rudder_rms_deg'), 3, 'deg')}.")
    if pc:
        points.append("The paper's case gives a steady MAE of "
                      f"{nb.num(pc.get('steady_mae_mean'), 3, 'deg')} (paper 0.86 deg): a PD holds a "
                      "constant wind only with an error |wind|/Kp = "
                      f"{nb.num(pc.get('pd_steady_offset_deg'), 3, 'deg')}; the integral action of the "
                      "autopilot removes it.")
nb.conclusion(points)
