# %% [markdown]
# # Diagnosis: what the linear model gets wrong
# The linear sway-yaw model (SPEC section 5) fitted on training runs is simulated free-run on held-out
# runs; each candidate effect (rudder offset, nonlinear yaw damping, rudder delay, speed loss) is tried as
# an extension and kept only when the held-out gain is real.

# %% tags=["parameters"]
# Parameters (papermill injects the real values after this cell)
dataset = "virtual"            # data/processed/<dataset>/
root = "data/processed"        # processed-data root
max_runs_plotted = 6          # validation runs drawn


# %%
import numpy as np  # noqa: F401  (for analysts who dig further)
import pandas as pd
import matplotlib.pyplot as plt
from IPython.display import display
from pipeline.report import nb
nb.setup()
data = nb.Data(root, dataset)

dg = data.json("diagnose/diagnosis.json")
series = data.frame("diagnose/series.parquet", ("run_id", "time", "psi"))
display(nb.banner(data, "Model diagnosis", {"training runs": ", ".join(dg.get("training_runs") or []),
                                            "validation runs": ", ".join(dg.get("validation_runs") or []),
                                            **(dg.get("settings") or {})}))


# %%
from IPython.display import HTML


def effect_name(e):
    return str(e).replace("_", " ") if e and e != "none" else "none"


def interval(iv, pct=True):
    if not (isinstance(iv, (list, tuple)) and len(iv) == 2):
        return ""
    f = (lambda x: f"{100 * x:.0f} %") if pct else (lambda x: nb.num(x, 3))
    return f"[{f(iv[0])}, {f(iv[1])}]"


gain_block = dg.get("gain") or {}
gain = gain_block.get("mae_psi_relative_reduction")
cause = dg.get("cause", "none")
base_v = (dg.get("baseline") or {}).get("validation") or {}
ext_v = (dg.get("extended") or {}).get("validation") or {}
iv = interval(gain_block.get("interval_95"))
measured_on = gain_block.get("measured_on") or []
msg = (f"<div style='font-size:1.3em;margin:6px 0'>Cause: <b>{nb.esc(effect_name(cause))}</b>"
       + (f" &middot; held-out free-run MAE of psi reduced by <b>{100 * gain:.0f} %</b>"
          + (f" (95 % interval {nb.esc(iv)})" if iv else "")
          + f" ({nb.esc(nb.num(base_v.get('mae_psi_deg')))} deg to "
          f"{nb.esc(nb.num(ext_v.get('mae_psi_deg')))} deg)"
          if isinstance(gain, (int, float)) and cause != "none"
          else " (no effect brings a real, material held-out gain)")
       + "</div>")
display(HTML(msg))
if measured_on:
    nb.note("The gain is measured on runs no choice has seen: " + ", ".join(map(str, measured_on)) + ".")
if dg.get("summary"):
    nb.note(dg["summary"])

# %% [markdown]
# ## Every effect tried

# %%
UNIT_SUFFIX = (("_s_per_deg2", "s/deg^2"), ("_deg_s", "deg/s"), ("_m_s", "m/s"), ("_deg", "deg"),
               ("_s", "s"), ("_m", "m"))


def param_name(key):
    """'n_rrr_s_per_deg2' -> 'n_rrr (s/deg^2)': the unit suffix of a diagnosis key as a unit."""
    for suffix, unit in UNIT_SUFFIX:
        if key.endswith(suffix):
            return f"{key[: -len(suffix)]} ({unit})"
    return key


def estimate_text(f):
    est, unc = f.get("estimate") or {}, f.get("uncertainty") or {}
    parts = []
    for k, v in est.items():
        name = param_name(k)
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            u = unc.get(k)
            pm = f" +- {nb.num(u, 2)}" if isinstance(u, (int, float)) else ""
            parts.append(f"{name} = {nb.num(v, 4)}{pm}")
        else:
            parts.append(f"{name} = {v}")
    return "; ".join(parts)


def stability_text(st):
    if st is None:
        return None
    if isinstance(st, dict):
        return "; ".join(f"{k.replace('_', ' ')}: {nb.num(v) if isinstance(v, (int, float)) else v}"
                         for k, v in st.items())
    return nb.num(st) if isinstance(st, (int, float)) else str(st)


findings = sorted(dg.get("findings") or [], key=lambda f: -(f.get("validation_gain") or -1e9))
has = {k: any(k in f for f in findings) for k in ("material", "physical", "stability",
                                                  "validation_gain_in_extended")}
