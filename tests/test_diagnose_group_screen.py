"""The group search's per-fold screen (:meth:`pipeline.diagnose.select.Search.fold_may_pass`): a group is
fitted fold by fold, and after the first fold where a gate that every fold must pass already fails its
fits in the later folds are deferred (made, as they would have been, only when asked for).  So the
screen must say False exactly where the group's steps fail one of those gates, a deferred fit must be
the eager one, and which group is chosen never changes."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from tank_search import tank_search  # the virtual tank's runs as a two-fold search

from pipeline import tank
from pipeline.diagnose.effects import BY_NAME
from pipeline.diagnose.select import Search, _best_group, structure_of

#: the gates every fold must pass on its own (EveryFold, NoRunaway, PhysicalFloor)
PER_FOLD = {"every_fold", "no_runaway", "physical_floor"}


def _kcs_search() -> Search:
    """The virtual KCS's zigzags (its hull nonlinear in v and r; 60 s each), mirror runs held out: two
    folds, no fit memo (every fit made)."""
    zz = tank.zigzag
    return tank_search([zz(20, 20, "starboard", duration=60.0), zz(10, 10, "port", duration=60.0)],
                       [zz(20, 20, "port", duration=60.0), zz(10, 10, "starboard", duration=60.0)])


@pytest.mark.slow
def test_the_screen_says_false_exactly_where_a_per_fold_gate_fails():
    """Every pair of four catalogue effects fitted on the baseline in both folds of the virtual KCS's
    zigzags.  For each pair, the screen is True in every fold exactly when each member's step passes
    every per-fold gate; both outcomes occur (else the check would prove nothing)."""
    s = _kcs_search()
    ks = [0, 1]
    s.choose_baseline(ks)
    effects = ["rudder_offset", "nonlinear_yaw_damping", "speed_loss", "nonlinear_sway_damping"]
    seen = set()
    for group in itertools.combinations(effects, 2):
        full = structure_of(*[(e, BY_NAME[e].forms[0].name) for e in group])
        for k in ks:
            s.fit(k, full, start=s.fit(k, ()))
        screen = all(s.fold_may_pass(k, (), full, group) for k in ks)
        steps = [s.step(ks, (), full, m, 0.01) for m in group]
        gates = all(g.passed for st in steps for g in st.gates if g.code in PER_FOLD)
        assert screen == gates, (group, [[g.code for g in st.gates if not g.passed] for st in steps])
        seen.add(screen)
    assert seen == {True, False}, seen


@pytest.mark.slow
def test_a_deferred_group_fit_is_the_fit_the_group_search_would_have_made():
    """Fold 1's fits of a pair and of a triple holding it, made at once (as a group search reaching that
    fold makes them) in one search, and deferred in another (the triple's start the pair's deferred
    fit) and asked for later: the same parameters and cost to the bit, and :meth:`Search.fitted` makes
    a deferred fit; a structure never fitted or deferred is not held."""
    forms = {e: BY_NAME[e].forms[0].name for e in ("rudder_offset", "nonlinear_yaw_damping", "speed_loss")}
    one = {e: structure_of((e, f)) for e, f in forms.items()}
    pair = structure_of(*[(e, forms[e]) for e in ("rudder_offset", "nonlinear_yaw_damping")])
    triple = structure_of(*[(e, f) for e, f in forms.items()])
    other = structure_of(*[(e, forms[e]) for e in ("rudder_offset", "speed_loss")])
    now, later = _kcs_search(), _kcs_search()
    for s in (now, later):
        s.choose_baseline([0, 1])
    now.group_fit(1, pair, [now.fit(1, one["nonlinear_yaw_damping"]), now.fit(1, one["rudder_offset"])])
    now.group_fit(1, other, [now.fit(1, one["speed_loss"]), now.fit(1, one["rudder_offset"])])
    now.group_fit(1, triple, [now.start_of(1, st) for st in (other, pair)])
    later.defer_group_fit(1, pair, [later.fit(1, one["nonlinear_yaw_damping"]),
                                    later.fit(1, one["rudder_offset"])])
    later.group_fit(1, other, [later.fit(1, one["speed_loss"]), later.fit(1, one["rudder_offset"])])
    later.defer_group_fit(1, triple, [later.start_of(1, st) for st in (other, pair)])
    assert (1, pair) not in later._fits and (1, triple) not in later._fits
    assert later.fitted(1, triple) and (1, pair) not in later._fits      # the pair only as a start
    for st in (triple, pair):
        a, b = now.fit(1, st), later.fit(1, st)
        assert a.cost == b.cost and np.array_equal(a.p, b.p), st
    assert not later.fitted(0, triple)


class _GroupSearch:
    """``_best_group``'s stub: fits are recorded; ``bad[(k, members)]`` says fold k fails the screen;
    every step of a group that passes the screen in every fold passes, with gain ``gain[members]``."""

    memo = None  # no fit memo: no helper makes fits ahead (pipeline.diagnose.ahead)

    def __init__(self, bad, gain):
        from pipeline.diagnose.select import Step

        self.bad, self.gain, self.fitted, self.deferred, self.Step = bad, gain, [], [], Step
        self._fits, self._evals, self._short = {}, {}, {}

    def fit(self, k, structure, start=None):
        key = (k, structure_of(*structure))
        if key not in self._fits:
            self.fitted.append((k, tuple(e for e, _ in structure)))
            self._fits[key] = type("F", (), {"cost": 1.0})()
        return self._fits[key]

    def start_of(self, k, structure):
        return self.fit(k, structure)

    def group_fit(self, k, structure, starts):
        self._fits.pop((k, structure_of(*structure)), None)
        return self.fit(k, structure)

    def defer_group_fit(self, k, structure, starts):
        self.deferred.append((k, frozenset(e for e, _ in structure)))

    def fold_may_pass(self, k, before, after, effects):
        return (k, frozenset(effects)) not in self.bad

    def step(self, ks, before, after, effect, noise_deg):
        g = self.gain.get(frozenset(e for e, _ in after), 0.5)
        return self.Step(passes=True, gain=g, gains=[g], abs_gain_deg=1.0, t=3.0, t_crit=1.7, blocks=20,
                         material=True, floor="", why=[])


def test_a_group_failing_the_screen_in_its_first_fold_is_not_fitted_in_the_next():
    """A pair that fails the screen in fold 0 is not fitted in fold 1 (its fit there is deferred); one
    failing in fold 1 is fitted in both and refused; the pair passing in both folds is chosen even where
    a refused one would have had the larger gain."""
    a, b, c = ("rudder_offset", "constant"), ("speed_loss", "power"), ("rudder_lag", "first_order")
    pool = [(e[0], (structure_of(e), None)) for e in (a, b, c)]
    bad = {(0, frozenset({a[0], b[0]})), (1, frozenset({a[0], c[0]}))}
    gain = {frozenset({a[0], b[0]}): 0.9, frozenset({a[0], c[0]}): 0.8, frozenset({b[0], c[0]}): 0.3}
    s = _GroupSearch(bad, gain)
    first, st, step = _best_group(s, [0, 1], (), pool, 0.1, 2)
    assert {e for e, _ in st} == {b[0], c[0]} and step.gain == 0.3
    pairs = [(k, frozenset(m)) for k, m in s.fitted if len(m) == 2]
    assert (0, frozenset({a[0], b[0]})) in pairs and (1, frozenset({a[0], b[0]})) not in pairs
    assert s.deferred == [(1, frozenset({a[0], b[0]}))]
    assert {(0, frozenset({a[0], c[0]})), (1, frozenset({a[0], c[0]}))} <= set(pairs)
