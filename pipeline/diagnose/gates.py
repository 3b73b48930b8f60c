"""The criteria of a selection step as typed objects (docs/diagnosis.md, "The gates").

A step S -> S' of the selection (:mod:`.select`) measures its evidence once (:class:`Evidence`); each
criterion is a small frozen object of :data:`GATES` that judges that evidence and returns a
:class:`GateResult` (a stable ``code``, ``passed``, the measured ``value`` and its ``threshold`` in the
criterion's own unit, or None where it has none, and ``words`` for the reader).  diagnosis.json carries
them per finding (``findings[].gates``); the finding's evidence sentence is made from their words, and
the report reads the codes, never the words.

Units: heading errors deg, gains and shares dimensionless (0.1 = 10 %), t statistics dimensionless.
The reasons of the criteria themselves are at :mod:`.select` (module docstring) and in the docs file.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class GateResult:
    """One criterion's judgement of one step.

    ``code``: the criterion's stable identifier (:data:`CODES`); ``passed``: the step meets it;
    ``value`` / ``threshold``: the measured number and the bound it is held to, in the criterion's own
    unit (None where it has none); ``words``: one clause for the reader (the reason, when it failed)."""

    code: str
    passed: bool
    value: float | None
    threshold: float | None
    words: str

    def to_json(self) -> dict:
        """The result as diagnosis.json's ``findings[].gates[]`` entry."""
        return {"code": self.code, "passed": bool(self.passed), "value": _num(self.value),
                "threshold": _num(self.threshold), "words": self.words}


def _num(x) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if x == x and abs(x) != float("inf") else None


@dataclass(frozen=True)
class RunTest:
    """One held-out run's own test within a step: its name, the measured number and the bound (the
    per-run block t and its critical value, or the error growth and the run's heading swing, deg), and
    the clause naming it ("run a -> b deg (block t = ..)")."""

    run: str
    value: float
    threshold: float
    words: str


@dataclass(frozen=True)
class Evidence:
    """What a step S -> S' measured on the held-out runs of its folds (deg unless said)."""

    gain: float                         # pooled relative cut of held-out MAE psi (0.1 = 10 %)
    fold_gains: tuple[float, ...]       # the same per fold
    min_gain: float                     # DiagnoseConfig.min_gain
    abs_gain_deg: float                 # mean held-out MAE psi cut over the folds, deg
    noise_floor_deg: float              # max(2 x heading noise, min_abs_gain_deg), deg
    t: float                            # one-sided block t of the per-block cuts
    t_crit: float                       # t(1 - alpha, G - 1)
    blocks: int                         # G
    carried: tuple[RunTest, ...]        # held-out runs without which the block t fails
    floor_ok: tuple[bool, ...]          # the new effect above its physical floor, per fold
    floor_words: str                    # the floor's failure clause ("" when every fold passes)
    harm: tuple[RunTest, ...]           # held-out runs made significantly worse (block t, -crit)
    harm_level: str                     # "0.05/4": the per-run level, Bonferroni
    short_gain: float                   # pooled relative short-horizon cut
    short_t: float                      # its one-sided block t
    short_t_crit: float                 # its critical t
    short_horizon_T: float              # the pieces' length, ship time scales
    runaway: tuple[RunTest, ...]        # held-out runs whose error grew by more than their swing
    #: training runs the step hinges on; None: not judged (another criterion refused the step first)
    hinges: tuple[str, ...] | None = None
    #: the stepped-to model's pooled held-out MAE psi (mean over the folds), deg
    model_mae_deg: float = float("nan")
    #: the reported linear baseline's, deg, where it is not the linear model the step's family extends
    #: (the best linear model without the sign bounds beside a bounded family); None where it is
    best_linear_mae_deg: float | None = None


@dataclass(frozen=True)
class MinGain:
    """The pooled held-out gain reaches ``min_gain``."""

    code: str = "min_gain"
    last: bool = False
    worth: bool = True

    def judge(self, ev: Evidence) -> GateResult:
        ok = ev.gain >= ev.min_gain
        return GateResult(self.code, ok, ev.gain, ev.min_gain,
                          f"held-out gain {ev.gain:.0%}" + (f" below {ev.min_gain:.0%}" if not ok else
                                                            f" at least {ev.min_gain:.0%}"))