rows = []
for f in findings:
    row = {"effect": effect_name(f.get("effect")), "significant": bool(f.get("significant"))}
    if has["material"]:
        row["material"] = bool(f.get("material"))
    pct = (lambda x: 100 * x if isinstance(x, (int, float)) else None)  # noqa: E731
    row["held-out gain (%)"] = pct(f.get("validation_gain"))
    if has["validation_gain_in_extended"]:
        row["worth in extended model (%)"] = pct(f.get("validation_gain_in_extended"))
    if has["stability"]:
        row["stability across folds"] = stability_text(f.get("stability"))
    row["estimate (+- 1 sigma)"] = estimate_text(f)
    if has["physical"]:
        row["what it means physically"] = f.get("physical") or ""
    row["evidence"] = f.get("evidence") or ""
    rows.append(row)
if rows:
    nb.table(pd.DataFrame(rows).set_index("effect"),
             "Every effect tried, largest held-out gain first. Held-out gain: relative reduction of the "
             "mean free-run MAE of psi on the validation runs; significant needs a real gain and an "
             "estimate clearly different from zero"
             + ("; material: the gain is large enough to matter" if has["material"] else "")
             + ("; worth in extended model: the gain of the extended model over the same model refitted "
                "without that effect" if has["validation_gain_in_extended"] else "") + ".")

ladder = dg.get("ladder") or []
if ladder:
    lrows = [{"model": l.get("model"),
              "effects": ", ".join(map(effect_name, l.get("effects") or [])) or "none",
              "validation MAE psi (deg)": l.get("validation_mae_psi_deg"),
              "test MAE psi (deg)": l.get("test_mae_psi_deg"),
              "test 95 % interval (deg)": interval(l.get("test_interval_95"), pct=False)} for l in ladder]
    nb.table(pd.DataFrame(lrows).set_index("model"),
             "The model ladder, in the order it was climbed: each model's free-run MAE of psi on the "
             "validation runs (which chose it) and on the test runs (which no choice has seen), with the "
             "test interval.")

vrows = []
ext_name = "extended: " + " + ".join(map(effect_name, (dg.get("extended") or {}).get("effects") or [])) \
    if (dg.get("extended") or {}).get("effects") else "extended (no effect added)"
per = {}
for label_, key in (("baseline (linear)", "baseline"), (ext_name, "extended")):
    v = (dg.get(key) or {}).get("validation") or {}
    vrows.append({"run": "all validation runs", "model": label_,
                  **{k: x for k, x in v.items() if not isinstance(x, (list, dict))}})
    for p_ in (dg.get(key) or {}).get("per_run") or []:
        rid = p_.get("run_id") or p_.get("run") or "?"
        vrows.append({"run": rid, "model": label_, **{k: x for k, x in p_.items()
                                                      if k not in ("run_id", "run") and
                                                      not isinstance(x, (list, dict))}})
vt = pd.DataFrame(vrows)
ALL = "all validation runs"
vt["_o"] = [(r != ALL, data.sort_key(r) if r != ALL else (), m != "baseline (linear)")
            for r, m in zip(vt["run"], vt["model"], strict=True)]
vt = vt.sort_values("_o").drop(columns="_o")
vt = vt.rename(columns={"mae_psi_deg": "MAE psi (deg)", "mse_r": "MSE r ((deg/s)^2)",
                                         "mse_v": "MSE v ((m/s)^2)"})
nb.table(vt.set_index(["run", "model"]),
         "Free-run errors of the baseline and the extended model on the validation runs: all together "
         "first, then run by run in rudder-angle order, baseline above extended.")

# %% [markdown]
# ## Measured against baseline and extended model, free-run

# %%
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
    nb.legend_outside(ax)
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
        ax2.set_zorder(0)
        ax2.grid(False)
    axr.set_ylabel("psi residual (deg)")
    axr.set_xlabel(nb.label("time"))
    nb.legend_outside(axr)
    nb.show(fig, f"Validation run {data.run_label(rid)}: free-run heading (and yaw rate) of the "
            "baseline linear model and of the extended model against the measurement; bottom, the "
            "heading residuals (measured minus model) with the rudder in grey. A residual that grows "
            "or follows the rudder is what the model gets wrong; the extended model should flatten it.")

# %% [markdown]
# ## Conclusion

# %%
sig = [f for f in findings if f.get("significant")]
points = [
    (f"The linear model's main error is {effect_name(cause)}: adding it cuts the held-out free-run heading "
     f"error by {100 * gain:.0f} %" + (f" (95 % interval {iv})" if iv else "")
     + (f", measured on {', '.join(map(str, measured_on))}" if measured_on else "") + ".")
    if isinstance(gain, (int, float)) and cause != "none" else
    "No effect of the catalogue brings a real, material held-out gain: the linear model is kept.",
    f"{len(sig)} of {len(findings)} effects tried are significant"
    + (": " + ", ".join(effect_name(f.get("effect")) for f in sig) if sig else "") + ".",
]
if ladder:
    points.append(f"Model ladder: {len(ladder)} models, the last one "
                  f"{nb.num(ladder[-1].get('test_mae_psi_deg'), 3, 'deg')} MAE of psi on the test runs.")
nb.conclusion(points)
