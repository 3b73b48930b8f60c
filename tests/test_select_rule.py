"""The stepwise rule of pipeline.diagnose.select on a table of held-out errors (no fitting).

A fake search gives every structure a held-out error from a table; a step passes when it cuts that
error by at least 10 %.  The table is made as the Mariner truth behaved (tests/truths/mariner.py): the
forward pass takes an effect (saturation) that a later one (speed loss) makes redundant, the backward
pass drops it, and on what is left an effect (offset) that gained nothing beside the first picks now
gains a great deal.  The rule must end at its own fixed point: no single addition passes, every
member's drop-one step passes.
"""

from __future__ import annotations

import sys

import pytest

from pipeline.config import DiagnoseConfig
from pipeline.diagnose import select as sel
from pipeline.diagnose.effects import Context
from pipeline.diagnose.fit import structure_of
from pipeline.diagnose.gates import GateResult

A, C, D, O = "rudder_saturation", "nonlinear_sway_damping", "speed_loss", "rudder_offset"
#: held-out MAE psi (deg) of each structure; any other effect of the catalogue changes nothing
TABLE = {
    (): 10.0, (A,): 5.0, (C,): 7.0, (D,): 5.5, (O,): 8.0,
    (A, C): 3.5, (A, D): 4.4, (A, O): 4.0, (C, D): 3.1, (C, O): 6.8, (D, O): 4.4,
    (A, C, D): 3.0, (A, C, O): 3.45, (A, D, O): 3.3, (C, D, O): 2.0,
    (A, C, D, O): 2.8,
}
MIN_GAIN = 0.10


def _error(structure) -> float:
    names = {e for e, _ in structure}
    return TABLE[tuple(x for x in (A, C, D, O) if x in names)]


class _Fit:
    def __init__(self, cost):
        self.cost = cost


class FakeSearch:
    """What select needs of pipeline.diagnose.select.Search, with held-out errors from TABLE."""

    memo = None  # no fit memo: no helper makes fits ahead (pipeline.diagnose.ahead)

    def __init__(self, max_effects: int = 4):
        self.cfg = DiagnoseConfig(max_effects=max_effects)
        self.ctx = Context(t_ship=10.0, h=0.08, d_max=20.0, r_max=3.0, v_max=0.3, u_ref=1.0,
                           u_min_ratio=0.8)
        self._fits: dict = {}
        self._evals: dict = {}
        self._short: dict = {}
        self.steps: list = []

    def choose_baseline(self, ks):
        """The baseline's choice (Search.choose_baseline) is not what these tests ask: the table's."""

    def fit(self, k, structure, start=None):
        """A stand-in fit whose training cost is the table's error (what _pair_pool ranks by)."""
        f = _Fit(_error(structure))
        self._fits[(k, structure_of(*structure))] = f
        return f

    def fitted(self, k, structure):
        return (k, structure_of(*structure)) in self._fits

    def start_of(self, k, structure):
        return self.fit(k, structure)

    def group_fit(self, k, structure, starts):
        return self.fit(k, structure)

    def defer_group_fit(self, k, structure, starts):
        """Never asked: every group passes the per-fold screen here (fold_may_pass)."""

    def fold_may_pass(self, k, before, after, effects):
        """The table has no per-fold figures: the steps alone judge."""
        return True

    def refine(self, k, structure, richer):
        return False

    def choose_form(self, ks, base, effect):
        return structure_of(*base, effect)

    def step(self, ks, before, after, effect, noise_deg):
        b, a = _error(before), _error(after)
        gain = (b - a) / b
        why = [] if gain >= MIN_GAIN else [f"held-out gain {gain:.0%} below {MIN_GAIN:.0%}"]
        self.steps.append((tuple(e for e, _ in before), tuple(e for e, _ in after)))
        gates = (GateResult("min_gain", not why, gain, MIN_GAIN, "; ".join(why)),)
        return sel.Step(passes=not why, gain=gain, gains=[gain], abs_gain_deg=b - a, t=10.0, t_crit=1.7,
                        blocks=20, material=True, floor="", why=why, structure=structure_of(*after),
                        mean_diff=b - a, se=0.0, gates=gates)


def _names(structure) -> set:
    return {e for e, _ in structure}


