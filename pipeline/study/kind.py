"""What a study kind provides to the engine (one small object per kind, in its own module)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd


@dataclass(frozen=True)
class StudyKind:
    """A kind of study.

    name : the ``kind`` of ``[study]`` and the name of its settings table in the spec.
    config : the kind's frozen settings dataclass (in :mod:`pipeline.config`).
    cases : settings -> list of case parameter dicts (JSON scalars only); their keys become columns
        of results.parquet.  Called on the client.
    run_case : (params, seed, settings) -> dict of scalar results; runs on a worker.  ``seed`` is the
        case's own seed (from the study seed and the case's parameters, never from scheduling).
        Raise on failure: the engine records the error and carries on.
    summarise : (results frame sorted by case_id, settings, study seed) -> summary dict (JSON).
    render : optional (results frame, summary, output dir) -> None, writes figures / HTML atomically.
    warm : optional (settings) -> None, compiles the numba kernels a case uses (once per worker).
    check : optional (settings) -> None, refuses settings no case could run with (a negative duration,
        an effect name the catalogue has not) by raising :class:`pipeline.errors.InputError` whose
        message starts with ``key '<table>.<key>'``; called when the spec is read, before any work.
    summary_only : settings fields that only change the summary (not the cases' results); they are
        left out of the case fingerprint, so changing them reuses the done cases.
    grid : settings fields that only say which cases exist (ranges, seed counts); every case's
        parameters carry its own values, so these are left out of the fingerprint too: extending a
        study's ranges keeps the cases already done.
    """

    name: str
    config: type
    cases: Callable[[Any], list[dict[str, Any]]]
    run_case: Callable[[dict[str, Any], int, Any], dict[str, Any]]
    summarise: Callable[[pd.DataFrame, Any, int], dict[str, Any]]
    render: Callable[[pd.DataFrame, dict[str, Any], Path], None] | None = None
    warm: Callable[[Any], None] | None = None
    check: Callable[[Any], None] | None = None
    summary_only: tuple[str, ...] = field(default_factory=tuple)
    grid: tuple[str, ...] = field(default_factory=tuple)
