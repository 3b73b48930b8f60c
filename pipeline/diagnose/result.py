"""The diagnosis's result as typed, frozen objects with their JSON form (docs/diagnosis.md).

``diagnosis.json`` is a :class:`DiagnosisReport`; its blocks are the objects below, each deriving
from :class:`pipeline.results.Result` so that its fields, in declaration order, are the file's keys in
the file's order.  The blocks whose keys belong to the functions that make them stay plain mappings:
the validation summaries and per-run rows (:func:`pipeline.diagnose.fit.evaluate`) and the residual
structure (:func:`pipeline.diagnose.core.residual_structure`).

Units: heading errors (MAE psi) in deg, relative gains and reductions as fractions (0.25 = 25 % cut,
positive = the extended model is better), times in s, speeds in m/s; parameters in the units of
docs/contract.md.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from pipeline.diagnose.gates import GateResult
from pipeline.results import Result, optional


@dataclass(frozen=True)
class UnjudgedFinding(Result):
    """``findings[]`` of an effect not judged (not tried, or its fit failed): nothing is claimed;
    ``evidence`` says why, ``floor`` is the effect's physical floor in words."""

    effect: str
    significant: bool
    material: bool
    estimate: dict[str, float]
    uncertainty: dict[str, float]
    validation_gain: float | None
    validation_gain_folds: list[float] | None
    z: float | None
    physical: str
    floor: str
    evidence: str
    gates: list[GateResult] = field(default_factory=list)

    judged = False


@dataclass(frozen=True)
class Finding(Result):
    """``findings[]`` of a judged effect.

    ``significant``: named in the extended model; ``material``: its cut clears the floor; ``floor`` the
    floor in words; ``estimate`` / ``uncertainty`` its parameters (fold 0's fit of the structure last
    judged) and their standard deviations; ``profile`` the profile intervals of its time parameters
    (s; chosen effects only, else empty); ``z`` the smallest |estimate| / std; ``validation_gain*`` the
    relative held-out cuts (pooled and per fold), alone and in the extended model; ``abs_gain_deg`` the
    cut (deg); ``block_t`` / ``block_t_crit`` / ``blocks`` the one-sided block t-test; ``short_horizon_*``
    the same step from the measured state; ``hinges_on`` the training runs the step hinges on;
    ``judged`` the context of the step in words; ``folds`` per fold its estimate, gain and MAE psi
    (deg); ``rivals`` the candidates the runs could not tell from it; ``evidence`` the sentence made
    from ``gates`` (every criterion judged, :mod:`pipeline.diagnose.gates`)."""

    effect: str
    form: str
    significant: bool
    material: bool
    floor: str
    physical: str
    estimate: dict[str, float]
    uncertainty: dict[str, float]
    profile: dict[str, Any]
    z: float
    validation_gain: float
    validation_gain_folds: list[float]
    validation_gain_alone: float | None
    validation_gain_alone_folds: list[float] | None
    validation_gain_in_extended: float | None
    validation_gain_in_extended_folds: list[float] | None
    abs_gain_deg: float
    block_t: float
    block_t_crit: float
    blocks: int
    short_horizon_gain: float | None
    short_horizon_block_t: float | None
    hinges_on: list[str]
    judged: str
    folds: list[dict[str, Any]]
    rivals: list[dict[str, Any]]
    evidence: str
    gates: list[GateResult]


@dataclass(frozen=True)
class Signature(Result):
    """One effect signature the baseline's residual correlates with (``correlation``, -1..1)."""

    effect: str
    correlation: float


@dataclass(frozen=True)
class Adequacy(Result):
    """``baseline_adequacy``: whether the linear baseline's pooled held-out ``mae_psi_deg`` (deg) is
    within ``floors`` noise floors (``threshold_deg`` = floors x ``noise_floor_deg``, deg); ``reason``
    in words; ``signatures`` the strongest residual correlations (at most three)."""

    adequate: bool
    mae_psi_deg: float
    threshold_deg: float
    noise_floor_deg: float
    floors: float
    reason: str
    signatures: list[Signature]


