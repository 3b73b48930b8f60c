# %% [markdown]
# # Diagnosis: what the linear model gets wrong
# The linear sway-yaw model (docs/contract.md#the-identification-model), fitted on training runs, is simulated
# free-run on runs it has not seen. Effects of the catalogue (docs/diagnosis.md) are added one at a time (two
# or three together, or the reference structure as one model, where none passes alone), each kept only when
# it cuts the held-out heading error materially, significantly and in every fold. The effects are chosen on
# the validation runs; the gain is reported on runs no choice has seen.

# %% tags=["parameters"]
# Parameters (papermill injects the real values after this cell). In JupyterLab: `make lab D=NAME`,
# or type the dataset's name here (docs/reports.md).
import os
dataset = os.environ.get("TANKTEST_DATASET") or "virtual"   # data/processed/<dataset>/
root = ""                      # processed-data root ("": $TANKTEST_ROOT, else data/processed)
max_runs_plotted = 6          # validation runs drawn


# %%
import textwrap

import numpy as np
import pandas as pd
import matplotlib.pyplot as plt
from IPython.display import HTML, display
from pipeline.report import nb
from pipeline.report import diagnosis_text as dt
from pipeline.report import particulars
from pipeline.diagnose.fit import sign_bound_text
page = nb.setup()
data = nb.Data(root, dataset)

dg = data.json("diagnose/diagnosis.json")
series = data.frame("diagnose/series.parquet", ("run_id", "time", "psi"))
settings = dg.get("settings") or {}
shown_settings = {k: (", ".join(map(dt.effect_label, v)) if k == "catalogue" and isinstance(v, list) else v)
                  for k, v in settings.items()}
display(nb.banner(data, "Model diagnosis", {
    "training runs": ", ".join(dg.get("training_runs") or []),
    "validation runs": ", ".join(dg.get("validation_runs") or []),
    "test runs": ", ".join(dg.get("test_runs") or []) or "none (nested leave-one-run-out)",
    **shown_settings}))

# %%
gain_block = dg.get("gain") or {}
gain = gain_block.get("mae_psi_relative_reduction")
cause = dg.get("cause", "none")
named = list((dg.get("extended") or {}).get("effects") or [])
measured_on = [str(r) for r in gain_block.get("measured_on") or []]
iv = dt.interval(gain_block.get("interval_95"))
ship = particulars.summary(data.index)
applied = particulars.particulars(data.index).get("files_scale_factor")
scale_words = ("model scale" if applied in (None, 1, 1.0)
               else "model scale (full-scale files Froude-scaled at ingest)")
has_gain = isinstance(gain, (int, float))
mode = dt.gain_mode(dg)            # "test runs", "nested leave-one-run-out" or None (no honest gain)
if cause != "none":
    carried = dt.carried_text(dg.get("extended") or {})
    head = (f"Cause: <b>{nb.esc(dt.effect_label(cause))}</b>"
            + (f" (extended model: {nb.esc(' + '.join(map(dt.effect_label, named)) + carried)})"
               if len(named) > 1 or carried else ""))
else:
    head = "Cause: <b>none</b>: no effect of the catalogue brings a real, material held-out gain"
if has_gain and (named or cause != "none"):
    head += f" &middot; <b>{nb.esc(dt.honest_gain_text(dg))}</b>"
display(HTML(f"<div style='font-size:1.3em;margin:6px 0'>{head}</div>"))
# the honest gain's own check (diagnosis.json gain.flag): said beside the number it qualifies
if gain_block.get("flag"):
    display(HTML("<div style='border:2px solid #b00020;padding:6px 10px;margin:8px 0'><b>Flag: "
                 + nb.esc(dt.effect_words(gain_block["flag"])) + "</b></div>"))
nb.note(f"Ship and scale: {ship}. Every number below is at {scale_words}, in the units of the logged "
        "data (deg, deg/s, m/s, s). Residuals are measured minus model.")
