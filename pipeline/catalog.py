"""Named datasets: where each stage reads and writes (Kedro's idea, without its weight).

A *dataset* is one collection of runs (``virtual`` for the built-in tank, ``hsva`` for the measured
KVLCC2 zigzags, or any name a user gives their own folder).  Everything a stage makes for it lives
under ``data/processed/<dataset>/<stage>/``.

The contracts between stages (what each file holds, in full in docs/contract.md#output-files; JSON
written with :func:`pipeline.io.write_json`, Parquet with :func:`pipeline.io.write_frame`, both
atomic):

``runs/<run_id>.parquet``  processed run, docs/contract.md#run-data (``pipeline.io.Run``).
``runs/index.json``        ``{"dataset", "provenance": "virtual"|"measured"|"mixed", "ship", "roles",
                           "runs": [entry...]}``; ``ship`` (when the dataset has a description,
                           pipeline.dataset.Dataset.particulars): ship, lpp_m, beam_m, draught_m,
                           design_speed_kn (full scale), scale, model_scale, lpp_model_m, tank, source,
                           dataset_toml; ``roles``: identify, train, validate, test (run ids);
                           entry = ``{"run_id", "file"}`` + the run's metadata (source_file, source_sha256,
                           source_format, provenance, test_name, kind, rudder_deg, heading_deg, first_side,
                           dt, original_dt, scale_factor, duration, samples, ship, lpp (model, m),
                           lpp_source, froude_number, rudder_sign, ingest_notes, the particulars, ...).
Every stage directory is written as one set (pipeline.io.atomic_dir); its manifest is
``.<dir>.set.json`` beside it.
``identify/<alg>/estimates.json``  the model's parameters, covariance, indices, ``run_id``, ``dataset``,
                           ``provenance``, settings, consistency, flags.
``identify/<alg>/trace.parquet``   per step: time, delta, v, r, psi (measured); v_pred, r_pred, psi_pred
                           (one-step prediction made before the sample); v_est, r_est, psi_est (posterior);
                           a11..b21 and a11_std..b21_std; f (forgetting factor); innov_v, innov_r, innov_psi;
                           nis (normalised innovation squared).
``validate/metrics.json``  ``{"dataset", "provenance", "ident_run", "rows": [{"algorithm", "run_id",
                           "segment": "identification-rest"|"held-out", "mode": "one-step"|"free-run",
                           "mse_v", "mse_r", "mae_psi", "samples"}], "paper": {...}}``.
``validate/predictions.parquet``   long format: algorithm, run_id, mode, time, delta, v, r, psi, v_pred,
                           r_pred, psi_pred.
``indices/indices.json``   ``{"dataset", "provenance", "identified": {alg: {"K": {"value", "std"}, ...}},
                           "graphical": [{"run_id", "method": "standard"|"integral", "K", "T", ...}],
                           "control_model": {"source", "K", "T1", "T2", "T3", "T"},
                           "graphical_model": {"source", "K", "T"}, "paper": {...}}``.
``indices/zigzag.json``    per run: ITTC zigzag or turning metrics and the IMO check.
``control/metrics.json``   design (gains, margins, bandwidth, sensitivity peak) and per (plant, design)
                           statistics over wave seeds (mean, std, worst), with the paper's figures.
``control/timeseries.parquet``     plant, design, seed, time, psi_ref, psi, r, delta_cmd, delta, wave, wind.
``diagnose/diagnosis.json``        docs/diagnosis.md; ``diagnose/series.parquet`` measured/baseline/extended
                           free-run series per validation run; ``diagnose/test_series.parquet`` the same
                           per test run (models refitted on all selection runs; only with test runs);
                           PNG plots beside them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

#: a file beside results saying how long something took (never a result: no stamp hashes it, no
#: report shows it, no rebuild compares it; docs/operations.md, "Timings and byte-identical rebuilds")
TIMING_FILE = "timing.json"


@dataclass(frozen=True)
class Catalog:
    root: Path = Path("data/processed")
    dataset: str = "virtual"

    @property
    def base(self) -> Path:
        return Path(self.root) / self.dataset

    # ingest
    @property
    def runs_dir(self) -> Path:
        return self.base / "runs"                       # <run_id>.parquet, one per run

    @property
    def runs_index(self) -> Path:
        return self.runs_dir / "index.json"             # list of runs with their metadata

    # identify
    def identify_dir(self, algorithm: str) -> Path:
        return self.base / "identify" / algorithm       # estimates.json, trace.parquet

    # validate
    @property
    def validate_dir(self) -> Path:
        return self.base / "validate"                   # metrics.json, predictions_*.parquet

    @property
    def indices_dir(self) -> Path:
        return self.base / "indices"                    # indices.json, zigzag.json, table7.csv

    @property
    def control_dir(self) -> Path:
        return self.base / "control"                    # metrics.json, timeseries.parquet

    @property
    def diagnose_dir(self) -> Path:
        return self.base / "diagnose"                   # diagnosis.json, plots

    @property
    def raw_dir_default(self) -> Path:
        return Path("data/raw") / self.dataset


#: how the built-in tank's CSV files begin their ``# note:`` (pipeline/tank/simulate.py NOTE)
TANK_NOTE_PREFIX = "virtual tank (MMG model of the KCS"


def is_builtin_tank_run(meta: dict) -> bool:
    """Whether a run is the built-in virtual tank's.

    Provenance virtual, the KCS or no ship named, and no file note other than the tank's own.  A
    user's simulator writing "provenance: virtual" (or a dataset.toml declaring it) makes simulated
    data, but not this tank's: its ship is not the KCS the tank's plant and words describe.

    Parameters
    ----------
    meta : dict
        The run's metadata, or its entry of ``runs/index.json``.

    Returns
    -------
    bool
    """
    if meta.get("provenance") != "virtual":
        return False
    header = meta.get("header")
    note = str((header or {}).get("note") or "") if isinstance(header, dict) else ""
    return meta.get("ship") in (None, "KCS") and (not note or note.startswith(TANK_NOTE_PREFIX))


def is_builtin_tank(index: dict) -> bool:
    """Whether a dataset is the built-in virtual tank's.

    Parameters
    ----------
    index : dict
        The dataset's ``runs/index.json``.

    Returns
    -------
    bool
        True when its provenance is virtual, at least one run is listed and every run is the tank's
        (:func:`is_builtin_tank_run`).
    """
    runs = index.get("runs") or []
    return index.get("provenance") == "virtual" and bool(runs) and all(is_builtin_tank_run(r) for r in runs)


def data_label(builtin_tank: bool, provenance: str | None) -> dict[str, str]:
    """What a stage output made from simulated runs says about them.

    Parameters
    ----------
    builtin_tank : bool
        The data are the built-in tank's (:func:`is_builtin_tank`).
    provenance : str or None
        The dataset's provenance ('virtual' for simulated data).

    Returns
    -------
    dict
        ``{"virtual_tank": ...}`` for the built-in tank's, ``{"simulated": ...}`` for a user's
        simulated runs, ``{}`` for measured ones.
    """
    if builtin_tank:
        return {"virtual_tank": "made from virtual-tank (simulated KCS) data, not from measurements"}
    if provenance == "virtual":
        return {"simulated": "made from simulated data (provenance virtual), not from measurements"}
    return {}
