"""Make the probe corpus ``tests/data/probes/`` (run: .venv/bin/python tests/make_probes.py).

Files as a careless or unlucky user produces them, each with its expected outcome
(:data:`PROBES`).  Every probe is a variant of one clean model-scale 20/20 zigzag (``clean.csv``)
of a ship that is *not* the identification model's (a first-order Nomoto ship with K 0.25 1/s,
T 6 s and a rudder servo of 14 deg/s, heading from continuous integration at a fine step, logged
at 0.1 s), so a probe that is accepted must give the clean run back.  Deterministic: no random draws.

Outcomes:
  ("equal", {})                            accepted, the frame equals the clean file's frame
  ("equal_marin", {})                      accepted, equals the clean MARIN fixture
  ("converted", {"col": ...})              accepted after converting a declared unit: equals clean
  ("refused", (text, row, column))         exit 2, one line naming the file, and row/column if given
  ("kind", {...})                          accepted; the run's metadata has these values
"""

from __future__ import annotations

import gzip
import io
import zipfile
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parent / "data"
PROBE_DIR = DATA / "probes"
DT = 0.1                      # s, logging step of the clean file
DURATION = 40.0               # s
LPP = 7.0                     # m, model
U0 = 1.2                      # m/s, approach speed (Fn 0.145)
COLS = ("time", "x0", "y0", "psi", "u", "v", "r", "delta", "rpm")
HEADER = ["# ship: PROBE", "# Lpp: 7.0", "# test: zigzag 20/20 starboard"]
SPIKE_ROW = 3 + 1 + 151       # 1-based line of data row 150 (0-based; 3 comment lines, 1 header)


def clean_truth() -> dict[str, np.ndarray]:
    """Model-scale 20/20 zigzag: Nomoto T r' + r = K delta, rudder rate 14 deg/s (deg, deg/s, s, m)."""
    h = 0.005
    n = int(round(DURATION / h)) + 1
    k_gain, t_const = 0.25, 6.0
    psi = r = delta = 0.0
    cmd = 20.0
    out = {c: np.zeros(n) for c in ("t", "psi", "r", "delta")}
    for i in range(n):
        t = i * h
        out["t"][i], out["psi"][i], out["r"][i], out["delta"][i] = t, psi, r, delta
        if psi > 20.0:
            cmd = -20.0
        elif psi < -20.0:
            cmd = 20.0
        if t >= 1.0:
            delta += np.clip(cmd - delta, -14.0 * h, 14.0 * h)
        rdot = (k_gain * delta - r) / t_const
        psi += h * (r + 0.5 * h * rdot)
        r += h * rdot
    step = int(round(DT / h))
    sel = slice(0, n, step)
    t = out["t"][sel]
    psi_d, r_d, d_d = out["psi"][sel], out["r"][sel], out["delta"][sel]
    u = U0 - 0.1 * (1 - np.exp(-t / 15.0))
    v = -0.02 * r_d
    ang = np.deg2rad(psi_d)
    dx0 = u * np.cos(ang) - v * np.sin(ang)
    dy0 = u * np.sin(ang) + v * np.cos(ang)
    x0 = np.concatenate([[0.0], np.cumsum(0.5 * (dx0[1:] + dx0[:-1]) * DT)])
    y0 = np.concatenate([[0.0], np.cumsum(0.5 * (dy0[1:] + dy0[:-1]) * DT)])
    return {"time": t, "x0": x0, "y0": y0, "psi": psi_d, "u": u, "v": v, "r": r_d, "delta": d_d,
            "rpm": np.full(t.size, 600.0)}


FMT = {"time": "{:.2f}", "x0": "{:.4f}", "y0": "{:.4f}", "psi": "{:.5f}", "u": "{:.5f}", "v": "{:.5f}",
       "r": "{:.5f}", "delta": "{:.4f}", "rpm": "{:.1f}"}


def _rows(tr: dict[str, np.ndarray], cols=COLS, fmt=None) -> list[list[str]]:
    fmt = fmt or FMT
    return [[fmt.get(c, "{:.6g}").format(tr[c][k]) for c in cols] for k in range(len(tr["time"]))]


def _text(rows, header=None, head=None, sep=",", end="\n") -> str:
    header = ",".join(COLS) if header is None else header
    head = HEADER if head is None else head
    return end.join(head + [header] + [sep.join(r) for r in rows]) + end


