"""Manoeuvrability indices (docs/indices.md): Nomoto indices with uncertainty, ITTC zigzag and turning-circle
analysis with the IMO MSC.137(76) check, Nomoto K-T by the standard (graphical) and integral methods.

Public API (pure functions; units of docs/contract.md#run-data: s, m, deg, deg/s; positive delta
turns to starboard):

* :func:`zigzag_metrics` (run) -> dict          ITTC 7.5-04-02-01 zigzag metrics
* :func:`turning_metrics` (run) -> dict         advance, transfer, tactical/steady diameter, speed ratio
* :func:`graphical_kt` (run) -> dict            K, T by Nomoto's standard test method
* :func:`integral_kt` (run) -> dict             K, T by least squares on the integrated model
* :func:`indices_with_uncertainty` (params, cov) -> {name: {"value", "std"}}   Eq. 6 + propagation
* :func:`imo_check` (kind, metrics, meta) -> dict
* :func:`build` (index, runs, estimates) -> the stage's three outputs as written
* :func:`build_documents` (index, runs, estimates) -> the same as typed objects
  (:class:`IndicesDocument`, :class:`ZigzagDocument`, each with ``to_json``/``from_json``)
"""

from pipeline.config import IndicesConfig
from pipeline.indices.imo import imo_check, overshoot_limits
from pipeline.indices.nomoto_kt import graphical_kt, integral_kt
from pipeline.indices.result import IndicesDocument, ZigzagDocument
from pipeline.indices.stage import analyse_run, build, build_documents
from pipeline.indices.turning import turning_metrics
from pipeline.indices.uncertainty import (
    draw_validity,
    index_range_over_box,
    indices_with_uncertainty,
    monte_carlo,
    propagate,
    rounding_half_widths,
)
from pipeline.indices.zigzag import zigzag_metrics

__all__ = [
    "IndicesConfig", "IndicesDocument", "ZigzagDocument", "analyse_run", "build", "build_documents",
    "draw_validity", "graphical_kt", "imo_check",
    "index_range_over_box", "indices_with_uncertainty", "integral_kt", "monte_carlo", "overshoot_limits",
    "propagate",
    "rounding_half_widths", "turning_metrics", "zigzag_metrics",
]