@dataclass(frozen=True)
class EveryFold:
    """Better in every fold (the smallest fold gain above 0)."""

    code: str = "every_fold"
    last: bool = False
    worth: bool = True

    def judge(self, ev: Evidence) -> GateResult:
        low = min(ev.fold_gains) if ev.fold_gains else 0.0
        ok = low > 0
        return GateResult(self.code, ok, low, 0.0,
                          "better in every fold" if ok else "not better in every fold")


@dataclass(frozen=True)
class NoiseFloor:
    """The mean held-out heading cut is above the noise level (deg)."""

    code: str = "noise_floor"
    last: bool = False
    worth: bool = True

    def judge(self, ev: Evidence) -> GateResult:
        ok = not ev.abs_gain_deg < ev.noise_floor_deg
        rel = "above" if ok else "below"
        return GateResult(self.code, ok, ev.abs_gain_deg, ev.noise_floor_deg,
                          f"held-out heading cut {ev.abs_gain_deg:.3f} deg {rel} the noise level "
                          f"{ev.noise_floor_deg:.3f} deg")


@dataclass(frozen=True)
class BlockT:
    """The one-sided block t-test of the per-block cuts is significant (t with G - 1 dof)."""

    code: str = "block_t"
    last: bool = False
    worth: bool = True

    def judge(self, ev: Evidence) -> GateResult:
        ok = ev.t >= ev.t_crit
        if ev.blocks < 3:
            return GateResult(self.code, ok, None, None, "fewer than 3 blocks")
        rel = ">=" if ok else "below"
        return GateResult(self.code, ok, ev.t, ev.t_crit,
                          f"block t = {ev.t:.2f} {rel} t(0.95, {ev.blocks - 1}) = {ev.t_crit:.2f}")


@dataclass(frozen=True)
class CarriedByOneRun:
    """Not carried by one held-out run: leaving any one out, the others' blocks still pass the t-test
    (value: the smallest such t; threshold: its critical value)."""

    code: str = "carried_by_one_run"
    last: bool = False
    worth: bool = True

    def judge(self, ev: Evidence) -> GateResult:
        if not ev.carried:
            return GateResult(self.code, True, None, None, "not carried by one held-out run")
        worst = min(ev.carried, key=lambda x: x.value - x.threshold)
        return GateResult(
            self.code, False, worst.value, worst.threshold,
            "carried by one held-out run: without it the block t-test no longer finds a cut, and a free "
            "run's blocks are not independent, so the cut is that run's, not the ship's: "
            + ", ".join(x.words for x in ev.carried))


@dataclass(frozen=True)
class PhysicalFloor:
    """The new effect's estimate exceeds its physical floor in every fold (the effect's own
    :meth:`~.effects.base.Effect.material`)."""

    code: str = "physical_floor"
    last: bool = False
    worth: bool = True

    def judge(self, ev: Evidence) -> GateResult:
        ok = all(ev.floor_ok)
        return GateResult(self.code, ok, None, None,
                          "above its physical floor in every fold" if ok else ev.floor_words)


@dataclass(frozen=True)
class BeatsBestLinear:
    """The stepped-to model predicts the held-out runs better (pooled MAE psi, deg) than the reported
    linear baseline where that is not the linear model the step's family extends (the best linear
    model fitted without the sign bounds, :meth:`~.select.Search.choose_baseline`).  A step's gain is
    measured inside its family; without this gate an extension of the bounded fit could be named while
    predicting worse than a linear model at hand, and its gain be one over a crippled baseline."""

    code: str = "beats_best_linear"
    last: bool = False
    worth: bool = False

    def judge(self, ev: Evidence) -> GateResult:
        if ev.best_linear_mae_deg is None:
            return GateResult(self.code, True, ev.model_mae_deg, None,
                              "the family's own linear model is the best linear model")
        ok = ev.model_mae_deg < ev.best_linear_mae_deg
        rel = "below" if ok else "not below"
        return GateResult(self.code, ok, ev.model_mae_deg, ev.best_linear_mae_deg,
                          f"held-out MAE psi {ev.model_mae_deg:.2f} deg {rel} the best linear model's "
                          f"{ev.best_linear_mae_deg:.2f} deg")


