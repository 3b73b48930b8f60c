"""Tank-test analysis pipeline.

Stages (each a subpackage or module of pure functions; the command line lives in
:mod:`pipeline.cli`): ``tank`` (virtual KCS tank), ``ingest``, ``identify``, ``validate``,
``indices``, ``control``, ``diagnose``, ``report``.

Units and signs follow docs/contract.md#run-data: time s, positions m, u and v m/s (v positive to
starboard), psi deg (continuous, from x0 toward y0), r deg/s (= d psi/dt), delta deg (positive
delta gives positive r), rpm 1/min.  Degrees are used at the edges; functions that need radians
convert with :mod:`pipeline.units`.
"""

__version__ = "0.1.0"

__all__ = ["StageResult", "run", "stages"]


def __getattr__(name: str):
    """``pipeline.run``, ``pipeline.stages``, ``pipeline.StageResult``: the Python API
    (:mod:`pipeline.api`, docs/api.md), imported when first used, so that importing one stage's
    package does not import the command line."""
    if name in __all__:
        import importlib

        return getattr(importlib.import_module("pipeline.api"), name)
    raise AttributeError(f"module 'pipeline' has no attribute {name!r}")
