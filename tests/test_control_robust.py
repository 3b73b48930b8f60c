"""The sampled plant built straight from the sway-yaw parameters equals the one through the transfer
function, with servo lag and dead time (pipeline/control/robust.py)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.control.robust import (
    loop_response,
    parameters_plant,
    parameters_rate_tf,
    sampled_plant_tf,
)
from pipeline.model import PAPER_TABLE4, PARAM_NAMES


@pytest.mark.parametrize("servo, dead", [(0.0, 0.0), (0.5, 0.16)])
def test_parameters_plant_equals_the_transfer_function_route(servo, dead):
    import control as ct

    theta = [PAPER_TABLE4[n] for n in PARAM_NAMES]
    dt = 0.08
    a = parameters_plant(theta, dt, servo_time_constant=servo, dead_time=dead)
    b = sampled_plant_tf(parameters_rate_tf(theta), dt, servo_time_constant=servo, dead_time=dead)
    w = np.logspace(-3, np.log10(np.pi / dt * 0.99), 50)
    for out in (0, 1):                                    # psi (deg) and r (deg/s) per deg of command
        ha = loop_response(ct.ss(a.A, a.B, a.C[out:out + 1], a.D[out:out + 1], dt), w)
        hb = loop_response(ct.ss(b.A, b.B, b.C[out:out + 1], b.D[out:out + 1], dt), w)
        np.testing.assert_allclose(ha, hb, rtol=1e-8, atol=1e-12)
    assert a.nstates == 3 + (servo > 0) + round(dead / dt)
