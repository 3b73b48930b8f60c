"""pipeline.diagnose.datacheck: the approach's drift angle (a heading reference off the centreline) and
the yaw rate against the heading's change (a rate gyro's bias)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from truths import tanker as tk
from truths.files import marin_test_name, write_marin

from pipeline.config import IngestConfig
from pipeline.diagnose.datacheck import (
    MISALIGNMENT_FLOOR_DEG,
    approach_drift,
    correct_rate_bias,
    rate_bias,
)
from pipeline.diagnose.fit import Series, series_from_run
from pipeline.ingest import ingest_file


def _series(name: str, drift_deg: float, n_approach: int = 25, u: float = 1.2, seed: int = 0) -> Series:
    """A straight approach at u m/s drifting ``drift_deg`` (v = u tan(drift) + 2 mm/s of noise), then a
    10 deg rudder execute and a turn."""
    rng = np.random.default_rng(seed)
    n = 200
    t = np.arange(n) * 0.08
    delta = np.where(np.arange(n) < n_approach, 0.0, 10.0)
    v = np.where(np.arange(n) < n_approach, u * math.tan(math.radians(drift_deg)), -0.05)
    v = v + rng.normal(0.0, 0.002, n)
    r = np.where(np.arange(n) < n_approach, 0.0, 1.0)
    return Series(name, t, delta, np.cumsum(r) * 0.08, r, v, np.full(n, u))


def test_known_drift_is_read_and_warned():
    """Known answers: a 0.5 deg drift in every approach is read within noise and warned of; none is
    not; drifts of both signs (a ship's own, not a sensor's) are not; an approach shorter than five
    samples is not read; runs without v are left out."""
    runs = [_series(f"a{k}", 0.5, seed=k) for k in range(3)]
    got = approach_drift(runs)
    assert got["median_deg"] == pytest.approx(0.5, abs=0.05)
    assert all(d == pytest.approx(0.5, abs=0.05) for d in got["per_run"].values())
    assert got["warning"] and "+0.50 deg in every run" in got["warning"]
    assert "+0.0105 m/s" in got["warning"]          # u sin(0.5 deg) = 1.2 x 0.008727
    assert approach_drift([_series(f"b{k}", 0.0, seed=k) for k in range(3)])["warning"] is None
    mixed = [_series("c0", 0.5), _series("c1", -0.4, seed=1), _series("c2", 0.6, seed=2)]
    assert approach_drift(mixed)["warning"] is None
    short = approach_drift([_series("d0", 2.0, n_approach=3)])
    assert short == {"per_run": {}, "median_deg": None, "warning": None}
    nov = _series("e0", 2.0)
    nov.v = None
    assert approach_drift([nov])["per_run"] == {}
    below = approach_drift([_series(f"f{k}", 0.5 * MISALIGNMENT_FLOOR_DEG, seed=k) for k in range(3)])
    assert below["warning"] is None


@pytest.mark.parametrize("eps", [0.0, 1.0])
def test_misaligned_marin_files_are_told(tmp_path, eps):
    """The tanker's MARIN files (full scale, read with --scale 50) with the heading reference
    misaligned by ``eps`` deg (tests/truths/files.write_marin): the reader's v carries -u sin(eps), so
    the approach drifts by -eps; aligned files drift by the ship's own (the propeller's) next to
    nothing, and get no warning.

    Measured 2026-11-25 (two 20/20 zigzags, noise seed 1300): aligned +0.04 / +0.10 deg; 1 deg
    -0.96 / -0.90 deg, warned; 0.3 deg -0.26 / -0.20 deg, under the 0.3 deg floor: the check is silent
    there, though a fold of the published tanker already lost its cut (test_tanker_heading_misalignment)."""
    ship = tk.Tanker(form="offset")
    series = []
    for j, side in enumerate(("starboard", "port")):
        f = tk.simulate_zigzag(ship, 20, 20, side, duration=300.0, seed=1300 + j, scale=50.0)
        path = write_marin(f, tmp_path / f"tk_{side}.dat", marin_test_name("Tanker", 20, 20),
                           heading_misalignment_deg=eps)
        run = ingest_file(path, scale=50.0, config=IngestConfig())
        run.meta["run_id"] = path.stem
        series.append(series_from_run(run))
    got = approach_drift(series)
    assert len(got["per_run"]) == 2
    assert got["median_deg"] == pytest.approx(-eps, abs=0.1), got
    assert (got["warning"] is not None) == (eps > 0), got


def _gyro_run(name: str, bias: float, seed: int, turn_deg_s: float = 0.0, dur: float = 120.0) -> Series:
    """A continuous-time heading, not the check's formula: psi(t) = 15 sin(2 pi t / 40) + 5 sin(2 pi t
    / 13 + 1) deg plus a steady turn (deg/s), sampled every 0.08 s; psi logged with 0.1 deg white
    noise, r the exact derivative plus ``bias`` (deg/s) plus AR(1) noise (0.05 deg/s, lag-1
    correlation 0.9: a gyro's coloured noise)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, dur, 0.08)
    w1, w2 = 2 * math.pi / 40, 2 * math.pi / 13
    psi = 15 * np.sin(w1 * t) + 5 * np.sin(w2 * t + 1) + turn_deg_s * t
    r = 15 * w1 * np.cos(w1 * t) + 5 * w2 * np.cos(w2 * t + 1) + turn_deg_s
    e = np.empty(t.size)
    e[0] = rng.normal(0.0, 0.05)
    for k in range(1, t.size):
        e[k] = 0.9 * e[k - 1] + rng.normal(0.0, 0.05 * math.sqrt(1 - 0.81))
    delta = 10.0 * np.sign(np.sin(w1 * t))
    return Series(name, t, delta, psi + rng.normal(0.0, 0.1, t.size), r + bias + e)


def test_rate_bias_known_answers():
    """A gyro's bias read against the heading's change, within noise; corrected only when significant;
    its standard error is the scatter of the estimate; a turning circle's heading (hundreds of
    degrees) is no bias."""
    got = rate_bias([_gyro_run(f"g{k}", 0.05, seed=k) for k in range(4)])
    for x in got["per_run"].values():
        assert x["bias_deg_s"] == pytest.approx(0.05, abs=3 * x["se_deg_s"]) and x["corrected"], x
    assert got["warning"] and "4 of 4 runs" in got["warning"]
    # the correction leaves r agreeing with the heading, and runs not marked untouched
    runs = [_gyro_run("a", 0.05, seed=10), _gyro_run("b", 0.0, seed=11)]
    check = rate_bias(runs)
    fixed = correct_rate_bias(runs, check)
    assert check["per_run"]["b"]["corrected"] is False and fixed[1] is runs[1]
    after = rate_bias(fixed)["per_run"]["a"]
    assert abs(after["bias_deg_s"]) < 1e-9 and not after["corrected"]
    assert np.allclose(runs[0].r - fixed[0].r, check["per_run"]["a"]["bias_deg_s"])
    # unbiased: the estimates scatter as their standard error says (coloured noise counted), and none
    # of 100 runs is corrected (RATE_BIAS_ALPHA: 0.27 % each)
    clean = rate_bias([_gyro_run(f"c{k}", 0.0, seed=100 + k) for k in range(100)])
    b = np.array([x["bias_deg_s"] for x in clean["per_run"].values()])
    se = np.mean([x["se_deg_s"] for x in clean["per_run"].values()])
    assert 0.7 < np.std(b) / se < 1.3, (np.std(b), se)
    assert clean["warning"] is None and not any(x["corrected"] for x in clean["per_run"].values())
    # a turning circle: 0.8 deg/s for 120 s, 96 deg of steady turn, no bias
    circle = rate_bias([_gyro_run("tc", 0.0, seed=7, turn_deg_s=0.8)])["per_run"]["tc"]
    assert not circle["corrected"] and abs(circle["bias_deg_s"]) < 3 * circle["se_deg_s"], circle
    # the same circle's heading wrapped into [0, 360) (a file not through ingest): the same reading
    wrapped = _gyro_run("tc", 0.0, seed=7, turn_deg_s=0.8)
    wrapped.psi = np.mod(wrapped.psi, 360.0)
    assert rate_bias([wrapped])["per_run"]["tc"] == pytest.approx(circle)
