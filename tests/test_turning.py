"""Turning circle by ITTC 7.5-04-02-01 (docs/indices.md): steady phase, pull-out excluded, titles,
IMO check from every format."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pipeline.indices.imo import imo_check
from pipeline.indices.turning import turning_metrics
from pipeline.ingest import read_raw
from pipeline.io import Run

U0, LPP = 1.2, 7.0
K, T = 0.25, 8.0                # 1/s, s: first-order yaw response at model scale (not the filter's model)


def turning_truth(pull_out_after_deg: float | None = 540.0, side: float = 1.0, h: float = 0.01,
                  dt: float = 0.1, duration: float = 260.0):
    """A 35 deg turning circle with speed loss to 70 % and an optional pull-out (rudder back to 0 once
    the heading has turned ``pull_out_after_deg``).  Continuous integration at step h, logged at dt.
    Returns the frame (docs/contract.md units) and the true steady yaw rate (deg/s) and diameter (m)."""
    n = int(round(duration / h)) + 1
    psi = r = delta = 0.0
    x = y = 0.0
    cmd = 35.0 * side
    rows = []
    every = int(round(dt / h))
    pulled = False
    for i in range(n):
        t = i * h
        u = U0 * (0.7 + 0.3 * np.exp(-(t - 2) / 8.0)) if t > 2 else U0
        if i % every == 0:
            rows.append((t, x, y, psi, u, -0.03 * r, r, delta))
        if pull_out_after_deg is not None and not pulled and abs(psi) >= pull_out_after_deg:
            cmd, pulled = 0.0, True
        if t >= 2.0:
            delta += np.clip(cmd - delta, -14 * h, 14 * h)
        rdot = (K * delta * (u / U0) - r) / T * (u / U0)
        a = np.deg2rad(psi)
        x += h * u * np.cos(a)
        y += h * u * np.sin(a)
        psi += h * r
        r += h * rdot
    frame = pd.DataFrame(rows, columns=["time", "x0", "y0", "psi", "u", "v", "r", "delta"])
    u_s = 0.7 * U0
    r_s = K * 35.0 * 0.7 * side                          # deg/s: steady r of T r' + r = K delta u/U0
    d_s = 2 * u_s / np.deg2rad(abs(r_s))
    return frame, r_s, d_s


def _run(frame, **meta):
    return Run(frame, {"lpp": LPP, "run_id": "turn", "approach_speed": U0, **meta})


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_steady_phase_excludes_pull_out(side):
    frame, r_s, d_s = turning_truth(side=side)
    m = turning_metrics(_run(frame))
    assert m["pull_out_s"] is not None
    assert m["steady_yaw_rate_deg_s"] == pytest.approx(r_s, rel=0.02)
    assert m["steady_diameter_m"] == pytest.approx(d_s, rel=0.02)
    assert m["steady_diameter_m"] <= m["tactical_diameter_m"]
    # the same run without pull-out gives the same steady figures
    m2 = turning_metrics(_run(turning_truth(None, side=side)[0]))
    assert m2["steady_diameter_m"] == pytest.approx(m["steady_diameter_m"], rel=0.02)


def _marin(frame: pd.DataFrame, title: str, scale: float) -> str:
    s = np.sqrt(scale)
    ang = np.deg2rad(frame["psi"].to_numpy())
    u, v = frame["u"].to_numpy(), frame["v"].to_numpy()
    dx0, dy0 = u * np.cos(ang) - v * np.sin(ang), u * np.sin(ang) + v * np.cos(ang)
    cols = [frame["time"] * s, frame["x0"] * scale, frame["y0"] * scale, 0 * u, frame["psi"],
            dx0 * s, dy0 * s,
            0 * u, frame["r"] / s, -frame["delta"], 0 * u + 80.0]
    body = ["\t".join(f"{float(c.iloc[k] if hasattr(c, 'iloc') else c[k]):.2E}" for c in cols)
            for k in range(len(frame))]
    return "\n".join(["MARIN", title, ""] + body + ["\t" * 10, ""]) + "\n"


def test_marin_turning_title_with_ship_digits_and_imo_check(tmp_path):
    frame, _, _ = turning_truth(side=-1.0)
    p = tmp_path / "turn_p.dat"
    p.write_text(_marin(frame, "Turning / Pull-out manoeuvre for KVLCC2 : -35 (deg)", 45.7))
    run = read_raw(p, scale=45.7)
    assert run.meta["kind"] == "turning" and run.meta["rudder_deg"] == 35.0
    m = turning_metrics(run)
    assert m["steady_diameter_m"] <= m["tactical_diameter_m"]
    imo = imo_check("turning", m, run.meta)
    assert imo["applicable"] and imo["test"] == "turning 35"
    assert {c["name"] for c in imo["criteria"]} >= {"advance", "tactical diameter"}


def test_turning_without_title_found_from_rudder(tmp_path):
    frame, _, _ = turning_truth()
    text = "# ship: PROBE\n# Lpp: 7.0\n" + frame.to_csv(index=False, float_format="%.6f", lineterminator="\n")
    p = tmp_path / "t.csv"
    p.write_text(text)
    run = read_raw(p)
    got = (run.meta["kind"], run.meta["rudder_deg"], run.meta["test_from"])
    assert got == ("turning", 35.0, "rudder signal")
