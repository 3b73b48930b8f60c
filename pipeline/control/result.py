"""The control stage's result as a typed, frozen object with its JSON form (docs/control.md).

``control/metrics.json`` is a :class:`ControlMetrics` when an autopilot was designed and a
:class:`RefusedControl` when no index set could be trusted (no design, the reason, nothing
simulated).  Both derive from :class:`pipeline.results.Result`: their fields are the file's keys in
the file's order.  The nested blocks (designs, results per plant and design, robustness, ...) stay
plain mappings: their keys belong to the functions that make them (:mod:`pipeline.control.design`,
:mod:`pipeline.control.metrics`, :mod:`pipeline.control.robustness`, :mod:`pipeline.control.adaptive`).
Angles in deg, rates in deg/s, times in s (docs/contract.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pipeline.results import Result, optional


@dataclass(frozen=True)
class ControlMetrics(Result):
    """``control/metrics.json`` of a designed autopilot.

    ``wind_rudder_deg`` the constant equivalent wind rudder (deg); ``wave_variance_theory_deg2`` the
    wave disturbance's variance (deg^2); ``seeds`` the wave seeds every (plant, design) pair ran on;
    ``designs`` design name -> its gains, loop analysis and sampled-loop margins; ``results`` one row
    per (plant, design) with per-seed metrics and their statistics; ``adaptive`` the in-loop
    identification block (None: not run, key left out); ``indices_source`` the indices file the
    command read (None: key left out).
    """

    dataset: str | None
    provenance: str
    virtual: bool
    builtin_tank: bool
    plants: dict[str, Any]
    notes: list[str]
    design_basis: dict[str, Any]
    config: dict[str, Any]
    wind_rudder_deg: float
    wave_variance_theory_deg2: float
    seeds: list[int]
    models: dict[str, Any]
    definitions: dict[str, Any]
    designs: dict[str, Any]
    results: list[dict[str, Any]]
    identification_value: dict[str, Any]
    paper: dict[str, Any]
    paper_case: dict[str, Any] | None
    design_model: dict[str, Any]
    settings: dict[str, Any]
    operating_point: dict[str, Any]
    robustness: dict[str, Any]
    adaptive: dict[str, Any] | None = optional()
    indices_source: str | None = optional()

    refused = False


@dataclass(frozen=True)
class RefusedControl(Result):
    """``control/metrics.json`` when the indices stage refused every index set: ``reason`` says why,
    ``designs``, ``results``, ``plants`` and ``seeds`` are empty."""

    dataset: str | None
    provenance: str
    virtual: bool
    builtin_tank: bool
    refused: bool
    reason: str | None
    design_basis: dict[str, Any]
    notes: list[str]
    config: dict[str, Any]
    designs: dict[str, Any]
    results: list[dict[str, Any]]
    identification_value: dict[str, Any]
    paper: dict[str, Any]
    plants: dict[str, Any]
    seeds: list[int]
    indices_source: str | None = optional()