@dataclass(frozen=True)
class Baseline(Result):
    """``baseline``: the reported linear fit (fold 0), its parameters and standard deviations, the
    parameters at a ship-sign bound, which linear fit it is (``sign_bounds``, ``best_linear_sign_bounds``,
    ``other_linear``, ``choice``), the a12 held where v is latent ((m/s^2)/(deg/s); None where v is
    measured), its held-out ``validation`` and ``per_run`` figures (deg) and its ``residuals``."""

    parameters: dict[str, float]
    uncertainty: dict[str, float]
    course_stable: bool
    at_sign_bound: list[str]
    sign_bounds: bool
    best_linear_sign_bounds: bool | None
    other_linear: dict[str, Any] | None
    choice: str
    latent_sway_a12: float | None
    validation: dict[str, Any]
    per_run: list[dict[str, Any]]
    residuals: dict[str, Any]


@dataclass(frozen=True)
class Extended(Result):
    """``extended``: the model kept (the baseline when no effect is named): its named ``effects``, the
    effects it ``carried`` without naming them (below their physical floor,
    ``DiagnoseConfig.reference_names_material_only``), the ``forms`` of both, parameters, standard
    deviations, ``effect_estimates`` (estimate, uncertainty, form per effect of the model), held-out
    figures (deg) and ``residuals``."""

    effects: list[str]
    forms: dict[str, str]
    parameters: dict[str, float]
    uncertainty: dict[str, float]
    effect_estimates: dict[str, Any]
    course_stable: bool
    at_sign_bound: list[str]
    validation: dict[str, Any]
    per_run: list[dict[str, Any]]
    residuals: dict[str, Any]
    carried: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class HeldOutSelection(Result):
    """``gain.nested[]``: one round of the nested leave-one-run-out: the selection repeated without the
    run ``measured_on`` (``fold`` names it), the ``effects`` and ``cause`` it chose on the runs
    ``chosen_on``, the baseline's and the chosen model's MAE psi on the held-out run (deg), the relative
    ``gain`` (0.25 = 25 % cut), whether that selection's baseline kept the ship-sign bounds, and the MAE
    psi of the linear fit it did not choose (deg; None where that fit failed)."""

    fold: str
    effects: list[str]
    cause: str | None
    chosen_on: list[str]
    measured_on: list[str]
    baseline_mae_psi_deg: float
    extended_mae_psi_deg: float
    gain: float
    baseline_sign_bounds: bool
    other_linear_mae_psi_deg: float | None
    #: the reference structure (``reference``) refitted on the same runs ``chosen_on`` and measured on
    #: the held-out run (deg); None where not made: the baseline within its noise floors there,
    #: DiagnoseConfig.reference_fit off, no hull term applicable, or its fit failed
    reference_mae_psi_deg: float | None = None
    #: the effects that round's model carried without naming them (``extended.carried``)
    carried: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class OtherLinearGain(Result):
    """``gain.against_other_linear``: the extended model against the linear fit not chosen as the
    baseline, on the same unseen runs: the relative cut and its bootstrap 95 % interval, both MAE psi
    (deg), and (where the other fit exists in every fold) the same cut on the selection's validation
    runs, a key left out otherwise."""

    mae_psi_relative_reduction: float
    interval_95: list[float] | None
    other_linear_mae_psi_deg: float
    extended_mae_psi_deg: float
    validation_mae_psi_relative_reduction: float | None = optional()


@dataclass(frozen=True, kw_only=True)
class Gain(Result):
    """``gain``: the honest gain, on runs no choice has seen (docs/diagnosis.md, "The honest gain").

    ``mae_psi_relative_reduction`` the relative cut of the pooled MAE psi (0.25 = 25 %; None where no
    run unseen by every choice exists) with its bootstrap 95 % ``interval_95`` over blocks of the unseen
    runs, the runs it was ``measured_on`` and the ``method`` in words.  Where measured, the baseline's
    and the extended model's pooled MAE psi (deg) and the ``per_run`` rows; these three keys are left out
    where it is not.  ``nested`` the nested leave-one-run-out's rounds (empty with --test runs),
    ``against_other_linear`` the same cut against the linear fit not chosen, ``flag`` the reason a
    reader should not take the figure at face value (None: none), and the cut on the selection's own
    validation runs (optimistic: chosen on them)."""

    mae_psi_relative_reduction: float | None
    interval_95: list[float] | None
    measured_on: list[str]
    method: str
    baseline_mae_psi_deg: float | None = optional()
    extended_mae_psi_deg: float | None = optional()
    per_run: list[dict[str, Any]] | None = optional()
    nested: list[HeldOutSelection]
    against_other_linear: OtherLinearGain | None
    flag: str | None = None
    validation_mae_psi_relative_reduction: float | None = None

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Gain:
        """The gain block from its JSON form; the inverse of :meth:`to_json`."""
        other = doc["against_other_linear"]
        return super().from_json({
            **doc,
            "nested": [HeldOutSelection.from_json(n) for n in doc["nested"]],
            "against_other_linear": None if other is None else OtherLinearGain.from_json(other),
        })