# a check of the data's own set-up (pipeline.diagnose.datacheck): said before any result it may bend
# (approach drift: a heading reference off the centreline; rate bias: r against the heading's change)
for check in (dg.get("data_checks") or {}).values():
    if (check or {}).get("warning"):
        display(HTML("<div style='border:2px solid #b8860b;padding:6px 10px;margin:8px 0'><b>"
                     + nb.esc(check["warning"]) + "</b></div>"))
# runs of the dataset the design left out (another approach speed, another kind of test), with reasons
not_used = dg.get("runs_not_used") or {}
if not_used:
    nb.note("Not used: " + "; ".join(f"{k} ({v})" for k, v in not_used.items()) + ".")

# %% [markdown]
# ## The baseline: the linear model
# Fitted without forcing stability: a course-unstable ship is reported as such, not hidden.

# %%
base = dg.get("baseline") or {}
ext = dg.get("extended") or {}
stab_rows = [{"model": "linear baseline (first fold)",
              "training runs": ", ".join(dg.get("training_runs") or []),
              "course stability": dt.stability_words(base.get("parameters"), base.get("course_stable"))}]
for k, fr in enumerate(dg.get("folds") or []):
    if k == 0:
        continue
    b_ = fr.get("baseline") or {}
    stab_rows.append({"model": f"linear baseline (fold {k + 1}, reversed roles)",
                      "training runs": ", ".join(fr.get("training_runs") or []),
                      "course stability": dt.stability_words(b_.get("parameters"), b_.get("course_stable"))})
if named:
    stab_rows.append({"model": "extended model (its linear part)",
                      "training runs": ", ".join(dg.get("training_runs") or []),
                      "course stability": dt.stability_words(ext.get("parameters"),
                                                             ext.get("course_stable"))})
page.table(pd.DataFrame(stab_rows).set_index("model"),
         "Course stability of the fitted models: the baseline of each fold in fold order, then the extended "
         "model; from the poles of the "
         "fitted state matrix (a pole with a positive real part = course-unstable).")
bp, bu = base.get("parameters") or {}, base.get("uncertainty") or {}
if bp:
    held, ext_held = base.get("at_sign_bound") or [], ext.get("at_sign_bound") or []
    ep = ext.get("parameters") or {}
    # a parameter pressed against its bound sits within the solver's margin of 0 (1e-16): shown as 0
    rows = []
    for k, v in bp.items():
        where = [m for m, h in (("baseline", held), ("extended", ext_held)) if k in h]
        rows.append({"parameter": k, "baseline": 0.0 if k in held else v, "+- 1 sigma": bu.get(k),
                     "extended model": 0.0 if k in ext_held else ep.get(k),
                     "at its sign bound in": ", ".join(where)})
    ptab = pd.DataFrame(rows)
    page.table(ptab.set_index("parameter"),
             "Linear parameters of the baseline (with one standard error) and of the extended model, in "
             "the order of docs/contract.md#the-identification-model (v in m/s, r in deg/s, delta in deg, "
             "time in s); the last "
             "column names the fits that hold the parameter at its ship-sign bound 0 (there the standard "
             "error describes the unconstrained curvature, not a two-sided interval).")
    if held:
        nb.note(sign_bound_text(held))
if dt.baseline_choice_text(dg):
    nb.note(dt.baseline_choice_text(dg))
if dt.unphysical_signs_text(dg):
    nb.note(dt.unphysical_signs_text(dg))
if dt.adequacy_text(dg):
    nb.note(dt.adequacy_text(dg))

# %% [markdown]
# ## The model ladder
# The baseline, then each effect in the order the stepwise selection added (or dropped) it.

# %%
lrows = dt.ladder_rows(dg)
if lrows:
    lad = pd.DataFrame(lrows).set_index("step")
    page.table(lad, "The model ladder, in the order it was climbed (step 0 = the linear baseline): free-run "
             "MAE of psi on the validation runs (which chose each step; each fold's fit on its own "
             "validation runs, mean over the folds)"
             + (" and on the test runs (which no choice has seen; each step refitted on all training and "
                "validation runs, mean over the test runs) with the 95 % bootstrap interval over blocks of "
                "its gain over the baseline." if any(r["test MAE psi (deg)"] is not None for r in lrows) else
                ". Without test runs the stage measures the honest gain by nested leave-one-run-out, "
                "which has no per-step test error; see the honest gain below."))
