"""Make the ingest test fixtures in tests/data/ (run: .venv/bin/python tests/make_fixtures.py).

1. ``tests/data/marin_zigzag_fullscale.dat``: a MARIN SIMMAN free-running file (exact layout of
   docs/contract.md#raw-formats: 3 header lines, tab-separated 3-significant-digit E-format, 11 columns, full
   scale, rudder positive to port, earth-fixed dx0/dy0, trailing empty rows) written from a known
   model-scale truth, :func:`marin_truth`.  The tests rebuild the truth and check the conversion.
2. ``tests/data/bad/``: one small file per refusal of docs/contract.md#bad-input (see ``BAD`` for what each
   must say).

Everything is deterministic (no random draws).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pipeline.model import PAPER_TABLE4, step

DATA = Path(__file__).resolve().parent / "data"
MARIN_FILE = DATA / "marin_zigzag_fullscale.dat"
MARIN_SCALE = 45.7                  # full / model
MARIN_FULL_DT = 0.5                 # s, full-scale logging step
MARIN_DURATION = 60.0               # s, model scale

# name -> (text the one-line message must contain, 1-based line it must name or None)
BAD = {
    "missing_column.csv": ("required column is missing", None),
    "non_numeric.csv": ("not a number", 40),
    "nan_value.csv": ("NaN", 31),
    "inf_value.csv": ("infinite", 52),
    "time_backwards.csv": ("time goes backwards", 61),
    "time_gap.csv": ("gap", 71),
    "too_few_samples.csv": ("too few samples", None),
    "rudder_out_of_range.csv": ("beyond", 45),
    "psi_radians.csv": ("radians", None),
    "ragged_row.csv": ("expected 9 values", 33),
    "empty.csv": ("empty", None),
    "unknown_format.dat": ("unknown format", None),
    "marin_time_jump.dat": ("not a uniform step", None),
}


def marin_truth(h: float | None = None) -> dict[str, np.ndarray]:
    """Model-scale truth: a 20/20 zigzag of the sway-yaw model (paper Table 4) with speed loss.

    Units: time s, x0/y0 m, psi/phi/delta deg (canonical: positive delta gives positive r),
    u/v m/s, r/p deg/s, rpm 1/min.  ``h`` is the model-scale step (default full step / sqrt(scale)).
    """
    h = h if h is not None else MARIN_FULL_DT / np.sqrt(MARIN_SCALE)
    n = int(round(MARIN_DURATION / h)) + 1
    t = np.arange(n) * h
    x = np.zeros(3)
    delta_cmd = 20.0
    delta = 0.0
    out = {k: np.zeros(n) for k in ("v", "r", "psi", "delta")}
    for k in range(n):
        out["v"][k], out["r"][k], out["psi"][k] = x
        out["delta"][k] = delta
        if x[2] > 20.0:
            delta_cmd = -20.0
        elif x[2] < -20.0:
            delta_cmd = 20.0
        if t[k] >= 1.0:
            delta += np.clip(delta_cmd - delta, -14.0 * h, 14.0 * h)   # rudder rate 14 deg/s
        x = step(x, delta, PAPER_TABLE4, h)
    u = 1.2 - 0.15 * (1 - np.exp(-t / 20.0))
    psi_r = np.deg2rad(out["psi"])
    dx0 = u * np.cos(psi_r) - out["v"] * np.sin(psi_r)
    dy0 = u * np.sin(psi_r) + out["v"] * np.cos(psi_r)
    x0 = 5.0 + np.concatenate([[0], np.cumsum(0.5 * (dx0[1:] + dx0[:-1]) * h)])
    y0 = -2.0 + np.concatenate([[0], np.cumsum(0.5 * (dy0[1:] + dy0[:-1]) * h)])
    phi = -0.08 * u * out["r"] + 0.01 * out["delta"]
    p = np.gradient(phi, t)
    rpm = np.full(n, 600.0)
    return {"time": t, "x0": x0, "y0": y0, "psi": out["psi"], "u": u, "v": out["v"], "r": out["r"],
            "delta": out["delta"], "rpm": rpm, "phi": phi, "p": p, "dx0": dx0, "dy0": dy0}


def write_marin(path: Path, truth: dict[str, np.ndarray], scale: float, t0_full: float = 0.0) -> None:
    """Write ``truth`` (model scale) as a full-scale MARIN .dat."""
    s = np.sqrt(scale)
    full = {
        "time": t0_full + truth["time"] * s, "x0": truth["x0"] * scale, "y0": truth["y0"] * scale,
        "phi": truth["phi"], "psi": truth["psi"], "dx0": truth["dx0"] * s, "dy0": truth["dy0"] * s,
        "p": truth["p"] / s, "r": truth["r"] / s, "delta": -truth["delta"], "rev": truth["rpm"] / s,
    }
    cols = ("time", "x0", "y0", "phi", "psi", "dx0", "dy0", "p", "r", "delta", "rev")
    lines = ["MARIN", "Zig-zag manoeuvring for KVLCC2 : 20 / -20", ""]
    for k in range(len(full["time"])):
        lines.append("\t".join(f"{full[c][k]:.2E}" for c in cols))
    lines += ["\t" * 10, "", ""]
    path.write_text("\n".join(lines) + "\n")


def _base_csv_rows(n: int = 126, dt: float = 0.08) -> list[list[str]]:
    t = np.arange(n) * dt
    psi = 10.0 * np.sin(0.3 * t)
    r = 3.0 * np.cos(0.3 * t)
    delta = 15.0 * np.cos(0.3 * t + 0.5)
    rows = []
    for k in range(n):
        rows.append([f"{t[k]:.3f}", f"{1.2 * t[k]:.4f}", "0.0000", f"{psi[k]:.4f}", "1.2000", "0.0100",
                     f"{r[k]:.4f}", f"{delta[k]:.3f}", "600.0"])
    return rows


def _csv(rows: list[list[str]], header: str = "time,x0,y0,psi,u,v,r,delta,rpm") -> str:
    head = ["# ship: TEST", "# test: zigzag 15/10 starboard", header]
    return "\n".join(head + [",".join(r) for r in rows]) + "\n"


def make_bad(dir_: Path) -> None:
    """One file per failure; data row k (0-based) sits on line k + 4 (3 header lines)."""
    dir_.mkdir(parents=True, exist_ok=True)

    def w(name, text):
        (dir_ / name).write_text(text)

    rows = _base_csv_rows()
    w("missing_column.csv", _csv([r[:6] + r[7:] for r in rows], "time,x0,y0,psi,u,v,delta,rpm"))
    b = [list(r) for r in rows]
    b[36][3] = "abc"                                   # line 40
    w("non_numeric.csv", _csv(b))
    b = [list(r) for r in rows]
    b[27][6] = "nan"                                   # line 31
    w("nan_value.csv", _csv(b))
    b = [list(r) for r in rows]
    b[48][7] = "inf"                                   # line 52
    w("inf_value.csv", _csv(b))
    b = [list(r) for r in rows]
    b[57][0] = "4.000"                                 # line 61: 4.56 -> 4.0
    w("time_backwards.csv", _csv(b))
    b = [list(r) for r in rows]
    for k in range(67, len(b)):                        # line 71: jump of 2.08 s
        b[k][0] = f"{float(b[k][0]) + 2.0:.3f}"
    w("time_gap.csv", _csv(b))
    w("too_few_samples.csv", _csv(rows[:20]))
    b = [list(r) for r in rows]
    b[41][7] = "400.0"                                 # line 45
    w("rudder_out_of_range.csv", _csv(b))
    b = [list(r) for r in rows]
    for r_ in b:
        r_[3] = f"{np.deg2rad(float(r_[3])):.6f}"
    w("psi_radians.csv", _csv(b))
    b = [list(r) for r in rows]
    b[29] = b[29][:8]                                  # line 33
    w("ragged_row.csv", _csv(b))
    w("empty.csv", "")
    w("unknown_format.dat", "This is not tank data.\nJust some notes about the test.\n")
    truth = marin_truth()
    tmp = dir_ / "marin_time_jump.dat"
    write_marin(tmp, truth, MARIN_SCALE)
    lines = tmp.read_text().splitlines()
    del lines[3 + 200: 3 + 260]                        # 60 rows (30 s full scale) missing
    tmp.write_text("\n".join(lines) + "\n")


def main() -> None:
    DATA.mkdir(parents=True, exist_ok=True)
    write_marin(MARIN_FILE, marin_truth(), MARIN_SCALE)
    make_bad(DATA / "bad")
    print(f"written {MARIN_FILE} and {len(BAD)} files in {DATA / 'bad'}")


if __name__ == "__main__":
    main()
