"""A tiny dataset's stage outputs in the schemas of pipeline/catalog.py, for the report tests.

Written from a small simulated truth (the paper's Table 4 model driven by a zigzag rudder), so the
report tests do not depend on the other stages' code.  ``ids``, ``ship`` and ``test_names`` let a
test put hostile strings where data-derived text comes from (file names, CSV headers).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.catalog import Catalog
from pipeline.io import Run, write_frame, write_json, write_run
from pipeline.model import PAPER_TABLE4, PARAM_NAMES, nomoto_indices, simulate

DT = 0.08
ALGS = ("srukf-ffm", "ffm-ukf")


def _zigzag(rudder: float, heading: float, n: int, seed: int) -> pd.DataFrame:
    """Zigzag on the Table 4 model with a rate-limited rudder; returns canonical columns."""
    theta = np.array([PAPER_TABLE4[p] for p in PARAM_NAMES])
    a11, a12, a21, a22, b11, b21 = theta
    x = np.zeros(3)
    target, delta = rudder, 0.0
    rows = []
    for k in range(n):
        if x[2] >= heading:
            target = -rudder
        elif x[2] <= -heading:
            target = rudder
        delta += np.clip(target - delta, -14.28 * DT, 14.28 * DT)
        rows.append((k * DT, *x, delta))
        v, r, psi = x
        x = np.array([v + DT * (a11 * v + a12 * r + b11 * delta),
                      r + DT * (a21 * v + a22 * r + b21 * delta), psi + DT * r])
    df = pd.DataFrame(rows, columns=["time", "v", "r", "psi", "delta"])
    rng = np.random.default_rng(seed)
    for c, s in (("v", 0.002), ("r", 0.02), ("psi", 0.02)):
        df[c] = df[c] + rng.normal(0, s, n)
    df["u"] = 2.0 - 0.002 * np.abs(df["r"])
    hd = np.deg2rad(df["psi"].to_numpy())
    df["x0"] = np.cumsum(2.0 * np.cos(hd)) * DT
    df["y0"] = np.cumsum(2.0 * np.sin(hd)) * DT
    df["rpm"] = 600.0
    return df[["time", "x0", "y0", "psi", "u", "v", "r", "delta", "rpm"]]


def make_catalog(root: Path, dataset: str = "tiny", provenance: str = "virtual",
                 ids: tuple[str, str] = ("zz20", "zz10"), ship: str = "KCS",
                 test_names: tuple[str, str] | None = None, rich_diagnosis: bool = False) -> Catalog:
    """Write every stage output of a tiny dataset (two zigzags) in the catalog.py schemas.

    ``ids``: run ids of the 20/20 and the 10/10 zigzag; ``ship``, ``test_names``: header text;
    ``rich_diagnosis``: diagnosis.json in the full schema of the diagnosis stage: model
    ladder, physical words, floors, per-fold gains, honest gain per run, stability
    (:func:`rich_diagnosis_doc`).
    """
    id20, id10 = ids
    cat = Catalog(root=Path(root), dataset=dataset)
    theta = np.array([PAPER_TABLE4[p] for p in PARAM_NAMES])
    runs = {id20: (20.0, 20.0, 900), id10: (10.0, 10.0, 700)}
    frames, entries = {}, []
    for i, (rid, (rud, head, n)) in enumerate(runs.items()):
        df = _zigzag(rud, head, n, seed=i)
        frames[rid] = df
        meta = {"run_id": rid, "source_file": f"{rid}.csv", "source_sha256": f"{i:064x}",
                "source_format": "csv", "provenance": provenance,
                "test_name": (test_names[i] if test_names else f"zigzag {rud:g}/{head:g} starboard"),
                "kind": "zigzag",
                "rudder_deg": rud, "heading_deg": head, "first_side": "starboard", "dt": DT,
                "original_dt": DT, "scale_factor": 1.0, "duration": n * DT, "samples": n,
                "ship": ship, "lpp": 6.0702}
        write_run(cat.runs_dir / f"{rid}.parquet", Run(df, meta))
        entries.append({"file": f"{rid}.parquet", **meta})
    write_json(cat.runs_index, {"dataset": dataset, "provenance": provenance, "runs": entries})

    # identify
    ident = frames[id20].iloc[:585]
    t = ident["time"].to_numpy()
    for j, alg in enumerate(ALGS):
        est = theta * (1 + 0.02 * (j + 1))
        conv = np.exp(-t / 8.0)[:, None]
        path = est[None, :] * (1 - conv) + np.array([-1.0, 0, -1, -1, 0, 0.1])[None, :] * conv
        tr = ident[["time", "delta", "v", "r", "psi"]].copy()
        for c, s in (("v", 0.003), ("r", 0.05), ("psi", 0.01)):
            tr[f"{c}_pred"] = tr[c] + s
            tr[f"{c}_est"] = tr[c]
            tr[f"innov_{c}"] = -s
        for k, p in enumerate(PARAM_NAMES):
            tr[p] = path[:, k]
            tr[f"{p}_std"] = np.abs(est[k]) * (0.05 + conv[:, 0])
        tr["f"] = 0.95 + 0.05 * (1 - conv[:, 0])
        tr["nis"] = 3.0
        write_frame(cat.identify_dir(alg) / "trace.parquet", tr)
        params = dict(zip(PARAM_NAMES, est, strict=True))
        write_json(cat.identify_dir(alg) / "estimates.json", {
            "algorithm": alg, "samples": 585, "parameters": params,
            "covariance": np.diag((0.05 * est) ** 2).tolist(), "indices": nomoto_indices(params),
            "timing": {"file": "timing.json"},
            "run_id": id20, "dataset": dataset, "provenance": provenance,
            "settings": {"q_std": [0.02, 0.02, 0.01], "r_std": [0.02, 0.02, 0.01]}})
        write_json(cat.identify_dir(alg) / "timing.json",
                   {"seconds_total": 0.004 * (1 + 60 * j), "seconds_per_step": 6.8e-6 * (1 + 60 * j)})

    # validate
    rows, preds = [], []
    for alg, est_scale in zip(ALGS, (1.02, 1.04), strict=True):
        for rid, seg in ((id20, "identification-rest"), (id10, "held-out")):
            df = frames[rid].iloc[585:] if rid == id20 else frames[rid]
            for mode in ("one-step", "free-run"):
                x0 = df[["v", "r", "psi"]].to_numpy()[0]
                sim = simulate(theta * est_scale, x0, df["delta"].to_numpy(), DT)
                p = df[["time", "delta", "v", "r", "psi"]].copy()
                p["v_pred"], p["r_pred"], p["psi_pred"] = sim.T
                p.insert(0, "mode", mode)
                p.insert(0, "run_id", rid)
                p.insert(0, "algorithm", alg)
                preds.append(p)
                rows.append({"algorithm": alg, "run_id": rid, "segment": seg, "mode": mode,
                             "mse_v": float(np.mean((p.v - p.v_pred) ** 2)),
                             "mse_r": float(np.mean((p.r - p.r_pred) ** 2)),
                             "mae_psi": float(np.mean(np.abs(p.psi - p.psi_pred))), "samples": len(p)})
    write_json(cat.validate_dir / "metrics.json", {"dataset": dataset, "provenance": provenance,
                                                   "ident_run": id20, "rows": rows, "paper": {}})
    write_frame(cat.validate_dir / "predictions.parquet", pd.concat(preds, ignore_index=True))

    # indices
    idx = nomoto_indices(theta)
    identified = {a: {k: {"value": v * (1 + 0.01 * j), "std": 0.05 * abs(v)} for k, v in idx.items()}
                  for j, a in enumerate(ALGS)}
    graphical = [{"run_id": rid, "method": m, "K": 0.5 + 0.01 * i, "T": 4.0 + i}
                 for i, rid in enumerate(runs) for m in ("standard", "integral")]
    write_json(cat.indices_dir / "indices.json", {
        "dataset": dataset, "provenance": provenance, "identified": identified, "graphical": graphical,
        "control_model": {"source": "srukf-ffm", **idx}, "graphical_model": {"source": id20, "K": 0.5,
                                                                             "T": 4.0},
        "paper": {"table7": {"K": 0.3867}}})
    write_json(cat.indices_dir / "zigzag.json", {"runs": [
        {"run_id": rid, "kind": "zigzag", "metrics": {"first_overshoot_deg": 5.0 + i,
                                                     "second_overshoot_deg": 7.0 + i, "period_s": 30.0},
         "imo": {"pass": True, "criteria": [{"name": "first overshoot", "value": 5.0 + i, "limit": 25.0,
                                             "unit": "deg", "pass": True}]}} for i, rid in enumerate(runs)]})
    pd.DataFrame({"index": list(idx), "srukf-ffm": list(idx.values())}).to_csv(
        cat.indices_dir / "table7.csv", index=False)

    # control
    n = 400
    tt = np.arange(n) * DT * 5
    ts = []
    for design in ("identified", "graphical"):
        psi = 60 * (1 - np.exp(-tt / 8))
        ts.append(pd.DataFrame({"plant": "nomoto", "design": design, "seed": 0, "time": tt,
                                "psi_ref": 60.0, "psi": psi, "r": np.gradient(psi, tt),
                                "delta_cmd": 20 * np.exp(-tt / 5) - 1.7, "delta": 20 * np.exp(-tt / 5) - 1.7,
                                "wave": 0.1 * np.sin(tt), "wind": 2.0}))
    write_frame(cat.control_dir / "timeseries.parquet", pd.concat(ts, ignore_index=True))
    stats = {"rise_time": {"mean": 20.0, "std": 0.1, "worst": 20.5},
             "max_deviation": {"mean": 1.0, "std": 0.2, "worst": 1.5}}
    write_json(cat.control_dir / "metrics.json", {
        "dataset": dataset, "provenance": provenance,
        "designs": {"identified": {"order": 1, "K": 0.30, "T": 3.9, "Tw": 3.0, "Kp": 0.86, "Kd": 3.2,
                                   "loop_nomoto_plant": {"gain_margin_db": None, "phase_margin_deg": 70.0}},
                    "graphical": {"order": 1, "K": 0.32, "T": 3.8, "Tw": 3.0, "Kp": 0.58, "Kd": 2.8,
                                  "loop_nomoto_plant": {"gain_margin_db": None, "phase_margin_deg": 68.0}}},
        "results": [{"plant": "nomoto", "design": d, "seeds": 2, "stats": stats}
                    for d in ("identified", "graphical")],
        "paper": {"rise_time": 24.0}})

    # diagnose
    val = frames[id10]
    series = val[["time", "delta", "psi", "r"]].copy()
    series.insert(0, "run_id", id10)
    series["psi_baseline"] = series["psi"] * 1.2
    series["r_baseline"] = series["r"] * 1.2
    series["psi_extended"] = series["psi"] * 1.02
    series["r_extended"] = series["r"] * 1.02
    write_frame(cat.diagnose_dir / "series.parquet", series)
    write_json(cat.diagnose_dir / "diagnosis.json", {
        "cause": "rudder_offset",
        "findings": [{"effect": "rudder_offset", "significant": True, "estimate": {"offset_deg": 1.5},
                      "validation_gain": 0.61, "evidence": "a steady 1.5 deg of rudder is needed"},
                     {"effect": "rudder_delay", "significant": False, "estimate": {"delay_s": 0.01},
                      "validation_gain": 0.01, "evidence": "no lag"}],
        "baseline": {"validation": {"mae_psi_deg": 4.1, "mse_r": 0.8, "mse_v": 0.002}},
        "extended": {"effects": ["rudder_offset"],
                     "validation": {"mae_psi_deg": 1.6, "mse_r": 0.2, "mse_v": 0.001}},
        "gain": {"mae_psi_relative_reduction": 0.61}})
    if rich_diagnosis:
        write_json(cat.diagnose_dir / "diagnosis.json", rich_diagnosis_doc(id20, id10))
    return cat



#: the honest gain's test run in the rich diagnosis (a run the diagnosis held out of every choice)
RICH_TEST_SUFFIX = "-test"


def rich_diagnosis_doc(id20: str, id10: str) -> dict:
    """A diagnosis.json in the schema pipeline/diagnose/core.py writes (docs/diagnosis.md#diagnosisjson
    keys), with known numbers the report tests check against:

    - cause rudder_offset, extended model rudder offset + nonlinear yaw damping;
    - ladder: baseline (validation 4.1, test 4.3 deg), +rudder_offset (1.9, 2.0), +nonlinear_yaw_damping
      (1.6, 1.7); each rung's test_interval_95 is the interval of its relative gain over the baseline;
    - the baseline of fold 1 is course-stable, fold 2's is course-UNSTABLE (a pole at +0.02 1/s);
    - findings: the two named effects, rudder_asymmetry immaterial (below its floor), speed_loss failed
      a fold, rudder_delay not significant, sway_yaw_coupling a divergent fit (gain -2000 %),
      rudder_lag not tried;
    - honest gain 0.61 [0.48, 0.70] on the test run ``id10 + RICH_TEST_SUFFIX``.
    """
    test = id10 + RICH_TEST_SUFFIX
    stable = {"a11": -0.3, "a12": 0.01, "a21": -2.0, "a22": -0.5, "b11": 0.002, "b21": 0.05}
    unstable = {"a11": -0.3, "a12": 0.01, "a21": 3.0, "a22": 0.1, "b11": 0.002, "b21": 0.05}
    settings = {"min_gain": 0.10, "min_abs_gain_deg": 0.10, "alpha": 0.05, "block_T": 2.0, "block_s": 16.0,
                "time_scale_s": 8.0, "heading_noise_deg": 0.03, "max_effects": 4,
                "catalogue": ["rudder_offset", "nonlinear_yaw_damping"], "two_fold": True}

    def judged(effect, gain, folds, material, t, floor, physical, estimate, unc, cut):
        return {"effect": effect, "form": "x", "significant": False, "material": material,
                "floor": floor + " [the stated reason]", "physical": physical, "estimate": estimate,
                "uncertainty": unc, "z": 1.0, "validation_gain": gain, "validation_gain_folds": folds,
                "validation_gain_in_extended": None, "abs_gain_deg": cut, "block_t": t, "block_t_crit": 1.7,
                "blocks": 22, "judged": "added to the final model", "folds": [],
                "evidence": "Not named: see the verdict."}

    named = [
        {"effect": "rudder_offset", "form": "constant", "significant": True, "material": True,
         "floor": "|offset| 1.50 deg (floor 0.3 deg) [three encoder resolutions]",
         "physical": "the rudder's neutral angle is 1.5 deg to port of the logged zero",
         "estimate": {"offset_deg": -1.5, "offset_share_of_max_rudder": 0.075},
         "uncertainty": {"offset_deg": 0.05}, "z": 30.0, "validation_gain": 0.55,
         "validation_gain_folds": [0.57, 0.53], "validation_gain_in_extended": 0.55, "abs_gain_deg": 1.4,
         "block_t": 6.0, "block_t_crit": 1.7, "blocks": 22, "judged": "in the final model (drop-one worth)",
         "folds": [{"estimate": {"offset_deg": -1.5}, "uncertainty": {"offset_deg": 0.05}, "gain": 0.57},
                   {"estimate": {"offset_deg": -1.4}, "uncertainty": {"offset_deg": 0.06}, "gain": 0.53}],
         "rivals": [{"effect": "rudder_asymmetry", "validation_gain": 0.52}],
         "evidence": "Held-out heading error +55 % when removed."},
        {"effect": "nonlinear_yaw_damping", "form": "cubic", "significant": True, "material": True,
         "floor": "changes the peak yaw rate of the largest manoeuvre by 12% (floor 5%) [ITTC precision]",
         "physical": "yaw damping grows with the rate of turn (cubic form, n_rrr_s_per_deg2 = -0.02)",
         "estimate": {"n_rrr_s_per_deg2": -0.02, "r_max_deg_s": 3.0, "form": "cubic"},
         "uncertainty": {"n_rrr_s_per_deg2": 0.002}, "z": 10.0, "validation_gain": 0.16,
         "validation_gain_folds": [0.15, 0.17], "validation_gain_in_extended": 0.16, "abs_gain_deg": 0.3,
         "block_t": 3.0, "block_t_crit": 1.7, "blocks": 22, "judged": "in the final model (drop-one worth)",
         "folds": [], "rivals": [{"effect": "sway_yaw_coupling", "validation_gain": 0.14}],
         "evidence": "Held-out heading error +16 % when removed."},
    ]
    rejected = [
        judged("rudder_asymmetry", 0.12, [0.1, 0.14], False, 2.5, "|asymmetry| 0.4% (floor 3%)",
               "the rudder is 0.4 % more effective to starboard", {"asymmetry": 0.004},
               {"asymmetry": 0.001}, 0.2),
        judged("speed_loss", 0.11, [0.3, -0.05], True, 2.0, "exponent", "the ship slowed by 10 %",
               {"speed_exponent": 0.3}, {"speed_exponent": 0.1}, 0.15),
        judged("rudder_delay", 0.12, [0.1, 0.14], True, 1.2, "dead time 0.3 s (floor 0.12 s)",
               "the rudder acts 0.30 s after it is logged", {"delay_s": 0.3}, {"delay_s": 0.2}, 0.2),
        judged("sway_yaw_coupling", -20.0, [-0.1, -40.0], True, -2.0, "peak", "cross terms",
               {"n_vrr_s_per_m_deg": 3.0}, {"n_vrr_s_per_m_deg": 1.0}, -50.0),
        {"effect": "rudder_lag", "significant": False, "material": False, "estimate": {}, "uncertainty": {},
         "validation_gain": None, "validation_gain_folds": None, "z": None, "physical": "",
         "floor": "lag", "evidence": "Not tried: the runs have no rudder command."},
    ]
    per_base = [{"run_id": id20, "mae_psi_deg": 3.9, "mse_r": 0.7, "mse_v": 0.002},
                {"run_id": id10, "mae_psi_deg": 4.3, "mse_r": 0.9, "mse_v": 0.002}]
    per_ext = [{"run_id": id20, "mae_psi_deg": 1.5, "mse_r": 0.2, "mse_v": 0.001},
               {"run_id": id10, "mae_psi_deg": 1.7, "mse_r": 0.2, "mse_v": 0.001}]
    fold_names = [f"train {id20}, validate {id10}", f"train {id10}, validate {id20}"]
    return {
        "cause": "rudder_offset",
        "findings": named + rejected,
        "baseline": {"parameters": stable, "uncertainty": {k: 0.1 * abs(v) for k, v in stable.items()},
                     "course_stable": True, "validation": {"mae_psi_deg": 4.1, "mse_r": 0.8, "mse_v": 0.002},
                     "per_run": per_base,
                     "residuals": {"correlation": {"rudder_offset": 0.6, "nonlinear_yaw_damping": -0.3},
                                   "explained_fraction": 0.5, "mean_psi_error_deg": 1.0,
                                   "r_error_vs_r": 0.1}},
        "extended": {"effects": ["rudder_offset", "nonlinear_yaw_damping"],
                     "forms": {"rudder_offset": "constant", "nonlinear_yaw_damping": "cubic"},
                     "parameters": stable, "uncertainty": {k: 0.1 * abs(v) for k, v in stable.items()},
                     "effect_estimates": {"rudder_offset": {"estimate": {"offset_deg": -1.5},
                                                            "uncertainty": {"offset_deg": 0.05},
                                                            "form": "constant"}},
                     "course_stable": True,
                     "validation": {"mae_psi_deg": 1.6, "mse_r": 0.2, "mse_v": 0.001}, "per_run": per_ext,
                     "residuals": {"correlation": {"rudder_offset": 0.05, "nonlinear_yaw_damping": -0.02},
                                   "explained_fraction": 0.05, "mean_psi_error_deg": 0.0,
                                   "r_error_vs_r": 0.0}},
        "gain": {"mae_psi_relative_reduction": 0.61, "interval_95": [0.48, 0.70], "measured_on": [test],
                 "method": "test runs: models refitted on all selection runs, free-run on the test runs",
                 "baseline_mae_psi_deg": 4.3, "extended_mae_psi_deg": 1.7,
                 "per_run": [{"run_id": test, "baseline_mae_psi_deg": 4.3, "extended_mae_psi_deg": 1.7,
                              "gain": 0.6046511627906976}],
                 "nested": [], "validation_mae_psi_relative_reduction": 0.61},
        "ladder": [
            {"model": "baseline", "effects": [], "validation_mae_psi_deg": 4.1, "test_mae_psi_deg": 4.3,
             "test_interval_95": [0.0, 0.0]},
            {"model": "+rudder_offset", "effects": ["rudder_offset"], "validation_mae_psi_deg": 1.9,
             "test_mae_psi_deg": 2.0, "test_interval_95": [0.41, 0.63]},
            {"model": "+nonlinear_yaw_damping", "effects": ["rudder_offset", "nonlinear_yaw_damping"],
             "validation_mae_psi_deg": 1.6, "test_mae_psi_deg": 1.7, "test_interval_95": [0.48, 0.70]},
        ],
        "runs_not_used": {"zz20_slow": "approach speed 1.500 m/s, the design's 1.980-2.010 m/s: more "
                                       "than 15% apart, and one linear model holds at one speed"},
        "stability": {"folds_agreeing": 1, "total": 2,
                      "causes": [{"fold": fold_names[0], "cause": "rudder_offset",
                                  "effects": ["rudder_offset", "nonlinear_yaw_damping"]},
                                 {"fold": fold_names[1], "cause": "nonlinear_yaw_damping",
                                  "effects": ["nonlinear_yaw_damping"]}],
                      "rule": "each fold alone"},
        "course_stable": [True, False],
        "folds": [{"training_runs": [id20], "validation_runs": [id10], "course_stable": True,
                   "baseline": {"parameters": stable, "course_stable": True}},
                  {"training_runs": [id10], "validation_runs": [id20], "course_stable": False,
                   "baseline": {"parameters": unstable, "course_stable": False}}],
        "summary": "Held-out heading error +55 % when removed.",
        "training_runs": [id20], "validation_runs": [id10], "test_runs": [test],
        "provenance": "virtual", "settings": settings,
    }
