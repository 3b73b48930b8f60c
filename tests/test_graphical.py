"""Nomoto K and T from zigzags: the standard (graphical) and the integral (least-squares) methods.

Truth: first-order Nomoto zigzags simulated with a rate-limited rudder and measurement noise by
``simulate_zigzag`` (tests/test_zigzag.py).  Requirement (brief): both recover K and T within 3 %.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from test_zigzag import simulate_zigzag

from pipeline.config import IndicesConfig, ManoeuvreConfig
from pipeline.errors import InputError
from pipeline.indices import graphical_kt, integral_kt
from pipeline.io import Run

CASES = [  # K 1/s, T s, rudder/trigger deg, rudder rate deg/s, first side, seed
    (0.5, 6.0, 20, 5.0, 1, 0),
    (0.5, 6.0, 10, 5.0, -1, 1),
    (0.3, 10.0, 20, 14.28, 1, 2),
    (1.0, 3.0, 10, 2.32, -1, 3),
    (0.576, 4.816, 20, 14.28, 1, 4),
]


@pytest.mark.parametrize("K,T,amp,rate,side,seed", CASES)
def test_both_methods_recover_k_and_t(K, T, amp, rate, side, seed):
    run, _ = simulate_zigzag(K=K, T=T, rudder=amp, trigger=amp, rate=rate, first_side=side,
                             noise=0.05, seed=seed, duration=120)
    g = graphical_kt(run)
    i = integral_kt(run)
    assert g["method"] == "standard" and i["method"] == "integral"
    for res in (g, i):
        assert res["K"] == pytest.approx(K, rel=0.03)
        assert res["T"] == pytest.approx(T, rel=0.03)
    # the least-squares method is the sharper one on clean first-order data
    assert i["K"] == pytest.approx(K, rel=0.005) and i["T"] == pytest.approx(T, rel=0.005)
    assert abs(i["rudder_offset_deg"]) < 0.05
    # every swing between extrema tells the same K
    assert np.allclose(g["K_swings"], K, rtol=0.03)


def test_rudder_offset_is_found_by_integral_method():
    run, _ = simulate_zigzag(K=0.5, T=6.0, rudder=20, trigger=20, rate=5.0, noise=0.05, seed=5,
                             rudder_offset=1.5, duration=120)
    i = integral_kt(run)
    assert i["rudder_offset_deg"] == pytest.approx(1.5, abs=0.1)
    assert i["K"] == pytest.approx(0.5, rel=0.01) and i["T"] == pytest.approx(6.0, rel=0.01)
    no = integral_kt(run, offset=False)
    assert no["rudder_offset_deg"] is None
    assert abs(no["K"] / 0.5 - 1) > abs(i["K"] / 0.5 - 1)      # ignoring the offset costs accuracy
    # alternating swings cancel most of the offset in the standard method
    assert graphical_kt(run)["K"] == pytest.approx(0.5, rel=0.05)


def test_window_and_short_runs():
    run, _ = simulate_zigzag(duration=30)
    with pytest.raises(InputError, match="fewer than two heading extrema"):
        graphical_kt(run)
    run, _ = simulate_zigzag(duration=120)
    with pytest.raises(InputError, match="fewer than 20 samples"):
        integral_kt(run, t_start=10.0, t_end=10.5)
    part = integral_kt(run, t_start=0.0, t_end=60.0)
    assert part["K"] == pytest.approx(0.5, rel=0.01)
    # the floor is the configured one: 2 s at 0.08 s (26 samples) passes at 20, fails at 40
    dt = float(run.col("time")[1] - run.col("time")[0])
    n = int(np.sum((run.col("time") >= 10.0) & (run.col("time") <= 12.0)))
    assert dt == pytest.approx(0.08) and 20 <= n < 40
    assert integral_kt(run, t_start=10.0, t_end=12.0)["samples"] == n
    strict = replace(IndicesConfig(), manoeuvre=replace(ManoeuvreConfig(), integral_min_samples=40))
    with pytest.raises(InputError, match="fewer than 40 samples"):
        integral_kt(run, t_start=10.0, t_end=12.0, config=strict)


def test_integral_refuses_a_run_without_first_order_response():
    t = np.arange(0, 60, 0.08)
    rng = np.random.default_rng(0)
    run = Run(pd.DataFrame({"time": t, "psi": rng.standard_normal(t.size), "r": 0 * t,
                            "delta": 10 * np.sign(np.sin(t / 5))}), {"run_id": "junk"})
    with pytest.raises(InputError, match="no positive K and T"):
        integral_kt(run)