def test_stepwise_ends_at_its_own_fixed_point():
    """Forward: saturation (50 %), sway damping (30 %), speed loss (14 %); adding the offset then
    gains 7 %: stop.  Backward: saturation's drop-one step gains 3 %: it leaves.  On the pair left,
    the offset gains 35 %: the rule must add it (a forward round again after the backward pass) and end
    with sway damping + speed loss + offset, where nothing more passes and every member is needed."""
    search = FakeSearch()
    out = sel.select(search, [0], noise_deg=0.05)
    assert _names(out.structure) == {C, D, O}, out.structure
    # the largest drop-one worth: without speed loss 6.8 deg, without sway damping 4.4, without the
    # offset 3.1, with all three 2.0
    assert out.cause == D
    assert {e: round(s.gain, 3) for e, s in out.worth.items()} == {C: 0.545, D: 0.706, O: 0.355}
    # fixed point: no single addition passes (the final round's steps), every drop-one step passes
    others = {e: s for e, s in out.last.items() if e not in out.worth}
    assert A in others and not any(s.passes for s in others.values())
    assert all(s.passes for s in out.worth.values())
    assert [sorted(_names(st)) for st, _ in out.ladder] == [
        [], [A], sorted([A, C]), sorted([A, C, D]), sorted([C, D]), sorted([C, D, O])]


def test_one_cycle_is_the_old_rule(monkeypatch):
    """With one forward-backward cycle (the rule before 2026-11-24) the search ends on the pair, where
    the offset would pass: what the cycles mend, and proof that the bound on them is honoured."""
    monkeypatch.setattr(sel, "_MAX_CYCLES", 1)
    out = sel.select(FakeSearch(), [0], noise_deg=0.05)
    assert _names(out.structure) == {C, D}
    assert out.last[O].passes and out.last[O].gain > 0.3     # reported as passing, but not added



def test_pair_pool_ranks_by_training_cost_not_held_out_gain():
    """The pool of the pair fallback: the candidates that cut the training cost most (mean cut over
    the folds), whatever their held-out gain (the Mariner's offset and cross terms hurt held-out alone
    and explain most of the training error).  The mean, not the smallest cut (the rule before
    2026-11-26, under which D ranked last): the pool only chooses what is tried, every pair must still
    pass the held-out step in every fold, and by the smallest cut one fold's training runs vetoed the
    asymmetric KCS's offset (select._pair_pool)."""
    base = structure_of()
    cost = {  # (fold, effect) -> training cost; the baseline's is 1.0 in both folds
        (0, A): 0.9, (1, A): 0.95,     # held-out best, explains little
        (0, C): 0.5, (1, C): 0.6,      # cuts 40-50 %
        (0, D): 0.2, (1, D): 0.99,     # a large cut in one fold only: smallest cut 1 %
        (0, O): 0.7, (1, O): 0.7,      # cuts 30 %
    }

    class S:
        def fit(self, k, st):
            names = [e for e, _ in st]
            return _Fit(1.0 if not names else cost[(k, names[0])])

    ranked = [(e, (structure_of(e), None)) for e in (A, D, O, C)]     # held-out order
    # mean cuts: C 45 %, D 40.5 %, O 30 %, A 7.5 %
    assert [e for e, _ in sel._pair_pool(S(), [0, 1], base, ranked, 2)] == [C, D]
    assert [e for e, _ in sel._pair_pool(S(), [0, 1], base, ranked, 4)] == [C, D, O, A]


#: a second table, for a limit of two effects: saturation then sway damping fill the model, and
#: speed loss in saturation's place is better (2.5 deg against 3.5)
TABLE2 = {
    (): 10.0, (A,): 5.0, (C,): 7.0, (D,): 5.5, (O,): 8.0,
    (A, C): 3.5, (A, D): 4.4, (A, O): 4.4, (C, D): 2.5, (C, O): 6.8, (D, O): 4.4,
}


def test_a_full_structure_tries_replacements(monkeypatch):
    """Sequential replacement (Miller 2002): forward fills the two places with saturation and sway
    damping, backward keeps both (each drop-one step passes); swapping saturation for speed loss cuts
    the error by 29 %, so the rule moves there, and stops when no swap of the new pair passes."""
    monkeypatch.setattr(sys.modules[__name__], "TABLE", TABLE2)
    out = sel.select(FakeSearch(max_effects=2), [0], noise_deg=0.05)
    assert _names(out.structure) == {C, D}, out.structure
    assert [sorted(_names(st)) for st, _ in out.ladder] == [[], [A], sorted([A, C]), sorted([C, D])]
    assert out.ladder[-1][1].passes and round(out.ladder[-1][1].gain, 3) == round(1 - 2.5 / 3.5, 3)


def test_no_replacement_below_the_limit():
    """Below max_effects the forward round already tries every addition: no swap is judged."""
    search = FakeSearch()
    out = sel.select(search, [0], noise_deg=0.05)
    assert _names(out.structure) == {C, D, O}
    swaps = [(b, a) for b, a in search.steps if len(a) == len(b) and set(a) != set(b)]
    assert swaps == []


