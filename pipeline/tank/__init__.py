"""The virtual tank: a 3-DOF MMG model of the KCS at model scale 1:37.89 (SIMMAN 2020 deep water).

Its runs are written as canonical CSVs (docs/contract.md#raw-formats) and then go through the same stages as
measured data.  Every run says ``provenance: virtual``.

Public API::

    zigzag(rudder_deg, heading_deg, first_side="starboard", duration=None) -> Manoeuvre
    turning_circle(rudder_deg=35.0, side="starboard", duration=None) -> Manoeuvre
    selection_set() -> list[Manoeuvre]  # the six runs the diagnosis chooses on
    held_out_set() -> list[Manoeuvre]   # its three test runs, which no choice sees
    default_set() -> list[Manoeuvre]    # selection_set() + held_out_set()
    straight(duration=60.0) -> Manoeuvre  # rudder amidships, for checks
    simulate(manoeuvre, cfg=TankConfig()) -> pipeline.io.Run
    write_csv(path, run)
    KCSShip(cfg=TankConfig())            # stepping simulator for closed-loop use
    linearise(cfg=TankConfig())          # Nomoto indices of the linearised model

See :mod:`pipeline.tank.kcs` for the model, its sign conventions and the decisions taken, and
docs/virtual-tank.md.
"""

from pipeline.tank.kcs import KCSCoefficients, KCSShip, linearise, trim_rps
from pipeline.tank.manoeuvres import (
    Manoeuvre,
    default_set,
    held_out_set,
    selection_set,
    straight,
    turning_circle,
    zigzag,
)
from pipeline.tank.simulate import noise_seed, simulate, write_csv

__all__ = [
    "KCSCoefficients", "KCSShip", "Manoeuvre", "default_set", "held_out_set", "linearise", "noise_seed",
    "selection_set", "simulate", "straight", "trim_rps", "turning_circle", "write_csv", "zigzag",
]