lad_raw = dg.get("ladder") or []
if len(lrows) > 1:
    tv = [r["test MAE psi (deg)"] for r in lrows]
    has_test = any(isinstance(v, (int, float)) for v in tv)
    fig, axes = plt.subplots(1, 2 if has_test else 1, figsize=(11 if has_test else 9, 0.9 + 0.5 * len(lrows)),
                             sharey=True, squeeze=False)
    y = np.arange(len(lrows))[::-1]
    ax = axes[0, 0]
    ax.plot([r["validation MAE psi (deg)"] for r in lrows], y, "o", mfc="none", color="0.3", ms=7,
            label="validation runs (chose the step)")
    if has_test:
        ax.plot([np.nan if v is None else v for v in tv], y, "s", color="tab:red",
                label="test runs (no choice saw them)")
    ax.set_yticks(y)
    # long labels (a group step names several effects) wrapped, so the axes keep their width
    ax.set_yticklabels([textwrap.fill(f"{r['step']}: {r['model']}", 48) for r in lrows], fontsize=8)
    ax.set_xlabel("free-run MAE of psi (deg)")
    ax.set_xlim(left=0)
    ax.set_ylim(-0.6, len(lrows) - 0.4)
    # the legend below the axes (beside them it squeezed the axes behind the long step labels); one
    # marker alone is said in the title
    if has_test:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.35 - 0.05 * len(lrows)), frameon=False, ncol=1)
    else:
        ax.set_title("open circles: validation runs (they chose each step)", fontsize=9)
    if has_test:
        ag = axes[0, 1]
        base_t = tv[0]
        for yi, rung, v in zip(y, lad_raw, tv, strict=True):
            if yi == y[0] or not isinstance(v, (int, float)) or not base_t:
                continue
            g = 1.0 - v / base_t
            ivr = rung.get("test_interval_95") or [g, g]
            ag.errorbar([100 * g], [yi], xerr=[[100 * (g - ivr[0])], [100 * (ivr[1] - g)]], fmt="s",
                        color="tab:red", capsize=4)
        ag.axvline(0, color="k", lw=0.8)
        ag.set_xlabel("test gain over the baseline (%), 95 % interval")
        ag.set_title("right of 0: better than the baseline", fontsize=9)
    page.show(fig, "The model ladder, top to bottom in the order it was climbed. "
            + ("Left: held-out" if has_test else "Held-out") + " heading error of each step"
            + (" on the validation runs (open circles) and the test runs (red squares). Right: the "
               "relative gain of each step over the baseline on the test runs, with its 95 % bootstrap "
               "interval over blocks." if has_test else " on the validation runs (which chose it)."))
elif lrows:
    nb.note("The ladder has one step: no effect was added to the linear baseline.")
else:
    nb.note("The stage wrote no model ladder.")
if dt.reference_text(dg):
    nb.note(dt.reference_text(dg))

# %% [markdown]
# ## The honest gain
# Selection and reporting are separate: the effects are chosen on the validation runs, and the gain
# is measured on runs that no choice has seen.

# %%
method = str(gain_block.get("method") or "")
nested_all_none = not any(n.get("effects") for n in gain_block.get("nested") or [])
if mode == dt.TEST_MODE and not named:
    nb.note(f"No effect is named, so on the test runs ({', '.join(measured_on)}) the model kept is the "
            "linear baseline itself, refitted on all training and validation runs: "
            + dt.honest_mae_text(dg) + "." + (f" How: {method}." if method else ""))
elif mode == dt.NESTED_MODE and not named and nested_all_none:
    nb.note(f"No nested selection chose an effect, so on the runs held out ({', '.join(measured_on)}) the "
            "model is the linear baseline fitted without each run and the held-out error is unchanged: "
            + dt.honest_mae_text(dg) + "." + (f" How: {method}." if method else ""))