@dataclass(frozen=True)
class NoHarm:
    """No held-out run made significantly worse (value: the lowest per-run block t; threshold: minus
    the Bonferroni critical value)."""

    code: str = "no_harm"
    last: bool = False
    worth: bool = False

    def judge(self, ev: Evidence) -> GateResult:
        if not ev.harm:
            return GateResult(self.code, True, None, None, "no held-out run significantly worse")
        worst = min(ev.harm, key=lambda x: x.value)
        return GateResult(
            self.code, False, worst.value, worst.threshold,
            f"significantly worse on a held-out manoeuvre (one-sided block t at {ev.harm_level}, "
            "Bonferroni over the held-out runs): " + "; ".join(x.words for x in ev.harm))


@dataclass(frozen=True)
class ShortHorizon:
    """Not predicted significantly worse from the measured state over short_horizon_T ship time scales
    (value: the pieces' block t; threshold: minus its critical value)."""

    code: str = "short_horizon"
    last: bool = False
    worth: bool = False

    def judge(self, ev: Evidence) -> GateResult:
        ok = not ev.short_t < -ev.short_t_crit
        if ok:
            return GateResult(self.code, True, ev.short_t, -ev.short_t_crit,
                              f"not worse from the measured state over {ev.short_horizon_T:g} ship time "
                              f"scale(s) (short-horizon MAE psi {-ev.short_gain:+.0%})")
        return GateResult(
            self.code, False, ev.short_t, -ev.short_t_crit,
            f"predicts worse from the measured state over {ev.short_horizon_T:g} ship time scale(s): "
            f"held-out short-horizon MAE psi {-ev.short_gain:+.0%} (block t = {ev.short_t:.2f} below "
            f"-{ev.short_t_crit:.2f}); it fits the runs' drift, not the ship's response")


@dataclass(frozen=True)
class NoRunaway:
    """On no held-out run does the error grow by more than its heading swing (value: the largest
    growth beyond the swing, deg; threshold 0)."""

    code: str = "no_runaway"
    last: bool = False
    worth: bool = False

    def judge(self, ev: Evidence) -> GateResult:
        if not ev.runaway:
            return GateResult(self.code, True, None, 0.0, "runs away on no held-out manoeuvre")
        worst = max(ev.runaway, key=lambda x: x.value - x.threshold)
        return GateResult(
            self.code, False, worst.value - worst.threshold, 0.0,
            "runs away on a held-out manoeuvre (error grown by more than its heading swing): "
            + "; ".join(x.words for x in ev.runaway))


@dataclass(frozen=True)
class NoHinge:
    """Not hinging on one training run (:meth:`~.select.Search.hinges`); judged last, only for a step
    that passes every other criterion (it costs two fits per training run)."""

    code: str = "hinge"
    last: bool = True
    worth: bool = False

    def judge(self, ev: Evidence) -> GateResult:
        hinges = ev.hinges or ()
        if not hinges:
            return GateResult(self.code, True, None, None, "hinges on no training run")
        return GateResult(
            self.code, False, float(len(hinges)), 0.0,
            "hinges on one training run: refitted without it, the model no longer makes that manoeuvre "
            "(error grown by more than its heading swing): " + "; ".join(hinges))


#: the criteria of a step, in the order their reasons are read; a gate with ``last`` is judged only
#: when every other one passed
GATES = (MinGain(), EveryFold(), NoiseFloor(), BlockT(), CarriedByOneRun(), PhysicalFloor(),
         BeatsBestLinear(), NoHarm(), ShortHorizon(), NoRunaway(), NoHinge())
#: every gate's code
CODES = tuple(g.code for g in GATES)
#: the codes of the gates that measure what a step's effect is worth on the held-out runs (its gain,
#: its significance, its physical size); the others ask whether the model after the step is sound
#: (harm to one run, short-horizon prediction, run-away, the best linear model, one training run)
WORTH = tuple(g.code for g in GATES if g.worth)


def judge(ev: Evidence, last: bool) -> tuple[GateResult, ...]:
    """The results of the gates of :data:`GATES` whose ``last`` is ``last``, in order."""
    return tuple(g.judge(ev) for g in GATES if g.last == last)