@dataclass(frozen=True)
class ReferenceFold(Result):
    """``reference.per_fold[]``: one fold's validation runs and the MAE psi (deg) of the reported
    baseline and of the reference structure on them."""

    fold: str
    validation_runs: list[str]
    baseline_mae_psi_deg: float
    reference_mae_psi_deg: float


@dataclass(frozen=True)
class Reference(Result):
    """``reference``: the reference structure (the catalogue's terms told everything at once, not
    chosen; docs/diagnosis.md, "The reference fit").  ``computed`` False with ``reason`` where it was not
    made (every figure then None, ``per_fold`` empty); its ``effects`` and ``forms``; the pooled
    validation MAE psi (deg), per fold, and its relative cut against the baseline; with --test runs its
    MAE psi there, the baseline's, the relative cut and its 95 % interval (None without test runs);
    without them, where the honest gain is the nested leave-one-run-out, the same figures under that
    protocol (``nested_*``: refitted without each held-out run on the runs its selection saw, measured on
    that run against the same baseline as ``gain``; None where not made on every held-out run);
    ``material``: whether its pooled validation cut reaches ``material_threshold``."""

    computed: bool
    effects: list[str]
    forms: dict[str, str]
    validation_mae_psi_deg: float | None = None
    per_fold: list[ReferenceFold] = field(default_factory=list)
    validation_mae_psi_relative_reduction: float | None = None
    test_mae_psi_deg: float | None = None
    test_baseline_mae_psi_deg: float | None = None
    test_mae_psi_relative_reduction: float | None = None
    test_interval_95: list[float] | None = None
    nested_mae_psi_deg: float | None = None
    nested_baseline_mae_psi_deg: float | None = None
    nested_mae_psi_relative_reduction: float | None = None
    nested_interval_95: list[float] | None = None
    nested_measured_on: list[str] = field(default_factory=list)
    reason: str | None = None
    #: whether the pooled validation cut reaches ``material_threshold`` (DiagnoseConfig.min_gain, the
    #: selection's own materiality); None where not made
    material: bool | None = None
    material_threshold: float | None = None

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Reference:
        """The reference block from its JSON form; the inverse of :meth:`to_json`."""
        return super().from_json({**doc, "per_fold": [ReferenceFold.from_json(f) for f in doc["per_fold"]]})


@dataclass(frozen=True)
class LadderRung(Result):
    """``ladder[]``: one step of the selection: ``model`` (``baseline`` or ``+effect``/``-effect``), the
    structure's ``effects``, its pooled held-out MAE psi (deg) and, with test runs, its MAE psi there
    (deg) and the 95 % interval of its relative cut (None without test runs)."""

    model: str
    effects: list[str]
    validation_mae_psi_deg: float
    test_mae_psi_deg: float | None
    test_interval_95: list[float] | None


@dataclass(frozen=True)
class FoldCause(Result):
    """``stability.causes[]``: the cause one fold (or one held-out run's nested selection) named."""

    fold: str
    cause: str
    effects: list[str]


@dataclass(frozen=True)
class Stability(Result):
    """``stability``: how many of the ``total`` repeated selections agree with the cause, each one's
    cause, and the rule in words."""

    folds_agreeing: int
    total: int
    causes: list[FoldCause]
    rule: str


@dataclass(frozen=True)
class FoldBaseline(Result):
    """``folds[].baseline``: the fold's linear fit, its cost and optimiser message, its held-out figures."""

    parameters: dict[str, float]
    uncertainty: dict[str, float]
    course_stable: bool
    stable: bool
    training_cost: float
    fit: str
    validation: dict[str, Any]
    per_run: list[dict[str, Any]]


@dataclass(frozen=True)
class FoldExtended(Result):
    """``folds[].extended``: the kept structure refitted in the fold and its held-out figures."""

    effects: list[str]
    parameters: dict[str, float]
    course_stable: bool
    validation: dict[str, Any]
    per_run: list[dict[str, Any]]


@dataclass(frozen=True)
class FoldGain(Result):
    """``folds[].gain``: the fold's relative held-out cut of MAE psi (None where undefined)."""

    mae_psi_relative_reduction: float | None