#: a third table, for a limit of three effects: no effect and no pair cuts the error by 10 %, the
#: three of sway damping, speed loss and offset together cut it by 70 % (each needed)
TABLE3 = {
    (): 10.0, (A,): 9.5, (C,): 9.8, (D,): 9.7, (O,): 9.9,
    (A, C): 9.2, (A, D): 9.2, (A, O): 9.3, (C, D): 9.3, (C, O): 9.4, (D, O): 9.3,
    (A, C, D): 9.2, (A, C, O): 9.2, (A, D, O): 9.2, (C, D, O): 3.0,
}


def test_three_effects_that_pass_only_together_are_found(monkeypatch):
    """No single effect and no pair passes; the triple among the pool (the four of largest training
    cut: saturation, speed loss, sway damping, offset) that passes, each member needed, is taken."""
    monkeypatch.setattr(sys.modules[__name__], "TABLE", TABLE3)
    search = FakeSearch(max_effects=3)
    out = sel.select(search, [0], noise_deg=0.05)
    assert _names(out.structure) == {C, D, O}, out.structure
    assert [sorted(_names(st)) for st, _ in out.ladder] == [[], sorted([C, D, O])]
    # each member's need was judged: the step from each pair to the triple
    for pair in ((C, D), (C, O), (D, O)):
        assert any(set(b) == set(pair) and set(a) == {C, D, O} for b, a in search.steps), pair


def test_no_triples_without_room(monkeypatch):
    """With a limit of two effects no triple is tried, and nothing is named."""
    monkeypatch.setattr(sys.modules[__name__], "TABLE", TABLE3)
    search = FakeSearch(max_effects=2)
    out = sel.select(search, [0], noise_deg=0.05)
    assert out.structure == () and out.cause == "none"
    assert max(len(a) for _, a in search.steps) == 2


class _TieSearch(FakeSearch):
    """A round where an offset (30 % held-out) and a rudder asymmetry (28 %) both pass on their own,
    and together gain nothing more (they explain the same error); ``se`` is the standard error of
    every step's per-block cut (deg)."""

    ERR = {(): 10.0, ("rudder_offset",): 7.0, ("rudder_asymmetry",): 7.2,
           ("rudder_offset", "rudder_asymmetry"): 6.9}

    def __init__(self, se: float):
        super().__init__()
        self.se = se

    def _err(self, structure) -> float:
        names = {e for e, _ in structure}
        return self.ERR.get(tuple(x for x in ("rudder_offset", "rudder_asymmetry") if x in names), 10.0)

    def fit(self, k, structure, start=None):
        f = _Fit(self._err(structure))
        self._fits[(k, structure_of(*structure))] = f
        return f

    def step(self, ks, before, after, effect, noise_deg):
        b, a = self._err(before), self._err(after)
        gain = (b - a) / b
        why = [] if gain >= MIN_GAIN else [f"held-out gain {gain:.0%} below {MIN_GAIN:.0%}"]
        return sel.Step(passes=not why, gain=gain, gains=[gain], abs_gain_deg=b - a, t=10.0, t_crit=1.7,
                        blocks=20, material=True, floor="", why=why, structure=structure_of(*after),
                        mean_diff=b - a, se=self.se)


def test_rivals_within_one_standard_error_are_reported():
    """The offset is taken (the larger cut, one parameter as the asymmetry); the asymmetry's cut, 2.8
    against 3.0 deg, is within one standard error (0.5 deg) of it, so it is the offset's rival, and
    the asymmetry is not added on top (1.4 %).  With a standard error of 0.1 deg the data tell them
    apart: no rival."""
    out = sel.select(_TieSearch(se=0.5), [0], noise_deg=0.05)
    assert _names(out.structure) == {"rudder_offset"}
    own, rivals = out.rivals["rudder_offset"]
    assert own.gain == pytest.approx(0.30) and [x for x, _ in rivals] == ["rudder_asymmetry"]
    assert rivals[0][1].gain == pytest.approx(0.28)
    out = sel.select(_TieSearch(se=0.1), [0], noise_deg=0.05)
    assert _names(out.structure) == {"rudder_offset"} and out.rivals == {}


#: a fourth table: the offset then sway damping (O, C) pass forward; without the offset the model runs
#: away (1000 deg), and that drop-one step fails its t-test by the divergence's heavy tail
TABLE4 = {
    (): 10.0, (A,): 9.9, (C,): 1000.0, (D,): 9.9, (O,): 4.0,
    (A, C): 1000.0, (A, D): 9.9, (A, O): 3.9, (C, D): 1000.0, (C, O): 1.0, (D, O): 3.9,
    (A, C, D): 1000.0, (A, C, O): 0.99, (A, D, O): 3.9, (C, D, O): 0.99, (A, C, D, O): 0.98,
}