elif mode == dt.NESTED_MODE and not named:
    # none on all the runs, yet some nested selections chose effects: the gain is theirs (gain.flag)
    nb.note("No effect is named on all the runs, so the model kept is the linear baseline; but the "
            "selection repeated without each run chose effects in some of its rounds (table below), and "
            "on the runs those rounds did not see, the model each round chose "
            + dt.gain_sentence(gain, gain_block.get("interval_95"))
            + f" ({dt.honest_mae_text(dg)}; measured on {', '.join(measured_on)}). That is the worth of the "
            "nested choices, not of the model kept: the verdict depends on which runs make it."
            + (f" How: {method}." if method else ""))
elif has_gain:
    nb.note(dt.honest_gain_text(dg) + f"; measured on {', '.join(measured_on)}."
            + (f" How: {method}." if method else ""))
else:
    nb.note("No honest gain could be measured"
            + (f": {method}." if method else "."))
per_run = gain_block.get("per_run") or []
if per_run:
    # with test runs the extended model is the one kept, refitted on all selection runs; with nested
    # leave-one-run-out each run is predicted by the structure chosen without it
    nested_gain = mode == dt.NESTED_MODE
    base_by, by = dt.honest_fits(dg)
    bcol = "baseline fitted without it, MAE psi (deg)" if nested_gain else \
        "baseline refitted on all selection runs, MAE psi (deg)"
    col = "chosen without it, MAE psi (deg)" if nested_gain else \
        ("extended, refitted on them, MAE psi (deg)" if named else "model kept, MAE psi (deg)")
    pr = pd.DataFrame([{"run": p.get("run_id"), bcol: p.get("baseline_mae_psi_deg"),
                        col: p.get("extended_mae_psi_deg"), "gain": dt.gain_text(p.get("gain"))}
                       for p in per_run])
    pr["_o"] = [data.sort_key(r) for r in pr["run"]]
    pr = pr.sort_values("_o").drop(columns="_o").set_index("run")
    page.table(pr, "The runs the honest gain is measured on, in rudder-angle order: free-run MAE of psi on "
             f"each run alone of {base_by} and of {by}, and the relative gain on each; the means of the two "
             "MAE columns are the honest gain's two MAEs.")
nested = gain_block.get("nested") or []
if nested:
    nr = pd.DataFrame([{"held-out run": (n.get("measured_on") or ["?"])[0],
                        "effects chosen without it": (" + ".join(map(dt.effect_label, n.get("effects") or []))
                                                      or "none") + dt.carried_text(n),
                        "gain on it": dt.gain_text(n.get("gain"))}
                       for n in nested])
    nr["_o"] = [data.sort_key(r) for r in nr["held-out run"]]
    nr = nr.sort_values("_o").drop(columns="_o").set_index("held-out run")
    page.table(nr, "Nested leave-one-run-out, in rudder-angle order: each run held out in turn, the whole "
             "selection repeated on the others, the chosen model measured on the held-out run.")

# %% [markdown]
# ## The named effects, read physically

# %%
findings = dg.get("findings") or []
by_eff = {f.get("effect"): f for f in findings}
joint = ext.get("effect_estimates") or {}
if not named:
    nb.note("No effect is named: the linear model is kept. The effects tried and why each was "
            "rejected are listed below.")
