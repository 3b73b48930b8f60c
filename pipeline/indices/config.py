"""Settings of the indices stage.

There is no ``IndicesConfig`` in :mod:`pipeline.config` yet; it lives here until the lead moves it
there (and into ``PipelineConfig``).  Everything is deterministic: the only random draws (Monte Carlo
check of the uncertainty propagation) are seeded from ``seed``.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class IndicesConfig:
    """Zigzag/turning analysis, Nomoto K-T methods and index uncertainty."""

    algorithms: tuple[str, ...] = ("srukf-ffm", "ffm-ukf")   # identify/<alg>/estimates.json read
    uncertainty: str = "unscented"      # 'unscented' or 'linear' (central-difference Jacobian)
    mc_samples: int = 20000             # Monte Carlo check of the propagation (tests / diagnostics)
    seed: int = 4                       # seed of the Monte Carlo draws
    # Rudder execute detection (zigzag and turning): hysteresis at +-level_fraction of the rudder
    # amplitude; ramp fitted between ramp_band fractions of each transition.
    level_fraction: float = 0.5
    ramp_band: tuple[float, float] = (0.2, 0.8)
    # Heading extrema: a cubic is fitted to psi within +-peak_window s of the raw extremum
    # (clipped to a fraction of the interval between executes).
    peak_window: float = 1.5
    # Heading at an execute: straight line fitted to psi over this many seconds before it.
    heading_window: float = 2.0
    # Yaw rate read off the heading curve (the 'tangent' of the graphical method): local straight
    # line over +-tangent_window s.
    tangent_window: float = 0.4
    # Turning circle: steady part starts at this heading change (deg), lowered to 180 deg when the
    # run does not turn far enough; needs at least steady_min_span deg of steady turning.
    steady_from: float = 270.0
    steady_min_span: float = 90.0
    # IMO check: model scale factor by ship, used when the run's metadata does not give it
    # (L/U is a full-scale time; KVLCC2 HSVA 1:45.7 from the data README, KCS SIMMAN 1:37.89).
    ship_scales: dict[str, float] = field(default_factory=lambda: {"KVLCC2": 45.7, "KCS": 37.89})
