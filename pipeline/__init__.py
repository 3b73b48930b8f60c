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