for e in named:
    f = by_eff.get(e, {})
    j = joint.get(e) or {}
    est = dt.estimate_text(j.get("estimate") or f.get("estimate"),
                           j.get("uncertainty") or f.get("uncertainty"))
    words = [f"<h3>{nb.esc(dt.effect_label(e))}</h3>",
             "<p><b>In plain words:</b> "
             + nb.esc(dt.plain(f.get("physical") or "no reading written", (f.get("estimate") or {}).keys()))
             + "."
             "</p>"]
    if e == "rudder_offset":
        extra = dt.offset_words(j.get("estimate") or f.get("estimate"), ext.get("parameters"))
        if extra:
            words.append(f"<p><b>What it does to the ship ({nb.esc(scale_words)}):</b> {nb.esc(extra)}. "
                         "A yaw moment in N m needs the yaw inertia (including added inertia), which the "
                         "data do not give.</p>")
    words.append(f"<p><b>Estimate</b> (one standard error, in the extended model): {nb.esc(est or 'n/a')}. "
                 f"<b>Worth in the final model</b> (held-out heading error when it is removed): "
                 f"{nb.esc(dt.pct(f.get('validation_gain_in_extended', f.get('validation_gain'))))}"
                 + (", per fold " + nb.esc(", ".join(dt.pct(g, True) for g in f.get("validation_gain_folds")))
                    if f.get("validation_gain_folds") else "")
                 + f"; {nb.esc(dt.cut_text(f.get('abs_gain_deg')))}; block t "
                 f"{nb.esc(dt.num(f.get('block_t'), 3))} against {nb.esc(dt.num(f.get('block_t_crit'), 3))}. "
                 f"<b>Physical floor:</b> {nb.esc(dt.floor_reason(f.get('floor')) or 'n/a')}; measured: "
                 f"{nb.esc(dt.floor_measured(f.get('floor')))}.</p>")
    told = dt.rivals_text(f)
    if told:
        others = {r["effect"] for r in f["rivals"]}
        pair = {e, *others} >= {"rudder_offset", "rudder_asymmetry"}
        words.append("<p><b>Not told apart from:</b> " + nb.esc(told)
                     + ". When this effect was added, " + ("that one" if len(others) == 1 else "those")
                     + " passed too, with a per-block held-out cut within one standard error of its own: "
                     "the runs support this effect no better. Runs that separate them would decide"
                     + (" (an offset acts at zero rudder and the same at every angle, an asymmetry grows "
                        "with the angle: a straight run at zero rudder, or zigzags at more rudder angles)"
                        if pair else "") + ".</p>")
    display(HTML("".join(words)))
    frows = [{"fold": k + 1, "estimate": dt.estimate_text(x.get("estimate"), x.get("uncertainty")),
              "held-out gain": dt.gain_text(x.get("gain"))}
             for k, x in enumerate(f.get("folds") or [])]
    if len(frows) > 1:
        page.table(pd.DataFrame(frows).set_index("fold"),
                 f"{dt.effect_label(e)}: estimate and worth in each fold, fold order (fold 2 swaps the "
                 "training and validation runs).")

# %% [markdown]
# ## Residuals that make the case
# Held-out residuals (measured minus model) on the validation runs: the baseline on the left and, when
# an effect is named, the extended model on the right, on the same axes. A structured residual that the
# extended model flattens is the evidence for the effect.

# %%
runs_drawn = list(dict.fromkeys(series.run_id))[:max_runs_plotted]
has_r = all(c in series for c in ("r", "r_baseline", "r_extended"))
SHADES = {"baseline": ("tab:blue", "#9ecae1", "#08306b", "#6baed6"),
          "extended": ("tab:red", "#fc9272", "#67000d", "#fb6a4a")}
models = (("baseline", "linear baseline"),)
if named:
    models += (("extended", "extended: " + " + ".join(map(dt.effect_label, named))),)
fig, axes = plt.subplots(2 if has_r else 1, len(models), figsize=(5.5 * len(models) + 1.5, 6 if has_r else 3),
                         sharex=True, sharey="row", squeeze=False)
for col, (model, title) in enumerate(models):
    for i, rid in enumerate(runs_drawn):
        s = series[series.run_id == rid]
        colour = SHADES[model][i % 4]
        axes[0, col].plot(s.time, s.psi - s[f"psi_{model}"], color=colour, lw=1.0,
                          label=data.short_label(rid))
        if has_r:
            axes[1, col].plot(s.time, s.r - s[f"r_{model}"], color=colour, lw=0.8)
    axes[0, col].set_title(title)
    for a in axes[:, col]:
        a.axhline(0, color="k", lw=0.5)
    axes[-1, col].set_xlabel(nb.label("time"))
    nb.legend_outside(axes[0, col], title="validation run")
axes[0, 0].set_ylabel("psi error (deg)")
if has_r:
    axes[1, 0].set_ylabel("r error (deg/s)")
