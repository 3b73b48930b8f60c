"""Runs of the virtual tank written as another logger writes them (tests/test_columns.py).

The logger: SI units (heading and rudder in rad, yaw rate in rad/s, speeds in m/s, propeller in
rev/s), the heading wrapped to (-pi, pi], the rudder positive to port, its own column names with
units in brackets, 10 Hz, measured wind and roll columns, the record starting with the model
accelerating from rest, and empty rows at the end.  The same runs are also written as canonical CSV
(docs/contract.md#raw-formats) at 0.08 s, starting at the steady approach: what the logger's files must give.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline import tank
from pipeline.config import TankConfig

FINE_DT = 0.02             # s, the simulation's logging step: 0.08 and 0.1 are whole multiples of it
APPROACH_S = 3.0           # s of steady straight approach before the first execute
ACCEL_S = 8.0              # s of constant acceleration from rest before the approach
HEADING0_DEG = 170.0       # initial heading: a zigzag's swings then cross +-180 deg
LOGGER_COLUMNS = {         # canonical name -> the logger's column header
    "time": "Time [s]", "x0": "PosX [m]", "y0": "PosY [m]", "psi": "Heading [rad]",
    "r": "YawRate [rad/s]", "delta": "Rudder [rad]", "u": "Surge [m/s]", "v": "Sway [m/s]",
    "rpm": "Prop [rps]", "wind_speed": "WindSpeed [m/s]", "wind_dir": "WindDir [deg]", "phi": "Roll [rad]",
}
LOGGER_TOML_COLUMNS = '''[columns]
time = {source = "Time [s]"}
x0 = {source = "PosX [m]", unit = "m"}
y0 = {source = "PosY [m]", unit = "m"}
psi = {source = "Heading [rad]", unit = "rad", wrapped = true}
r = {source = "YawRate [rad/s]", unit = "rad/s"}
delta = {source = "Rudder [rad]", unit = "rad", sign = -1}
u = {source = "Surge [m/s]", unit = "m/s"}
v = {source = "Sway [m/s]", unit = "m/s"}
rpm = {source = "Prop [rps]", unit = "rps"}
wind_speed = {source = "WindSpeed [m/s]", unit = "m/s"}
wind_dir = {source = "WindDir [deg]", unit = "deg"}
phi = {source = "Roll [rad]", unit = "rad"}
'''


@functools.lru_cache(maxsize=8)
def zigzag_with_approach(rudder: float, side: str, duration: float = 60.0) -> pd.DataFrame:
    """A noise-free virtual-tank zigzag at FINE_DT, with APPROACH_S of steady approach before it
    (time 0 at the start of the approach), turned to HEADING0_DEG."""
    cfg = dataclasses.replace(TankConfig(), log_dt=FINE_DT, noise=False)
    f = tank.simulate(tank.zigzag(rudder, rudder, side, duration=duration), cfg).frame.copy()
    n_app = int(round(APPROACH_S / FINE_DT))
    u0, rpm0 = float(f["u"].iloc[0]), float(f["rpm"].iloc[0])
    ta = -np.arange(n_app, 0, -1) * FINE_DT
    app = pd.DataFrame({"time": ta, "x0": u0 * ta, "y0": 0.0 * ta, "psi": 0.0 * ta, "u": u0 + 0 * ta,
                        "v": 0.0 * ta, "r": 0.0 * ta, "delta": 0.0 * ta, "rpm": rpm0 + 0 * ta})
    f = pd.concat([app, f[app.columns]], ignore_index=True)
    f["time"] = np.arange(len(f)) * FINE_DT
    a = np.deg2rad(HEADING0_DEG)
    x, y = f["x0"].to_numpy(), f["y0"].to_numpy()
    f["x0"], f["y0"] = np.cos(a) * x - np.sin(a) * y, np.sin(a) * x + np.cos(a) * y
    f["psi"] = f["psi"] + HEADING0_DEG
    return f


def write_canonical(frame: pd.DataFrame, path: Path, test: str) -> Path:
    """The run as canonical CSV at 0.08 s (every 4th sample)."""
    f = frame.iloc[::4].reset_index(drop=True)
    path.write_text(f"# test: {test}\n" + f.to_csv(index=False, float_format="%.9g", lineterminator="\n"))
    return path


def logger_frame(frame: pd.DataFrame, accel_s: float = ACCEL_S, step: int = 5) -> pd.DataFrame:
    """The run as the logger has it (module docstring): every ``step``-th sample of FINE_DT, after
    ``accel_s`` of constant acceleration from rest (0 for none), in the logger's units and names."""
    f = frame.copy()
    if accel_s > 0:
        n = int(round(accel_s / FINE_DT))
        u0 = float(f["u"].iloc[0])
        tt = np.arange(n) * FINE_DT
        u = u0 * tt / accel_s
        dist = 0.5 * u0 / accel_s * tt ** 2 - 0.5 * u0 * accel_s      # reaches the approach's start
        a = np.deg2rad(HEADING0_DEG)
        x_a, y_a = float(f["x0"].iloc[0]), float(f["y0"].iloc[0])
        pre = pd.DataFrame({"x0": x_a + np.cos(a) * dist, "y0": y_a + np.sin(a) * dist,
                            "psi": HEADING0_DEG + 0 * tt, "u": u, "v": 0 * tt, "r": 0 * tt,
                            "delta": 0 * tt, "rpm": f["rpm"].iloc[0] + 0 * tt})
        f = pd.concat([pre, f.drop(columns="time")], ignore_index=True)
    f["time"] = np.arange(len(f)) * FINE_DT
    f = f.iloc[::step].reset_index(drop=True)
    k = np.arange(len(f))
    out = pd.DataFrame({
        "time": f["time"], "x0": f["x0"], "y0": f["y0"],
        "psi": np.angle(np.exp(1j * np.deg2rad(f["psi"].to_numpy()))),          # wrapped to (-pi, pi]
        "r": np.deg2rad(f["r"]), "delta": -np.deg2rad(f["delta"]), "u": f["u"], "v": f["v"],
        "rpm": f["rpm"] / 60.0, "wind_speed": 3.0 + 0.1 * np.sin(0.05 * k), "wind_dir": 45.0 + 0 * k,
        "phi": np.deg2rad(0.5 * np.sin(0.3 * k)),
    })
    return out.rename(columns=LOGGER_COLUMNS)


def write_logger(frame: pd.DataFrame, path: Path, empty_rows: int = 3) -> Path:
    """The logger's table as CSV with ``empty_rows`` rows of empty fields at the end."""
    body = frame.to_csv(index=False, float_format="%.9g", lineterminator="\n")
    path.write_text(body + ("," * (frame.shape[1] - 1) + "\n") * empty_rows)
    return path