def probes() -> dict[str, bytes]:
    """name -> file content."""
    tr = clean_truth()
    rows = _rows(tr)
    clean = _text(rows)
    out: dict[str, bytes] = {"clean.csv": clean.encode()}
    # --- real-file quirks
    out["trailing_excel_rows.csv"] = (clean + ",,,,,,,,\n" * 3).encode()
    out["quoted_numbers.csv"] = _text([[f'"{x}"' for x in r] for r in rows]).encode()
    out["extra_text_column.csv"] = _text([r + [f"note {k % 3}"] for k, r in enumerate(rows)],
                                         ",".join(COLS) + ",comment").encode()
    out["crlf.csv"] = clean.replace("\n", "\r\n").encode()
    # --- other separators and encodings (item 10)
    out["semicolon_decimal_comma.csv"] = _text([[x.replace(".", ",") for x in r] for r in rows],
                                               ";".join(COLS), sep=";").encode()
    out["tab_separated.tsv"] = _text(rows, "\t".join(COLS), sep="\t").encode()
    out["gzip.csv.gz"] = gzip.compress(clean.encode(), mtime=0)
    out["utf16.csv"] = clean.encode("utf-16")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr(zipfile.ZipInfo("clean.csv", date_time=(2020, 1, 1, 0, 0, 0)), clean)
    out["zipped.zip"] = buf.getvalue()
    ms = dict(tr, time=tr["time"] * 1000.0)
    out["time_ms_undeclared.csv"] = _text(_rows(ms, fmt=dict(FMT, time="{:.0f}"))).encode()
    out["time_ms_declared.csv"] = _text(_rows(ms, fmt=dict(FMT, time="{:.0f}")),
                                        ",".join(COLS).replace("time", "time [ms]")).encode()
    # --- declared units (item 4): converted
    rad = dict(tr, psi=np.deg2rad(tr["psi"]), r=np.deg2rad(tr["r"]), delta=np.deg2rad(tr["delta"]))
    fr = dict(FMT, psi="{:.8f}", r="{:.8f}", delta="{:.8f}")
    out["psi_declared_rad.csv"] = _text(_rows(dict(tr, psi=rad["psi"]), fmt=fr),
                                        ",".join(COLS).replace("psi", "psi [rad]")).encode()
    out["r_declared_rad_s.csv"] = _text(_rows(dict(tr, r=rad["r"]), fmt=fr),
                                        ",".join(COLS).replace(",r,", ",r (rad/s),")).encode()
    out["all_suffix_rad.csv"] = _text(_rows(rad, fmt=fr), ",".join(COLS).replace("psi", "psi_rad")
                                      .replace(",r,", ",r_rad_s,").replace("delta", "delta_rad")).encode()
    out["unknown_unit.csv"] = _text(rows, ",".join(COLS).replace("psi", "psi [grad]")).encode()
    # --- undeclared units that cannot be right (item 4): refused
    out["r_rad_s_undeclared.csv"] = _text(_rows(dict(tr, r=rad["r"]), fmt=fr)).encode()
    out["psi_rad_undeclared.csv"] = _text(_rows(dict(tr, psi=rad["psi"]), fmt=fr)).encode()
    out["psi_r_both_rad.csv"] = _text(_rows(dict(tr, psi=rad["psi"], r=rad["r"]), fmt=fr)).encode()
    out["rudder_rad_no_test.csv"] = _text(_rows(dict(tr, delta=rad["delta"]), fmt=fr),
                                          head=HEADER[:2]).encode()
    flipped = dict(tr, delta=-tr["delta"])
    out["rudder_sign_flipped.csv"] = _text(_rows(flipped), head=HEADER[:2]).encode()
    # --- spikes (item 5)
    b = [list(r) for r in rows]
    b[150][3] = f"{float(b[150][3]) + 1000.0:.5f}"
    out["heading_spike.csv"] = _text(b).encode()
    b = [list(r) for r in rows]
    b[150][6] = f"{float(b[150][6]) + 25.0:.5f}"
    out["yaw_rate_spike.csv"] = _text(b).encode()
    # --- scale
    lam = 45.7
    full = {"time": tr["time"] * np.sqrt(lam), "x0": tr["x0"] * lam, "y0": tr["y0"] * lam, "psi": tr["psi"],
            "u": tr["u"] * np.sqrt(lam), "v": tr["v"] * np.sqrt(lam), "r": tr["r"] / np.sqrt(lam),
            "delta": tr["delta"], "rpm": tr["rpm"] / np.sqrt(lam)}
    full_head = ["# ship: KVLCC2", "# test: zigzag 20/20 starboard"]
    out["full_scale_no_scale.csv"] = _text(_rows(full, fmt=dict(FMT, r="{:.7f}")), head=full_head).encode()
    out["model_at_8_m_s.csv"] = _text(_rows(dict(tr, u=tr["u"] * 6.7))).encode()
    out["states_model_scale.csv"] = _text(rows, head=HEADER + ["# scale: 45.7"]).encode()
    # --- non-numeric in a used column: refused naming row and column
    b = [list(r) for r in rows]
    b[40][4] = "fast"
    out["text_in_used_column.csv"] = _text(b).encode()
    # --- HSVA layout, title in another code page, and without a usable title (item 10)
    def hsva(title: bytes) -> bytes:
        head = [b" HSVA, experimental data CPMC", b" KVLCC2  model 1:45.7", title, b" Time series"]
        body = []
        for k in range(len(tr["time"])):
            vals = [tr["time"][k], tr["x0"][k], tr["y0"][k], tr["psi"][k], tr["u"][k], tr["v"][k],
                    tr["r"][k], 0.0, -tr["delta"][k], 10.0, 20.0, 1.0]
            body.append(" ".join(f"{x:12.5f}" for x in vals).encode())
        return b"\n".join(head + body) + b"\n"
    out["hsva_title_cp437.dat"] = hsva(" Z20°/20° starting to starboard".encode("cp437"))
    out["hsva_title_unreadable.dat"] = hsva(b" \xff\xfe\xfd test")
    return out