class RunAwaySearch(FakeSearch):
    """The drop-one step from a model that runs away (error above 100 deg) fails significance, as the
    block t-test did on the fresh truth draw's case 31 (block t 1.02), and says it runs away."""

    def step(self, ks, before, after, effect, noise_deg):
        st = super().step(ks, before, after, effect, noise_deg)
        if _error(before) > 100.0 >= _error(after):
            st.passes, st.why = False, ["block t = 1.02 below t(0.95, 7) = 1.89"]
            st.gates = (*st.gates, GateResult("block_t", False, 1.02, 1.89, st.why[0]))
            st.removal_runs_away = [f"run 1 {_error(after):.2f} -> {_error(before):.2f} deg"]
        return st


def test_backward_never_removes_an_effect_without_which_the_model_runs_away(monkeypatch):
    """Forward takes the offset (60 %) and sway damping (75 %); dropping the offset leaves a model that
    runs away, whose drop-one step fails its t-test.  The offset stays; a search that ignored the
    run-away (the rule before 2026-11-24) drops it and ends on a model that runs away."""
    monkeypatch.setattr(sys.modules[__name__], "TABLE", TABLE4)
    out = sel.select(RunAwaySearch(), [0], noise_deg=0.05)
    assert _names(out.structure) == {O, C}, out.structure
    assert out.worth[O].removal_runs_away and not out.worth[O].passes

    class Old(RunAwaySearch):
        def step(self, *a, **kw):
            st = super().step(*a, **kw)
            st.removal_runs_away = []
            return st

    assert _names(sel.select(Old(), [0], noise_deg=0.05).structure) == {C}


def test_a_floor_failure_names_the_fold_that_fails():
    """Measured on HSVA (2026-11-25): the misalignment's evidence read "below its physical floor:
    |misalignment| 0.39 deg (floor 0.2 deg)", the passing fold's text, where the other fold's estimate
    was under the floor."""
    from pipeline.diagnose.select import floor_failure

    floors = ["|m| 0.39 deg (floor 0.2 deg)", "|m| 0.05 deg (floor 0.2 deg)"]
    assert floor_failure([True, False], floors, [0, 1]) == "below its physical floor in fold 2: " + floors[1]
    assert floor_failure([False, True], floors, [0, 1]) == "below its physical floor in fold 1: " + floors[0]
    assert floor_failure([False], floors[1:], [0]) == "below its physical floor: " + floors[1]


def test_floor_readings_label_the_folds_when_they_differ():
    from pipeline.diagnose.select import floor_readings

    same = "|offset| 0.50 deg (floor 0.3 deg)"
    assert floor_readings([same, same], [0, 1]) == same
    assert floor_readings([same], [0]) == same
    got = floor_readings(["|m| 0.39 deg", "|m| 0.07 deg"], [0, 1])
    assert got == "fold 1: |m| 0.39 deg; fold 2: |m| 0.07 deg"


def test_a_cut_carried_by_one_held_out_run_is_named():
    """select.carried_by_one_run, known answers on per-block held-out MAE differences (deg): a cut that
    every run shares survives leaving any one out; a cut one run makes (a drift it corrected, the other
    runs' blocks noise about zero) does not, and that run is named; the pooled t of the latter still
    clears the one-sided 5 % bound, which is why the check exists; two runs are too few to ask."""
    import numpy as np
    from scipy import stats

    rng = np.random.default_rng(11)
    shared = [(f"run{j}", list(0.4 + 0.2 * rng.standard_normal(7))) for j in range(4)]
    assert sel.carried_by_one_run(shared, 0.05) == []
    one = [("drift", [0.0, 0.5, 1.1, 1.2, 1.5, 1.8, 1.3])] + [
        (f"run{j}", list(0.3 * rng.standard_normal(7))) for j in range(3)]
    pooled = np.concatenate([d for _, d in one])
    t = pooled.mean() / (pooled.std(ddof=1) / np.sqrt(pooled.size))
    assert t > stats.t.ppf(0.95, pooled.size - 1), t
    named = sel.carried_by_one_run(one, 0.05)
    assert len(named) == 1 and named[0].run == "drift", named
    assert named[0].words.startswith("drift (without it block t = ") and named[0].value < named[0].threshold
    assert sel.carried_by_one_run(one[:2], 0.05) == []
