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
from pipeline.io import Run, read_json, write_frame, write_json, write_run
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
    ``rich_diagnosis``: diagnosis.json also holds the model ladder, each finding's physical sentence,
    material flag and stability, and the gain's interval and measured_on runs (issue 11's keys).
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
            "timing": {"seconds_total": 0.004 * (1 + 60 * j), "seconds_per_step": 6.8e-6 * (1 + 60 * j)},
            "run_id": id20, "dataset": dataset, "provenance": provenance,
            "settings": {"q_std": [0.02, 0.02, 0.01], "r_std": [0.02, 0.02, 0.01]}})

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
        "design": {"identified": {"Kp": 0.86, "Kd": 3.2, "gain_margin_db": None, "phase_margin_deg": 70.0},
                   "graphical": {"Kp": 0.58, "Kd": 2.8, "gain_margin_db": None, "phase_margin_deg": 68.0}},
        "results": [{"plant": "nomoto", "design": d, "metrics": stats} for d in ("identified", "graphical")],
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
        doc = read_json(cat.diagnose_dir / "diagnosis.json")
        doc["findings"][0].update(physical="the rudder's neutral angle is 1.5 deg to port of the logged zero",
                                  material=True, stability={"folds_agreeing": 2, "folds": 2})
        doc["findings"][1].update(physical="no measurable steering-gear delay", material=False,
                                  stability={"folds_agreeing": 0, "folds": 2})
        doc["gain"].update(interval_95=[0.48, 0.70], measured_on=[id10 + "-test"])
        doc["ladder"] = [
            {"model": "linear", "effects": [], "validation_mae_psi_deg": 4.1, "test_mae_psi_deg": 4.3,
             "test_interval_95": [3.9, 4.8]},
            {"model": "linear + offset", "effects": ["rudder_offset"], "validation_mae_psi_deg": 1.6,
             "test_mae_psi_deg": 1.7, "test_interval_95": [1.4, 2.1]}]
        write_json(cat.diagnose_dir / "diagnosis.json", doc)
    return cat

