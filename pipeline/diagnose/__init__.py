"""Diagnosis stage (SPEC section 7): what the linear model gets wrong, the named cause, the gain.

Public API: :func:`diagnose` (pure: runs in, :class:`Diagnosis` out), :func:`simulate_extended`,
:func:`fit_model`, the linear truth model :func:`zigzag_truth` for tests, :func:`write_outputs`.
"""

from pipeline.diagnose.core import Diagnosis, diagnose, residual_structure
from pipeline.diagnose.extended import EFFECT_PARAM, EFFECTS, simulate_extended
from pipeline.diagnose.fit import FitResult, Series, evaluate, fit_model, series_from_run
from pipeline.diagnose.truth import TruthConfig, zigzag_truth

__all__ = [
    "Diagnosis",
    "diagnose",
    "residual_structure",
    "EFFECT_PARAM",
    "EFFECTS",
    "simulate_extended",
    "FitResult",
    "Series",
    "evaluate",
    "fit_model",
    "series_from_run",
    "TruthConfig",
    "zigzag_truth",
]
