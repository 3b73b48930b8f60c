"""CGSA course-keeping autopilot: design (:mod:`.design`), disturbances (:mod:`.disturbance`),
closed-loop simulation (:mod:`.simulate`), metrics (:mod:`.metrics`) and the stage (:mod:`.stage`).

Units at the edges: K 1/s, time constants s, heading and rudder deg, yaw rate deg/s, frequency rad/s.
"""

from pipeline.control.design import (
    CGSADesign,
    bode_data,
    design_first_order,
    design_second_order,
    loop_analysis,
    nomoto_tf,
    open_loop,
    setpoint_response_tf,
)
from pipeline.control.disturbance import wave_sequence, wind_equivalent_rudder
from pipeline.control.metrics import course_metrics, seed_statistics
from pipeline.control.simulate import NomotoShip, simulate_course
from pipeline.control.stage import run_control

__all__ = [
    "CGSADesign", "NomotoShip", "bode_data", "course_metrics", "design_first_order", "design_second_order",
    "loop_analysis", "nomoto_tf", "open_loop", "run_control", "seed_statistics", "setpoint_response_tf",
    "simulate_course", "wave_sequence", "wind_equivalent_rudder",
]
