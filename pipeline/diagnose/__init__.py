"""Diagnosis stage (docs/diagnosis.md): what the linear model gets wrong, the named cause, the gain.

Public API: :func:`diagnose` (pure: runs in, :class:`Diagnosis` out), the open effect catalogue
:data:`CATALOGUE` (pipeline.diagnose.effects), :func:`simulate_extended`, :func:`fit_structure`,
the linear truth model :func:`zigzag_truth` for tests, :func:`write_outputs` (in .output).
"""

from pipeline.diagnose.core import Diagnosis, diagnose, residual_structure
from pipeline.diagnose.effects import BY_NAME, CATALOGUE
from pipeline.diagnose.extended import simulate_extended, simulate_terms
from pipeline.diagnose.fit import FitResult, Series, evaluate, fit_structure, series_from_run
from pipeline.diagnose.truth import TruthConfig, zigzag_truth

EFFECTS = tuple(e.name for e in CATALOGUE)

__all__ = [
    "Diagnosis",
    "diagnose",
    "residual_structure",
    "BY_NAME",
    "CATALOGUE",
    "EFFECTS",
    "simulate_extended",
    "simulate_terms",
    "FitResult",
    "Series",
    "evaluate",
    "fit_structure",
    "series_from_run",
    "TruthConfig",
    "zigzag_truth",
]
