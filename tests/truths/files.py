"""Raw files (docs/contract.md#raw-formats) written directly (no pipeline code) for ``ingest`` to read.

- :func:`write_csv`: canonical CSV, ``#`` key: value header, values in docs/contract.md#run-data units and
  signs, at the scale of the values given (model scale unless the caller passes ``--scale`` on
  reading);
- :func:`write_marin`: MARIN SIMMAN free-running ``.dat``: 3 header lines (institute; test name;
  blank), tab-separated E-format numbers with 3 significant digits, 11 columns
  ``time x0 y0 phi psi dx0 dy0 p r delta rev`` (s, m, m, deg, deg, m/s, m/s, deg/s, deg/s, deg,
  rpm), earth-fixed dx0, dy0, **positive rudder turning the ship to port** (the file's delta is
  minus the canonical one), two empty rows at the end (a quirk of real files);
- :func:`froude_to_full`: model-scale frame to full scale (lambda = L_full / L_model).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

# Froude exponents of lambda for each canonical column (time ~ sqrt, length ~ 1, velocity ~ sqrt,
# rate ~ -sqrt, angle ~ 0, rpm ~ -sqrt)
_FROUDE = {"time": 0.5, "x0": 1.0, "y0": 1.0, "psi": 0.0, "u": 0.5, "v": 0.5, "r": -0.5, "delta": 0.0,
           "rpm": -0.5, "phi": 0.0, "p": -0.5}


def froude_to_full(frame: pd.DataFrame, scale: float) -> pd.DataFrame:
    """Model-scale canonical frame to full scale (Froude similarity, lambda = ``scale``)."""
    out = frame.copy()
    for c in out.columns:
        if c in _FROUDE:
            out[c] = out[c].to_numpy(dtype=float) * scale ** _FROUDE[c]
    return out


def froude_to_model(frame: pd.DataFrame, scale: float) -> pd.DataFrame:
    """The inverse of :func:`froude_to_full`."""
    return froude_to_full(frame, 1.0 / scale)


def write_csv(frame: pd.DataFrame, path: str | Path, header: dict) -> Path:
    """Canonical CSV of the columns of ``frame`` that docs/contract.md#run-data names, with ``# key: value``
    lines from ``header`` (e.g. ship, test, provenance, lpp, dt, seed)."""
    path = Path(path)
    cols = [c for c in ("time", "x0", "y0", "psi", "u", "v", "r", "delta", "rpm") if c in frame.columns]
    lines = [f"# {k}: {v}" for k, v in header.items()]
    lines.append(",".join(cols))
    arr = frame[cols].to_numpy(dtype=float)
    lines += [",".join(f"{x:.7g}" for x in row) for row in arr]
    path.write_text("\n".join(lines) + "\n")
    return path


def _e3(x: float) -> str:
    return f"{x:.2E}"


INSTITUTE = "MARIN-layout file written by tests/truths (a simulation, not measured)"


def write_marin(frame: pd.DataFrame, path: str | Path, test_name: str, institute: str = INSTITUTE,
                heading_misalignment_deg: float = 0.0, rate_bias_deg_s: float = 0.0) -> Path:
    """MARIN SIMMAN free-running .dat of a canonical frame (values at the scale they are given).

    ``frame`` has time, x0, y0, psi, u, v, r, delta (canonical signs) and optionally rpm, phi, p.
    ``heading_misalignment_deg``: the file's heading reads this much more than the ship's (a heading
    reference set off the model's centreline); dx0, dy0 stay the true track velocities, so a reader
    that forms v from them and the heading gets v + u sin(misalignment).  ``rate_bias_deg_s``: a
    constant added to the file's yaw rate (a rate gyro's bias, in the file's scale).
    """
    path = Path(path)
    psi = frame["psi"].to_numpy(dtype=float)
    u = frame["u"].to_numpy(dtype=float)
    v = frame["v"].to_numpy(dtype=float)
    p = np.deg2rad(psi)
    dx0 = u * np.cos(p) - v * np.sin(p)
    dy0 = u * np.sin(p) + v * np.cos(p)
    if heading_misalignment_deg:       # (x + 0.0 would turn a -0.0 into 0.0: files stay byte-identical)
        psi = psi + heading_misalignment_deg
    r = frame["r"].to_numpy(dtype=float)
    if rate_bias_deg_s:
        r = r + rate_bias_deg_s
    n = len(frame)
    zeros = np.zeros(n)
    cols = [
        frame["time"].to_numpy(dtype=float),
        frame["x0"].to_numpy(dtype=float),
        frame["y0"].to_numpy(dtype=float),
        frame["phi"].to_numpy(dtype=float) if "phi" in frame else zeros,
        psi,
        dx0,
        dy0,
        frame["p"].to_numpy(dtype=float) if "p" in frame else zeros,
        r,
        -frame["delta"].to_numpy(dtype=float),          # MARIN: positive rudder turns to port
        frame["rpm"].to_numpy(dtype=float) if "rpm" in frame else zeros,
    ]
    rows = ["\t".join(_e3(c[k]) for c in cols) for k in range(n)]
    text = "\n".join([institute, test_name, ""] + rows) + "\n\n\n"
    path.write_text(text)
    return path


def marin_test_name(ship: str, rudder_deg: float, heading_deg: float) -> str:
    """The MARIN header spelling, e.g. ``Zig-zag manoeuvring for KVLCC2 : 20 / -20``."""
    return f"Zig-zag manoeuvring for {ship} : {rudder_deg:g} / -{heading_deg:g}"


def rounding_error_deg(x: float) -> float:
    """Half a unit of the third significant digit of x (what the 3-digit format can lose)."""
    if x == 0:
        return 0.0
    return 0.5 * 10.0 ** (math.floor(math.log10(abs(x))) - 2)
