"""Studies at scale on Dask: many cases of one kind fanned out over worker processes.

A study kind is a small object (:class:`pipeline.study.kind.StudyKind`) in its own module, registered
in :data:`KIND_MODULES` below: adding a kind is one new file, its line here and its test.  The engine
(:mod:`.engine`) runs any kind the same way: per-case seeds from the spec, per-case result files for
resuming, one Parquet table and one summary written atomically.

Public API: :func:`load_spec`, :func:`run_study`, :func:`get_kind`, :data:`KIND_MODULES`.
"""

from __future__ import annotations

import importlib

#: The registered study kinds: module names inside this package, each defining ``KIND``.
KIND_MODULES = ("detection_power", "autopilot_monte_carlo", "batch_identify")


def get_kind(name: str):
    """The registered study kind called ``name``.

    Parameters
    ----------
    name : str
        A kind's name (a ``[study] kind`` of a spec), e.g. ``"detection_power"``.

    Returns
    -------
    StudyKind
        Its :class:`~pipeline.study.kind.StudyKind`.

    Raises
    ------
    InputError
        No kind of that name.
    """
    from pipeline.errors import InputError

    for mod in KIND_MODULES:
        kind = importlib.import_module(f"{__name__}.{mod}").KIND
        if kind.name == name:
            return kind
    raise InputError(f"unknown study kind {name!r} (known: {', '.join(KIND_MODULES)})")


def kinds() -> list:
    """Every registered study kind.

    Returns
    -------
    list of StudyKind
        In registration order (:data:`KIND_MODULES`).
    """
    return [importlib.import_module(f"{__name__}.{mod}").KIND for mod in KIND_MODULES]


from pipeline.study.engine import run_study  # noqa: E402
from pipeline.study.spec import Spec, load_spec  # noqa: E402

__all__ = ["KIND_MODULES", "Spec", "get_kind", "kinds", "load_spec", "run_study"]
