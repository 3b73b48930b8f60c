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
display(nb.banner(data, "Model diagnosis", {"training runs": dg.get("training_runs"),
                                            "validation runs": dg.get("validation_runs"),
                                            **(dg.get("settings") or {})}))

# %%
from IPython.display import HTML
gain = (dg.get("gain") or {}).get("mae_psi_relative_reduction")
cause = dg.get("cause", "?")
base_v = (dg.get("baseline") or {}).get("validation") or {}
ext_v = (dg.get("extended") or {}).get("validation") or {}
def f3(x):
    return f"{x:.3g}" if isinstance(x, (int, float)) else "?"
msg = (f"<div style='font-size:1.3em;margin:6px 0'>Cause: <b>{nb.esc(cause)}</b>"
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
