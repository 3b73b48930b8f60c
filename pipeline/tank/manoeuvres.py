"""Manoeuvre definitions for the virtual tank: zigzags and turning circles (ITTC 7.5-04-02-01), the
latter optionally ending in a pull-out (the rudder returned to midships once the turn is steady;
IMO MSC/Circ.1053's test of course stability).

The first execute is at t = 0 from a steady straight approach (the identification window of the
paper, the first 585 samples of the 20/20 zigzag, then starts at the execute).  Angles in degrees,
times in seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pipeline.config import TankConfig
from pipeline.errors import InputError

SIDES = ("starboard", "port")

#: Default record lengths, s at model scale (pipeline/config.py TankConfig says why).
ZIGZAG_DURATION = TankConfig.zigzag_duration
TURNING_DURATION = TankConfig.turning_duration


def _num(x: float) -> str:
    return f"{x:g}"


@dataclass(frozen=True)
class Manoeuvre:
    """One free-running test: ``kind`` 'zigzag', 'turning' or 'straight'.

    rudder_deg : rudder amplitude (> 0), deg.  heading_deg : zigzag heading trigger (> 0), deg
    (None for turning).  side : first execute side, 'starboard' (rudder positive, psi increasing)
    or 'port'.  duration : record length, s.  pull_out_s : turning only, the time (s after the
    execute) at which the rudder is commanded back to midships; None for none.
    """

    kind: str
    rudder_deg: float
    heading_deg: float | None
    side: str
    duration: float
    pull_out_s: float | None = None

    @property
    def sign(self) -> float:
        """+1 for a first execute to starboard (positive rudder), -1 to port."""
        return 1.0 if self.side == "starboard" else -1.0

    @property
    def test_name(self) -> str:
        """E.g. 'zigzag 20/20 starboard', 'turning circle 35 port' (pipeline.runinfo parses these)."""
        if self.kind == "zigzag":
            return f"zigzag {_num(self.rudder_deg)}/{_num(self.heading_deg)} {self.side}"
        if self.kind == "straight":
            return "straight run"
        # the pull-out's time stays out of the title (a title's last standalone number is read as
        # the rudder angle, pipeline.runinfo); it is in the file stem and the metadata
        pull = " with pull-out" if self.pull_out_s is not None else ""
        return f"turning circle {_num(self.rudder_deg)} {self.side}{pull}"

    @property
    def file_stem(self) -> str:
        """E.g. 'kcs_zigzag_20_20_S', 'kcs_turning_35_P' (non-integer angles as 12p5)."""
        s = "S" if self.side == "starboard" else "P"

        def tok(x):
            return _num(x).replace(".", "p")

        if self.kind == "zigzag":
            return f"kcs_zigzag_{tok(self.rudder_deg)}_{tok(self.heading_deg)}_{s}"
        if self.kind == "straight":
            return "kcs_straight"
        pull = f"_pullout{tok(self.pull_out_s)}" if self.pull_out_s is not None else ""
        return f"kcs_turning_{tok(self.rudder_deg)}_{s}{pull}"


def _check(rudder_deg, side, duration, what):
    if not (isinstance(rudder_deg, (int, float)) and math.isfinite(rudder_deg) and rudder_deg > 0):
        raise InputError(f"{what}: rudder angle must be a positive number of degrees, got {rudder_deg!r}")
    if side not in SIDES:
        raise InputError(f"{what}: side must be 'starboard' or 'port', got {side!r}")
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        raise InputError(f"{what}: duration must be a positive number of seconds, got {duration!r}")


def zigzag(rudder_deg: float, heading_deg: float, first_side: str = "starboard", *,
           duration: float | None = None) -> Manoeuvre:
    """A rudder_deg/heading_deg zigzag, first execute to ``first_side``.

    Parameters
    ----------
    rudder_deg : float
        Rudder angle, deg (> 0).
    heading_deg : float
        Heading deviation that triggers each counter-rudder, deg (> 0).
    first_side : str
        'starboard' or 'port'.
    duration : float, optional
        Length of the record from the first execute, s (default 150 s).

    Returns
    -------
    Manoeuvre
    """
    _check(rudder_deg, first_side, duration, "zigzag")
    if not (isinstance(heading_deg, (int, float)) and math.isfinite(heading_deg) and heading_deg > 0):
        raise InputError(f"zigzag: heading trigger must be a positive number of degrees, got {heading_deg!r}")
    return Manoeuvre("zigzag", float(rudder_deg), float(heading_deg), first_side,
                     float(duration) if duration is not None else ZIGZAG_DURATION)


def turning_circle(rudder_deg: float = 35.0, side: str = "starboard",
                   duration: float | None = None, *, pull_out_s: float | None = None) -> Manoeuvre:
    """A turning circle at constant rudder to ``side``.

    Parameters
    ----------
    rudder_deg : float
        Rudder angle, deg (> 0).
    side : str
        'starboard' or 'port'.
    duration : float, optional
        Length of the record from the execute, s (default 90 s, > 400 deg of heading).
    pull_out_s : float, optional
        Time after the execute (s, inside the record) at which the rudder is commanded back to
        midships; the rest of the record is the pull-out.

    Returns
    -------
    Manoeuvre
    """
    _check(rudder_deg, side, duration, "turning circle")
    dur = float(duration) if duration is not None else TURNING_DURATION
    if pull_out_s is not None and not (isinstance(pull_out_s, (int, float)) and math.isfinite(pull_out_s)
                                       and 0 < pull_out_s < dur):
        raise InputError(f"turning circle: pull-out time must be inside the record (0, {dur:g}) s, "
                         f"got {pull_out_s!r}")
    return Manoeuvre("turning", float(rudder_deg), None, side, dur,
                     float(pull_out_s) if pull_out_s is not None else None)


def straight(duration: float = 60.0) -> Manoeuvre:
    """A straight run with the rudder amidships (not in the default set; for checks).

    Parameters
    ----------
    duration : float
        Length of the record, s.

    Returns
    -------
    Manoeuvre
    """
    _check(1.0, "starboard", duration, "straight run")
    return Manoeuvre("straight", 0.0, None, "starboard", float(duration))


def selection_set() -> list[Manoeuvre]:
    """The built-in tank's runs that the diagnosis chooses on: twins, one of each trains and one
    validates (pipeline.diagnose.design).

    Returns
    -------
    list of Manoeuvre
        Zigzags 20/20 and 10/10 to both sides, 35 deg turning circles to both sides.
    """
    return [
        zigzag(20, 20, "starboard"), zigzag(20, 20, "port"),
        zigzag(10, 10, "starboard"), zigzag(10, 10, "port"),
        turning_circle(35, "starboard"), turning_circle(35, "port"),
    ]


def held_out_set() -> list[Manoeuvre]:
    """The built-in tank's runs that no choice of the diagnosis sees: its test runs, on which the
    honest gain is measured (pipeline.diagnose.design makes them test runs: a pair between the
    selection's zigzag amplitudes, a turning circle without a twin).

    Returns
    -------
    list of Manoeuvre
        Zigzags 15/15 to both sides, a 25 deg turning circle to starboard.
    """
    return [zigzag(15, 15, "starboard"), zigzag(15, 15, "port"), turning_circle(25, "starboard")]


def default_set() -> list[Manoeuvre]:
    """The built-in tank's default runs: :func:`selection_set` then :func:`held_out_set`.

    Returns
    -------
    list of Manoeuvre
        Zigzags 20/20 and 10/10 to both sides, 35 deg turning circles to both sides; zigzags 15/15
        to both sides and a 25 deg turning circle to starboard.
    """
    return selection_set() + held_out_set()