page.show(fig, "Held-out heading error (top) and yaw-rate error (bottom) over time on the validation runs, "
        "one shade per run: the linear baseline"
        + (" (left, blues) and the extended model (right, reds), on the same axes" if named else
           " (no effect is named, so there is no extended model to compare)")
        + ". Error = measured minus free-run model.")

for e in named:
    sx = dt.signature_x(series, e) if has_r else None
    ch, ylabel, unit = dt.signature_residual(e)
    if sx is None or f"{ch}_baseline" not in series or series[ch].isna().all():
        nb.note(f"{dt.effect_label(e)}: its signature cannot be drawn from the series the stage wrote.")
        continue
    x, xlabel = sx
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6), sharex=True, sharey=True)
    for a, (model, colour) in zip(axes, (("baseline", "tab:blue"), ("extended", "tab:red")), strict=True):
        yerr = (series[ch] - series[f"{ch}_{model}"]).to_numpy()
        a.plot(x, yerr, ".", ms=2, color=colour, alpha=0.25)
        cx, my = dt.binned(x, yerr)
        a.plot(cx, my, "-o", ms=3, color="k", lw=1.2)
        a.axhline(0, color="k", lw=0.5)
        a.axhline(float(np.nanmean(yerr)), color="0.3", lw=1.0, ls="--")
        a.set_xlabel(xlabel)
        a.set_title(("linear baseline" if model == "baseline" else "extended model")
                    + f": mean {ch} error {dt.num(float(np.nanmean(yerr)), 2, unit)}")
    axes[0].set_ylabel(ylabel)
    page.show(fig, f"{dt.effect_label(e)}: held-out {'sway' if ch == 'v' else 'yaw-rate'} error against the "
            f"effect's signature "
            f"({xlabel}) on the validation runs, baseline left, extended model right; dots every sample, "
            "black line the mean in bins, dashed grey the overall mean. The trend (or, for an offset, the "
            "mean) the baseline leaves is what the effect explains.")

res_b = (base.get("residuals") or {}).get("correlation") or {}
res_e = (ext.get("residuals") or {}).get("correlation") or {}
if res_b:
    rs = pd.DataFrame([{"effect signature": dt.effect_label(k), "baseline": v, "extended model": res_e.get(k)}
                       for k, v in res_b.items()])
    rs["_o"] = -rs["baseline"].abs()
    rs = rs.sort_values("_o").drop(columns="_o").set_index("effect signature")
    page.table(rs, "Correlation of each effect's signature with the one-step yaw-acceleration error on the "
             "validation runs, largest baseline correlation (in size) first; the extended model should "
             "leave little. Signatures together explain "
             f"{dt.pct((base.get('residuals') or {}).get('explained_fraction'))} of the baseline's error and "
             f"{dt.pct((ext.get('residuals') or {}).get('explained_fraction'))} of the extended model's.")

# %% [markdown]
# ## Measured against baseline and extended model, free-run, run by run

# %%
def draw_run(s, title):
    """Heading, yaw rate and logged rudder of one run: the measurement and the two models' free runs."""
    fig, axes = plt.subplots(3 if has_r else 2, 1, figsize=(10, 7.0 if has_r else 5.0), sharex=True)
    ax = axes[0]
    ax.plot(s.time, s.psi, color="0.2", lw=1.4, label=data.source_label)
    ax.plot(s.time, s.psi_baseline, color="tab:blue", lw=1.0, ls="--", label="linear baseline")
    if named:
        ax.plot(s.time, s.psi_extended, color="tab:red", lw=1.0, label="extended model")
    ax.set_ylabel(nb.label("psi"))
    nb.legend_outside(ax)
    ax.set_title(title)
    if has_r:
        axes[1].plot(s.time, s.r, color="0.2", lw=1.4)
        axes[1].plot(s.time, s.r_baseline, color="tab:blue", lw=1.0, ls="--")
        if named:
            axes[1].plot(s.time, s.r_extended, color="tab:red", lw=1.0)
        axes[1].set_ylabel(nb.label("r"))
    axd = axes[-1]
    if "delta" in s:
        axd.plot(s.time, s.delta, color="0.4", lw=1.0)
        axd.set_ylabel(nb.label("delta"))
    axd.set_xlabel(nb.label("time"))
    return fig


