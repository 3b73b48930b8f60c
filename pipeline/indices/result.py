"""The indices stage's results as typed, frozen objects with their JSON form.

``indices/indices.json`` is an :class:`IndicesDocument`, ``indices/zigzag.json`` a
:class:`ZigzagDocument` (keys and units in docs/contract.md and docs/indices.md).  Each class has
``to_json()`` (the JSON-ready dict, keys in the order the files carry them: the field order of
:class:`pipeline.results.Result` unless the class writes its own) and
``from_json(doc)`` (its inverse: ``X.from_json(x.to_json()) == x``).  Trust flags, IMO criteria and
the per-run metrics stay plain mappings: their keys belong to :mod:`pipeline.indices.trust`,
:mod:`pipeline.indices.imo` and the metric functions.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from pipeline.model import INDEX_NAMES
from pipeline.results import Result

Flags = tuple[Mapping[str, Any], ...]


def _flags(items: Any) -> Flags:
    return tuple(dict(f) for f in (items or ()))


@dataclass(frozen=True)
class IndexValue(Result):
    """One index with its one-sigma uncertainty (K in 1/s, T's in s, primed ones dimensionless)."""

    value: float | None
    std: float | None

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> IndexValue:
        return cls(value=doc["value"], std=doc["std"])


@dataclass(frozen=True)
class UncertaintyCheck(Result):
    """The seeded Monte Carlo check of the Gaussian bounds of one algorithm's indices.

    ``invalid_fraction``: share of draws with no real positive time constants (second-order model);
    ``invalid_fraction_first_order``: share with no positive K, T; ``invalid_causes`` maps each
    cause to its share; ``percentiles`` maps an index to its 16/50/84 % percentiles (the index's
    unit).  The draws are N(estimate, covariance), ``samples`` of them from ``seed``.
    """

    samples: int
    seed: int
    invalid_fraction: float
    invalid_fraction_first_order: float
    invalid_causes: Mapping[str, float]
    percentiles: Mapping[str, tuple[float, float, float]]

    def to_json(self) -> dict[str, Any]:
        return {"samples": self.samples, "seed": self.seed, "invalid_fraction": self.invalid_fraction,
                "invalid_fraction_first_order": self.invalid_fraction_first_order,
                "invalid_causes": dict(self.invalid_causes),
                "percentiles_16_50_84": {n: list(p) for n, p in self.percentiles.items()}}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> UncertaintyCheck:
        return cls(samples=doc["samples"], seed=doc["seed"], invalid_fraction=doc["invalid_fraction"],
                   invalid_fraction_first_order=doc["invalid_fraction_first_order"],
                   invalid_causes=dict(doc["invalid_causes"]),
                   percentiles={n: tuple(p) for n, p in doc["percentiles_16_50_84"].items()})


@dataclass(frozen=True)
class Nondimensional(Result):
    """What the primed indices of one algorithm were made with (Lpp m, approach speed m/s)."""

    run_id: str | None
    lpp_m: float | None
    approach_speed_m_s: float | None

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Nondimensional:
        return cls(run_id=doc["run_id"], lpp_m=doc["lpp_m"], approach_speed_m_s=doc["approach_speed_m_s"])


@dataclass(frozen=True)
class KTRow(Result):
    """K (1/s) and T (s) of one zigzag by one K-T method ('standard' or 'integral').

    ``primes`` holds K' and T' (dimensionless, None where Lpp or U is unknown); ``K_std``,
    ``T_std`` (one sigma) and ``rudder_offset_deg`` exist for the integral method only.
    """

    run_id: str
    method: str
    K: float
    T: float
    test: str
    test_name: str | None
    first_side: str | None
    primes: Mapping[str, float | None]
    flags: Flags
    K_std: float | None = None
    T_std: float | None = None
    rudder_offset_deg: float | None = None

    def to_json(self) -> dict[str, Any]:
        out = {"run_id": self.run_id, "method": self.method, "K": self.K, "T": self.T, "test": self.test,
               "test_name": self.test_name, "first_side": self.first_side, **self.primes}
        if self.method == "integral":
            out.update({"K_std": self.K_std, "T_std": self.T_std,
                        "rudder_offset_deg": self.rudder_offset_deg})
        out["flags"] = [dict(f) for f in self.flags]
        return out

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> KTRow:
        fixed = {"run_id", "method", "K", "T", "test", "test_name", "first_side", "flags",
                 "K_std", "T_std", "rudder_offset_deg"}
        return cls(run_id=doc["run_id"], method=doc["method"], K=doc["K"], T=doc["T"], test=doc["test"],
                   test_name=doc["test_name"], first_side=doc["first_side"],
                   primes={k: v for k, v in doc.items() if k not in fixed}, flags=_flags(doc["flags"]),
                   K_std=doc.get("K_std"), T_std=doc.get("T_std"),
                   rudder_offset_deg=doc.get("rudder_offset_deg"))


@dataclass(frozen=True)
class AmplitudeMean(Result):
    """Mean K (1/s) and T (s) of one K-T method over the zigzags of one amplitude."""

    K_mean: float
    T_mean: float
    runs: int

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> AmplitudeMean:
        return cls(K_mean=doc["K_mean"], T_mean=doc["T_mean"], runs=doc["runs"])


@dataclass(frozen=True)
class GraphicalModel(Result):
    """The standard (graphical) method's K (1/s), T (s) on the reference zigzag, with K', T'."""

    source: str
    run_id: str
    K: float
    T: float
    primes: Mapping[str, float | None]
    flags: Flags

    def to_json(self) -> dict[str, Any]:
        return {"source": self.source, "run_id": self.run_id, "K": self.K, "T": self.T, **self.primes,
                "flags": [dict(f) for f in self.flags]}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> GraphicalModel:
        fixed = {"source", "run_id", "K", "T", "flags"}
        return cls(source=doc["source"], run_id=doc["run_id"], K=doc["K"], T=doc["T"],
                   primes={k: v for k, v in doc.items() if k not in fixed}, flags=_flags(doc["flags"]))


@dataclass(frozen=True)
class ControlModel(Result):
    """The indices the autopilot is designed from (K 1/s, T1 T2 T3 T s) and why.

    ``refused`` with its ``reason`` when no candidate is trustworthy (the indices shown are then
    those of the best identified set, and ``primes`` is empty).
    """

    source: str
    indices: Mapping[str, float]
    primes: Mapping[str, float | None]
    basis: str
    rejected: tuple[Mapping[str, Any], ...]
    flags: Flags
    second_order: Mapping[str, Any]
    refused: bool = False
    reason: str | None = None
    # the held-out decision (pipeline/indices/design_model.py): rule, both errors, the chosen model;
    # None when no held-out run was there to judge by (the choice then rests on the trust flags)
    design_model: Mapping[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"source": self.source}
        if self.refused:
            out.update({"refused": True, "reason": self.reason})
        out.update(self.indices)
        out.update(self.primes)
        out.update({"basis": self.basis, "rejected": [dict(r) for r in self.rejected],
                    "flags": [dict(f) for f in self.flags], "second_order": dict(self.second_order)})
        if self.design_model is not None:
            out["design_model"] = dict(self.design_model)
        return out

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> ControlModel:
        return cls(source=doc["source"], indices={n: doc[n] for n in INDEX_NAMES},
                   primes={k: v for k, v in doc.items() if k.endswith("_prime")}, basis=doc["basis"],
                   rejected=tuple(dict(r) for r in doc["rejected"]), flags=_flags(doc["flags"]),
                   second_order=dict(doc["second_order"]), refused=bool(doc.get("refused", False)),
                   reason=doc.get("reason"), design_model=doc.get("design_model"))


@dataclass(frozen=True)
class IndicesDocument(Result):
    """``indices/indices.json``: identified indices with uncertainty, K-T by the graphical and
    integral methods, the control model and the paper's figures (units in ``units``)."""

    dataset: str | None
    provenance: str | None
    builtin_tank: bool
    identification_run: str
    identified: Mapping[str, Mapping[str, IndexValue]]
    identified_flags: Mapping[str, Flags]
    nondimensional: Mapping[str, Nondimensional]
    uncertainty_method: Mapping[str, str]
    uncertainty_check: Mapping[str, UncertaintyCheck | None]
    identified_failures: Mapping[str, str]
    graphical: tuple[KTRow, ...]
    graphical_by_amplitude: Mapping[str, Mapping[str, AmplitudeMean]]
    control_model: ControlModel
    graphical_model: GraphicalModel
    paper: Mapping[str, Any]
    units: Mapping[str, str]
    nondimensional_definition: str

    def to_json(self) -> dict[str, Any]:
        return {
            "dataset": self.dataset, "provenance": self.provenance, "builtin_tank": self.builtin_tank,
            "identification_run": self.identification_run,
            "identified": {a: {n: v.to_json() for n, v in d.items()} for a, d in self.identified.items()},
            "identified_flags": {a: [dict(f) for f in fl] for a, fl in self.identified_flags.items()},
            "nondimensional": {a: v.to_json() for a, v in self.nondimensional.items()},
            "uncertainty_method": dict(self.uncertainty_method),
            "uncertainty_check": {a: None if c is None else c.to_json()
                                  for a, c in self.uncertainty_check.items()},
            "identified_failures": dict(self.identified_failures),
            "graphical": [g.to_json() for g in self.graphical],
            "graphical_by_amplitude": {a: {m: v.to_json() for m, v in d.items()}
                                       for a, d in self.graphical_by_amplitude.items()},
            "control_model": self.control_model.to_json(),
            "graphical_model": self.graphical_model.to_json(),
            "paper": dict(self.paper), "units": dict(self.units),
            "nondimensional_definition": self.nondimensional_definition,
        }

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> IndicesDocument:
        return cls(
            dataset=doc["dataset"], provenance=doc["provenance"], builtin_tank=doc["builtin_tank"],
            identification_run=doc["identification_run"],
            identified={a: {n: IndexValue.from_json(v) for n, v in d.items()}
                        for a, d in doc["identified"].items()},
            identified_flags={a: _flags(fl) for a, fl in doc["identified_flags"].items()},
            nondimensional={a: Nondimensional.from_json(v) for a, v in doc["nondimensional"].items()},
            uncertainty_method=dict(doc["uncertainty_method"]),
            uncertainty_check={a: None if c is None else UncertaintyCheck.from_json(c)
                               for a, c in doc["uncertainty_check"].items()},
            identified_failures=dict(doc["identified_failures"]),
            graphical=tuple(KTRow.from_json(g) for g in doc["graphical"]),
            graphical_by_amplitude={a: {m: AmplitudeMean.from_json(v) for m, v in d.items()}
                                    for a, d in doc["graphical_by_amplitude"].items()},
            control_model=ControlModel.from_json(doc["control_model"]),
            graphical_model=GraphicalModel.from_json(doc["graphical_model"]),
            paper=dict(doc["paper"]), units=dict(doc["units"]),
            nondimensional_definition=doc["nondimensional_definition"])


@dataclass(frozen=True)
class RunMetrics(Result):
    """One run's entry in ``indices/zigzag.json``: its kind ('zigzag', 'turning', other), the
    metrics (keys and units of :mod:`pipeline.indices.zigzag` / :mod:`pipeline.indices.turning`,
    None when they could not be computed), the IMO check and what failed and why."""

    run_id: str
    test_name: str | None
    kind: str
    metrics: Mapping[str, Any] | None
    imo: Mapping[str, Any] | None
    errors: tuple[str, ...]

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> RunMetrics:
        return cls(run_id=doc["run_id"], test_name=doc["test_name"], kind=doc["kind"],
                   metrics=doc["metrics"], imo=doc["imo"], errors=tuple(doc["errors"]))


@dataclass(frozen=True)
class ZigzagDocument(Result):
    """``indices/zigzag.json``: the manoeuvre metrics and IMO check of every run."""

    dataset: str | None
    provenance: str | None
    runs: tuple[RunMetrics, ...]

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> ZigzagDocument:
        return cls(dataset=doc["dataset"], provenance=doc["provenance"],
                   runs=tuple(RunMetrics.from_json(r) for r in doc["runs"]))
