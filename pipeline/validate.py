"""Validation of identified models on held-out data (docs/identification.md#validation): one-step and
free-run.

Data: the rest of the identification run after the identification window (segment
'identification-rest', the paper's Table 5) and every other zigzag run chosen by
:func:`pipeline.runinfo.choose_runs` (segment 'held-out'; the 10/10 one is the paper's Table 6).

Definitions (units of docs/contract.md#run-data: v m/s, r deg/s, psi deg):

* **one-step** (online, what the paper's Tables 5 and 6 report): the identifying filter (the same
  algorithm, settings and fuzzy forgetting) keeps running over the validation samples, parameters
  still adapting, and the prior prediction of each sample (time update from the posterior at the
  previous sample with the previous rudder) is compared with the measurement.  On the
  identification run it continues from the final posterior (state and covariance) of the window.
  On a held-out run it starts at the run's first sample: v, r, psi from that sample (v = 0 when
  the run has no v) with one-sigma r_std (v0_std for an unmeasured v), the parameters and their
  covariance from the identification, cross-covariance zero.  Scored on every sample after the start.
* **free-run** (simulation, the honest test): pipeline.model.simulate with the identified
  parameters from the measured state at the start of the segment, driven by the measured rudder
  alone; scored on every sample after the start.  On the identification run the start is the first
  sample after the window (its v is the filter's estimate there when the run has no v); on held-out
  runs the first sample (v = 0 when absent: the runs start from a straight approach).

Metrics: MSE of v (null when the run has no v), MSE of r, MAE of psi, number of samples.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from pipeline import paper
from pipeline.catalog import data_label, is_builtin_tank
from pipeline.config import FilterConfig
from pipeline.errors import InputError
from pipeline.identify.core import _arrays, measured_indices, run_filter
from pipeline.io import Run
from pipeline.model import PARAM_NAMES, simulate
from pipeline.results import Result, spread

#: The paper's Tables 5 and 6 (one-step online prediction; docs/results.md).
PAPER_TABLES = paper.TABLES_5_6

#: What the two validation modes mean and the units of the scores (``definitions`` of metrics.json).
DEFINITIONS = {
    "one-step": "prior prediction of each sample by the identifying filter continued over the "
                "validation data (parameters still adapting); identification run: from the "
                "window's final posterior; held-out runs: states from their first sample, "
                "parameters and covariance from the identification",
    "free-run": "pipeline.model.simulate with the identified parameters from the measured "
                "initial state, driven by the measured rudder alone",
    "units": "mse_v (m/s)^2, mse_r (deg/s)^2, mae_psi deg"}


@dataclass(frozen=True)
class ValidationRow(Result):
    """The scores of one algorithm on one segment of one run in one mode.

    ``segment`` is 'identification-rest' or 'held-out', ``mode`` 'one-step' or 'free-run';
    ``mse_v`` (m/s)^2 (None when the run has no v), ``mse_r`` (deg/s)^2, ``mae_psi`` deg over
    ``samples`` scored samples.
    """

    algorithm: str
    run_id: str
    segment: str
    mode: str
    test_name: str | None
    mse_v: float | None
    mse_r: float
    mae_psi: float
    samples: int

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> ValidationRow:
        return cls(**{k: doc[k] for k in cls.__dataclass_fields__})


@dataclass(frozen=True)
class ValidationMetrics(Result):
    """``validate/metrics.json``: every row's scores, the paper's Tables 5 and 6, the definitions,
    the identify-side trust flags of each algorithm's estimates and the data label
    (:func:`pipeline.catalog.data_label`: what simulated data the scores come from)."""

    dataset: str | None
    provenance: str | None
    ident_run: str
    validation_runs: tuple[str, ...]
    rows: tuple[ValidationRow, ...]
    paper: Mapping[str, Any]
    definitions: Mapping[str, str]
    flags: Mapping[str, tuple[Mapping[str, Any], ...]]
    label: Mapping[str, str] = spread()

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> ValidationMetrics:
        fixed = {"dataset", "provenance", "ident_run", "validation_runs", "rows", "paper", "definitions",
                 "flags"}
        return cls(dataset=doc["dataset"], provenance=doc["provenance"], ident_run=doc["ident_run"],
                   validation_runs=tuple(doc["validation_runs"]),
                   rows=tuple(ValidationRow.from_json(r) for r in doc["rows"]), paper=doc["paper"],
                   definitions=dict(doc["definitions"]),
                   flags={a: tuple(dict(f) for f in fl) for a, fl in doc["flags"].items()},
                   label={k: v for k, v in doc.items() if k not in fixed})


def metrics_document(dataset: str | None, index: Mapping[str, Any], *, ident_run: str,
                     validation_runs: list[str], rows: list[dict[str, Any]],
                     flags: Mapping[str, list[dict[str, Any]]]) -> ValidationMetrics:
    """The validate stage's metrics.json as a typed object.

    Parameters
    ----------
    dataset : str or None
        The dataset's name.
    index : mapping
        runs/index.json (its "provenance" and what :func:`pipeline.catalog.is_builtin_tank` reads).
    ident_run : str
        The identification run's id.
    validation_runs : list of str
        The held-out runs' ids.
    rows : list of dict
        The metric rows of :func:`validate`.
    flags : mapping
        Algorithm -> the identify-side trust flags of its estimates.

    Returns
    -------
    ValidationMetrics
        ``to_json()`` is the content of validate/metrics.json.
    """
    return ValidationMetrics(
        dataset=dataset, provenance=index.get("provenance"), ident_run=ident_run,
        validation_runs=tuple(validation_runs), rows=tuple(ValidationRow.from_json(r) for r in rows),
        paper=PAPER_TABLES, definitions=DEFINITIONS, flags={a: tuple(f) for a, f in flags.items()},
        label=data_label(is_builtin_tank(index), index.get("provenance")))


def scores(meas: np.ndarray, pred: np.ndarray) -> dict[str, Any]:
    """The validation scores of predictions against measurements.

    Parameters
    ----------
    meas, pred : numpy.ndarray
        (n, 3) arrays of v (m/s), r (deg/s), psi (deg); v may be NaN (not measured).

    Returns
    -------
    dict
        {"mse_v" ((m/s)^2, None when v is not measured), "mse_r" ((deg/s)^2), "mae_psi" (deg),
        "samples"}.

    Examples
    --------
    A prediction 1 deg off in heading and 0.5 deg/s in yaw rate, v not measured:

    >>> meas = np.array([[np.nan, 1.0, 10.0], [np.nan, 2.0, 11.0]])
    >>> pred = meas + [0.0, 0.5, 1.0]
    >>> scores(meas, pred)
    {'mse_v': None, 'mse_r': 0.25, 'mae_psi': 1.0, 'samples': 2}
    """
    err = pred - meas
    v_ok = np.all(np.isfinite(err[:, 0])) and len(err) > 0
    return {"mse_v": float(np.mean(err[:, 0] ** 2)) if v_ok else None,
            "mse_r": float(np.mean(err[:, 1] ** 2)),
            "mae_psi": float(np.mean(np.abs(err[:, 2]))),
            "samples": int(len(err))}


def _theta(est: dict[str, Any]) -> np.ndarray:
    try:
        return np.array([float(est["parameters"][p]) for p in PARAM_NAMES])
    except (KeyError, TypeError) as exc:
        raise InputError(f"estimates have no parameter {exc}") from None


def one_step(est: dict[str, Any], run: Run, *, cfg: FilterConfig | None = None, start: int = 0,
             continue_state: bool = False) -> np.ndarray:
    """One-step (online) predictions of v, r, psi for samples start+1 .. end (module docstring).

    Parameters
    ----------
    est : dict
        An estimates.json document ("algorithm", "parameters", "filter_state").
    run : Run
        The run validated on.
    cfg : FilterConfig, optional
        The identifying filter's settings (R, v0_std).
    start : int
        The sample the prediction starts from.
    continue_state : bool
        True: start from the estimates' final filter posterior (identification run, ``start`` the
        last window sample); False: restart the states from sample ``start``.

    Returns
    -------
    numpy.ndarray
        (n - start - 1, 3): predicted v (m/s), r (deg/s), psi (deg).
    """
    cfg = cfg or FilterConfig()
    _, d, Y3 = _arrays(run)
    h = run.dt
    alg = est["algorithm"]
    meas_idx = measured_indices(Y3[:, 0])
    fs = est.get("filter_state") or {}
    if "x" not in fs or "P" not in fs:
        raise InputError("estimates have no filter_state (re-run identify)")
    x0 = np.array(fs["x"], float)
    P_full = np.array(fs["P"], float)
    if not continue_state:
        P0 = np.zeros((9, 9))
        P0[3:, 3:] = P_full[3:, 3:]
        for i in range(3):
            if i in list(meas_idx):
                x0[i], P0[i, i] = Y3[start, i], cfg.r_std[i] ** 2
            else:
                x0[i], P0[i, i] = 0.0, cfg.v0_std ** 2
    else:
        P0 = P_full
    out = run_filter(alg, x0, P0, Y3[start + 1:], d[start:-1], h=h, cfg=cfg, meas_idx=meas_idx)
    return out.x_prior[:, :3]


def free_run(est: dict[str, Any], run: Run, *, start: int = 0, v_start: float | None = None) -> np.ndarray:
    """Free-run simulation from the measured state at ``start``, driven by the measured rudder.

    Parameters
    ----------
    est : dict
        An estimates.json document ("parameters": a11 a12 a21 a22 1/s, b11 b21 1/s^2).
    run : Run
        The run (time s, v m/s, r deg/s, psi deg, delta deg).
    start : int
        The starting sample.
    v_start : float, optional
        v at the start (m/s) when the run has no v (default 0: a straight approach).

    Returns
    -------
    numpy.ndarray
        Rows start+1 .. end of the simulated v (m/s), r (deg/s), psi (deg).

    Examples
    --------
    The paper's Table 4 model run free over a zigzag simulated from that very model (noise-free)
    follows it exactly:

    >>> from pipeline.identify.synthetic import zigzag_run
    >>> from pipeline.model import PAPER_TABLE4
    >>> run = zigzag_run("zz", n=300, noise=(0.0, 0.0, 0.0))
    >>> sim = free_run({"parameters": PAPER_TABLE4}, run)
    >>> meas = np.column_stack([run.col("v"), run.col("r"), run.col("psi")])[1:]
    >>> sim.shape, scores(meas, sim)["mae_psi"] < 1e-9
    ((299, 3), True)
    """
    _, d, Y3 = _arrays(run)
    x0 = Y3[start].copy()
    if not np.isfinite(x0[0]):
        x0[0] = 0.0 if v_start is None else v_start
    sim = simulate(_theta(est), x0, d[start:], run.dt)
    return sim[1:]


def validate(estimates: dict[str, dict[str, Any]], ident_run: Run, held_out: list[Run],
             cfg: FilterConfig | None = None) -> tuple[list[dict[str, Any]], pd.DataFrame]:
    """Score every algorithm's estimates on the identification rest and the held-out runs.

    Parameters
    ----------
    estimates : dict
        Algorithm -> estimates.json content.
    ident_run : Run
        The identification run (its samples after the window are the 'identification-rest').
    held_out : list of Run
        The held-out runs.
    cfg : FilterConfig, optional
        The identifying filter's settings for the one-step predictions.

    Returns
    -------
    list of dict, pandas.DataFrame
        The metric rows (:class:`ValidationRow` keys: mse_v (m/s)^2, mse_r (deg/s)^2, mae_psi deg) and
        the predictions in the long format of pipeline/catalog.py.
    """
    cfg = cfg or FilterConfig()
    rows: list[dict[str, Any]] = []
    frames: list[pd.DataFrame] = []
    for alg, est in estimates.items():
        n_id = int(est["samples"])
        segments = []
        if len(ident_run.frame) > n_id + 1:
            segments.append(("identification-rest", ident_run, n_id - 1, True))
        segments += [("held-out", run, 0, False) for run in held_out]
        for segment, run, start, cont in segments:
            t, d, Y3 = _arrays(run)
            meas = Y3[start + 1:]
            v_start = float(est["filter_state"]["x"][0]) if cont else None
            osa = one_step(est, run, cfg=cfg, start=start, continue_state=cont)       # rows start+1 ..
            if cont:
                # free-run starts at the first validation sample (start+1): that row is the
                # initial state itself, shown in the predictions but not scored
                fr = free_run(est, run, start=start + 1, v_start=v_start)
                first = Y3[start + 1].copy()
                first[0] = first[0] if np.isfinite(first[0]) else v_start
                fr_rows = np.vstack([first, fr])
                fr_score = scores(meas[1:], fr)
            else:
                fr_rows = free_run(est, run, start=0)
                fr_score = scores(meas, fr_rows)
            for mode, pred, s in (("one-step", osa, scores(meas, osa)), ("free-run", fr_rows, fr_score)):
                rows.append({"algorithm": alg, "run_id": run.name, "segment": segment, "mode": mode,
                             "test_name": run.meta.get("test_name"), **s})
                frames.append(pd.DataFrame({
                    "algorithm": alg, "run_id": run.name, "segment": segment, "mode": mode,
                    "time": t[start + 1:], "delta": d[start + 1:], "v": meas[:, 0], "r": meas[:, 1],
                    "psi": meas[:, 2], "v_pred": pred[:, 0], "r_pred": pred[:, 1], "psi_pred": pred[:, 2]}))
    pred_frame = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    return rows, pred_frame