for rid in runs_drawn:
    fig = draw_run(series[series.run_id == rid], data.run_label(rid))
    pb = next((p for p in base.get("per_run") or [] if p.get("run_id") == rid), {})
    pe = next((p for p in ext.get("per_run") or [] if p.get("run_id") == rid), {})
    page.show(fig, f"Validation run {data.run_label(rid)}: heading, yaw rate and logged rudder; the "
            f"measurement (dark), the linear baseline (blue dashed, MAE psi on this run "
            f"{dt.num(pb.get('mae_psi_deg'), 3)} deg)"
            + (" and the extended model (red, MAE psi on this run "
               f"{dt.num(pe.get('mae_psi_deg'), 3)} deg)" if named else "")
            + ", both the first fold's fits on the training runs ("
            + ", ".join(dg.get("training_runs") or []) + ")"
            + ", free-run from the initial state estimated on the run's quiet approach"
            + (f" (each model from its best start within {settings['x0_box_sigma']:g} standard deviations of "
               "that estimate)" if settings.get("x0_box_sigma") else "")
            + ". This run chose the effects; the honest gain is measured on the runs listed above.")

# %% [markdown]
# ## On the test runs
# The runs no choice has seen, where the honest gain is measured (with test runs only): both models
# refitted on all training and validation runs, free-run on each.

# %%
test_series = (data.frame("diagnose/test_series.parquet", ("run_id", "time", "psi"))
               if mode == "test runs" and data.exists("diagnose/test_series.parquet") else None)
if test_series is None:
    nb.note({"test runs": "The diagnosis stage wrote no test-run series: run it again to draw them.",
             "nested leave-one-run-out": "No test runs were given: the honest gain is the nested "
             "leave-one-run-out, its held-out runs' figures in the honest gain's table above."}.get(
                 mode, "No test runs were given."))
else:
    per_test = {p.get("run_id"): p for p in gain_block.get("per_run") or []}
    for rid in list(dict.fromkeys(test_series.run_id))[:max_runs_plotted]:
        fig = draw_run(test_series[test_series.run_id == rid], data.run_label(rid))
        p = per_test.get(rid, {})
        page.show(fig, f"Test run {data.run_label(rid)}: heading, yaw rate and logged rudder; the "
                "measurement (dark), the linear baseline refitted on all training and validation runs "
                f"(blue dashed, MAE psi on this run {dt.num(p.get('baseline_mae_psi_deg'), 3)} deg)"
                + (" and the extended model refitted on them (red, MAE psi on this run "
                   f"{dt.num(p.get('extended_mae_psi_deg'), 3)} deg)" if named else "")
                + ". No choice saw this run; the honest gain above is the mean over these runs.")

# %% [markdown]
# ## Every effect tried, and why it was kept or rejected

# %%
order = {v: i for i, v in enumerate(dt.VERDICTS)}
rows = []
for f in findings:
    v, why = dt.verdict(f, settings)
    g = f.get("validation_gain")
    rows.append({"effect": dt.effect_label(f.get("effect")), "verdict": v, "reason": why,
                 "judged": str(f.get("judged") or ""),
                 "held-out gain": dt.gain_text(g),
                 "estimate (+- 1 sigma)": dt.estimate_text(f.get("estimate"), f.get("uncertainty")) or "n/a",
                 "what the fit says physically": dt.plain(f.get("physical"), (f.get("estimate") or {}).keys())
                 or "n/a",
                 "_o": (order.get(v, 99), -(g if isinstance(g, (int, float)) else -1e9))})
if rows:
    tab = pd.DataFrame(rows).sort_values("_o").drop(columns="_o").set_index("effect")
    page.table(tab, "Every effect of the catalogue, named effects first, then by verdict ("
               + ", ".join(dt.VERDICTS[1:]) + ") and within a verdict by held-out gain, largest first. "
               "Held-out gain: the relative cut of the validation runs' free-run MAE of psi when the "
               "effect is added to the model it was judged against (for a named effect: when it is "
               "removed from the final model).")