@dataclass(frozen=True)
class FoldReport(Result):
    """``folds[]``: one fold's runs, its baseline and extended fits and its gain."""

    training_runs: list[str]
    validation_runs: list[str]
    course_stable: bool
    baseline: FoldBaseline
    extended: FoldExtended
    gain: FoldGain


@dataclass(frozen=True)
class DataChecks(Result):
    """``data_checks``: what the data's own set-up may do to every fit (pipeline.diagnose.datacheck)."""

    approach_drift: dict[str, Any]
    rate_bias: dict[str, Any]


FIT_WORDS = (
    "prediction-error over one ship time scale, then output-error on free-run psi, r (and v), "
    "each training run's start fitted within the box of its estimate; RK4 of the continuous-time "
    "model, rudder interpolated; stability not forced"
)
SIGNIFICANCE_WORDS = "one-sided t-test of per-block held-out MAE psi differences, t with G-1 dof"


@dataclass(frozen=True)
class Settings(Result):
    """``settings``: the selection's settings as run (DiagnoseConfig), the ship time scale ``time_scale_s``
    (s), the block length ``block_s`` (s), the heading noise floor (deg), the catalogue, the approach
    speed ``u_ref_m_s`` (m/s; None where the runs have no surge speed) and the method in words."""

    min_gain: float
    min_abs_gain_deg: float
    alpha: float
    block_T: float
    block_s: float
    time_scale_s: float
    heading_noise_deg: float
    max_effects: int
    inadequate_floors: float
    structured_r2: float
    catalogue: list[str]
    two_fold: bool
    u_ref_m_s: float | None
    x0_box_sigma: float
    fit: str = FIT_WORDS
    significance: str = SIGNIFICANCE_WORDS


@dataclass(frozen=True)
class DiagnosisReport(Result):
    """``diagnosis.json`` (docs/diagnosis.md): the cause named (None: no effect passes), the baseline's
    adequacy, one finding per catalogue effect (named first, then by held-out gain), the baseline and
    extended models, the honest gain, the selection's ladder, the reference fit, the stability over
    folds, per-fold reports, the summary sentence, the data checks, the runs and the settings."""

    cause: str | None
    baseline_adequate: bool
    baseline_adequacy: Adequacy
    findings: list[Finding | UnjudgedFinding]
    baseline: Baseline
    extended: Extended
    gain: Gain
    ladder: list[LadderRung]
    reference: Reference
    stability: Stability
    course_stable: list[bool]
    folds: list[FoldReport]
    summary: str
    data_checks: DataChecks
    training_runs: list[str]
    validation_runs: list[str]
    test_runs: list[str]
    provenance: str
    settings: Settings

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> DiagnosisReport:
        """The report from diagnosis.json's dict; the inverse of :meth:`to_json`."""
        def finding(d):
            kind = Finding if "form" in d else UnjudgedFinding
            gates = [GateResult(**g) for g in d.get("gates", [])]
            return kind.from_json({**d, "gates": gates})

        def fold(d):
            return FoldReport(d["training_runs"], d["validation_runs"], d["course_stable"],
                              FoldBaseline.from_json(d["baseline"]), FoldExtended.from_json(d["extended"]),
                              FoldGain.from_json(d["gain"]))

        adequacy = dict(doc["baseline_adequacy"])
        adequacy["signatures"] = [Signature.from_json(s) for s in adequacy["signatures"]]
        stability = dict(doc["stability"])
        stability["causes"] = [FoldCause.from_json(c) for c in stability["causes"]]
        nested = {
            "baseline_adequacy": Adequacy.from_json(adequacy),
            "findings": [finding(f) for f in doc["findings"]],
            "ladder": [LadderRung.from_json(r) for r in doc["ladder"]],
            "stability": Stability.from_json(stability),
            "folds": [fold(f) for f in doc["folds"]],
            "gain": Gain.from_json(doc["gain"]),
            "reference": Reference.from_json(doc["reference"]),
        }
        # the other blocks by Result.from_json (the nested ones above given as None, then put in)
        base = super().from_json({**doc, **dict.fromkeys(nested)})
        return dataclasses.replace(base, **nested)


__all__ = [
    "Adequacy", "Baseline", "DataChecks", "DiagnosisReport", "Extended", "Finding", "FoldBaseline",
    "FoldCause", "FoldExtended", "FoldGain", "FoldReport", "Gain", "HeldOutSelection", "LadderRung",
    "OtherLinearGain", "Reference", "ReferenceFold", "Settings", "Signature", "Stability",
    "UnjudgedFinding",
]
