"""Online identification of the sway-yaw model: SR-UKF-FFM (ours) and the filterpy FFM-UKF baseline.

Public API: :func:`identify_run`, :func:`identify_arrays`, :func:`identify_batch`, :func:`run_filter`,
:func:`estimates` (the typed :class:`Estimates`) and :func:`estimates_json`; the filters themselves
in :mod:`.srukf` (numpy reference), :mod:`.fast` (numba kernel), :mod:`.baseline` (filterpy); the
fuzzy factor in :mod:`.fuzzy`; synthetic test data in :mod:`.synthetic`.
"""

from pipeline.identify.core import (
    ALGORITHMS,
    Estimates,
    FilterOutput,
    Identification,
    estimates,
    estimates_json,
    identify_arrays,
    identify_batch,
    identify_run,
    initial_state,
    measured_indices,
    run_filter,
)

__all__ = ["ALGORITHMS", "Estimates", "FilterOutput", "Identification", "estimates", "estimates_json",
           "identify_arrays", "identify_batch", "identify_run", "initial_state", "measured_indices",
           "run_filter"]