stab = dg.get("stability") or {}
causes = stab.get("causes") or []
if causes:
    st = pd.DataFrame([{"selection": str(c.get("fold")), "cause": dt.effect_label(c.get("cause")),
                        "effects": " + ".join(map(dt.effect_label, c.get("effects") or [])) or "none",
                        "agrees": c.get("cause") == cause} for c in causes])
    page.table(st.set_index("selection"),
             f"Stability of the verdict: the selection repeated {len(causes)} times "
             + ("(each run held out in turn)" if mode == dt.NESTED_MODE else "(on each fold alone)")
             + ", in the order the stage ran them; "
             f"{stab.get('folds_agreeing')} of {stab.get('total')} name the same cause.")

# %% [markdown]
# ## Conclusion

# %%
base_stab = dt.stability_words(base.get("parameters"), base.get("course_stable")).split(":")[0]
rejected = [r for r in rows if r["verdict"] != "named"]
tests = {v: sum(v in dt.failed_tests(f, settings) for f in findings if not f.get("significant"))
         for v in dt.VERDICTS[1:]}
points = [
    f"Ship: {ship}; data at {scale_words}.",
    f"The linear baseline is {base_stab} and its held-out heading error is "
    f"{dt.num(dt.pooled_baseline_mae(dg), 3, 'deg')} on the validation runs (the mean over the folds, the "
    "number the selection judges by).",
]
if named and has_gain:
    points.append(
        f"The linear model's main error is {dt.effect_label(cause)}"
        + (f" (with {', '.join(dt.effect_label(e) for e in named if e != cause)})" if len(named) > 1 else "")
        + ": on validation it cut the heading error by "
        + f"{dt.pct(gain_block.get('validation_mae_psi_relative_reduction'))}; "
        + dt.honest_gain_text(dg)[0].lower() + dt.honest_gain_text(dg)[1:]
        + " (" + ", ".join(data.short_label(r) for r in measured_on) + ")"
        + (f". Flagged: {dt.effect_words(gain_block['flag'])}." if gain_block.get("flag") else "."))
    f0 = by_eff.get(cause, {})
    if f0.get("physical"):
        points.append(f"Read physically: {dt.plain(f0['physical'], (f0.get('estimate') or {}).keys())}.")
    if dt.rivals_text(f0):
        points.append(f"But the validation runs hardly told it from {dt.rivals_text(f0)}: the cause is one "
                      "of these, and runs that separate them would say which.")
    if base.get("course_stable") and ext.get("course_stable") is False:
        points.append("The extended model's linear part is course-unstable where the baseline's is stable: "
                      "the named effect holds the model only at large yaw rates, which is how it can fail on "
                      "small manoeuvres.")
elif named:
    points.append(f"Named: {', '.join(map(dt.effect_label, named))}; no run was left unseen by the choice, "
                  "so its gain is not measured honestly.")
else:
    points.append("No effect of the catalogue brings a real, material held-out gain: the linear model is "
                  "kept" + ((" (the nested selections' change on the runs each did not see: "
                             if mode == dt.NESTED_MODE else " (its change on the test runs: ")
                            + f"{dt.gain_text(gain)}, {dt.honest_mae_text(dg)})" if has_gain else "")
                  + (f". Flagged: {dt.effect_words(gain_block['flag'])}." if gain_block.get("flag") else "."))
if dt.adequacy_text(dg):
    points.append(dt.adequacy_text(dg))
if dt.reference_text(dg):
    points.append(dt.reference_text(dg))
if rejected:
    points.append(f"{len(rejected)} effects rejected (one may fail several tests): "
                  + ", ".join(f"{n} {k}" for k, n in tests.items() if n) + ".")
if causes:
    points.append(f"Stability: {stab.get('folds_agreeing')} of {stab.get('total')} repeated selections name "
                  f"the same cause ({dt.effect_label(cause)}).")
nb.conclusion(points)