# name -> (ingest options, outcome, detail)
PROBES: dict[str, tuple[dict, str, object]] = {
    "clean.csv": ({}, "equal", {}),
    "trailing_excel_rows.csv": ({}, "equal", {}),
    "quoted_numbers.csv": ({}, "equal", {}),
    "extra_text_column.csv": ({}, "equal", {"note": "column 'comment' ignored"}),
    "crlf.csv": ({}, "equal", {}),
    "semicolon_decimal_comma.csv": ({}, "equal", {"note": "decimal commas"}),
    "tab_separated.tsv": ({}, "equal", {"note": "tab-separated"}),
    "gzip.csv.gz": ({}, "equal", {"note": "gzip"}),
    "utf16.csv": ({}, "equal", {"note": "UTF-16"}),
    "time_ms_declared.csv": ({}, "converted", {"note": "column 'time' converted from declared ms"}),
    "psi_declared_rad.csv": ({}, "converted", {"note": "column 'psi' converted from declared rad"}),
    "r_declared_rad_s.csv": ({}, "converted", {"note": "column 'r' converted from declared rad/s"}),
    "all_suffix_rad.csv": ({}, "converted", {"note": "column 'delta' converted from declared rad"}),
    "rudder_sign_flipped.csv --rudder-sign -1": ({"rudder_sign": -1}, "equal", {}),
    "marin_nan_tail.dat --scale 45.7": ({"scale": 45.7}, "equal_marin", {"note": "NaN rows"}),
    "hsva_title_cp437.dat": ({}, "kind", {"kind": "zigzag", "rudder_deg": 20.0, "heading_deg": 20.0}),
    "hsva_title_unreadable.dat": ({}, "kind", {"kind": "zigzag", "rudder_deg": 20.0,
                                               "test_from": "rudder signal"}),
    "zipped.zip": ({}, "refused", ("zip archive", None, None)),
    "time_ms_undeclared.csv": ({}, "refused", ("not in seconds", None, "time")),
    "unknown_unit.csv": ({}, "refused", ("declared unit 'grad'", 4, "psi")),
    "r_rad_s_undeclared.csv": ({}, "refused", ("yaw rate looks like rad/s", None, "r")),
    "psi_rad_undeclared.csv": ({}, "refused", ("heading looks like radians", None, "psi")),
    "psi_r_both_rad.csv": ({}, "refused", ("probably in radians", None, "psi")),
    "rudder_rad_no_test.csv": ({}, "refused", ("rudder looks like radians", None, "delta")),
    "rudder_sign_flipped.csv": ({}, "refused", ("--rudder-sign -1", None, "delta")),
    "heading_spike.csv": ({}, "refused", ("spike", SPIKE_ROW, "psi")),
    "yaw_rate_spike.csv": ({}, "refused", ("spike", SPIKE_ROW, "r")),
    "full_scale_no_scale.csv": ({}, "refused", ("look full scale", None, None)),
    "model_at_8_m_s.csv": ({}, "refused", ("look full scale", None, "u")),
    "states_model_scale.csv --scale 45.7": ({"scale": 45.7}, "refused", ("scale it twice", None, None)),
    "text_in_used_column.csv": ({}, "refused", ("not a number", 3 + 1 + 41, "u")),
    "marin_nan_tail.dat": ({}, "refused", ("look full scale", None, None)),
}


def marin_nan_tail() -> bytes:
    """The MARIN fixture with NaN rows at its end (as real MARIN files have)."""
    text = (DATA / "marin_zigzag_fullscale.dat").read_text().rstrip("\n\t")
    return (text + "\n" + "\n".join(["\t".join(["NaN"] * 11)] * 4) + "\n").encode()


def make_probes(dir_: Path = PROBE_DIR) -> list[Path]:
    dir_.mkdir(parents=True, exist_ok=True)
    written = []
    files = probes()
    files["marin_nan_tail.dat"] = marin_nan_tail()
    for name, data in files.items():
        p = dir_ / name
        p.write_bytes(data)
        written.append(p)
    return written


if __name__ == "__main__":
    print(f"written {len(make_probes())} probes in {PROBE_DIR}")
