"""The backward pass of the selection (docs/diagnosis.md, "The bounded form and the reference step"):
which failed criteria of a member's drop-one step remove it.  A stub search stands in for the fits so
the rule is tested alone: a structure at ``max_effects`` (no forward round) whose members' drop-one
steps carry set gate results."""

from __future__ import annotations

import dataclasses as dc

from pipeline.config import DiagnoseConfig
from pipeline.diagnose.gates import CODES, GATES, WORTH, GateResult
from pipeline.diagnose.select import Step, _forward_backward


def _step(failed: set, gain: float) -> Step:
    gates = tuple(GateResult(c, c not in failed, None, None, c) for c in CODES)
    return Step(passes=not failed, gain=gain, gains=[gain], abs_gain_deg=1.0, t=3.0, t_crit=1.7,
                blocks=20, material=True, floor="", why=sorted(failed), gates=gates)


class _Search:
    """Drop-one steps by member: ``steps[e]`` judges (structure without e) -> (structure)."""

    memo = None  # no fit memo: no helper makes fits ahead (pipeline.diagnose.ahead)

    def __init__(self, cfg, steps):
        self.cfg, self.steps, self._fits = cfg, steps, {}

    def fit(self, k, structure, start=None):
        return None

    def fitted(self, k, structure):
        return False

    def refine(self, k, smaller, richer):
        return False

    def step(self, ks, before, after, effect, noise_deg):
        return self.steps[effect]


def _backward(steps: dict, **over) -> tuple:
    cur = tuple((e, "form") for e in steps)
    # the backward rule alone: reference_whole (which keeps the reference's members) off
    cfg = dc.replace(DiagnoseConfig(), max_effects=len(cur), **{"reference_whole": False, **over})
    out = _forward_backward(_Search(cfg, steps), [0], cur, None, 0.1, [(cur, None)], {}, {}, {})
    return tuple(e for e, _ in out[0])


def test_worth_gates_are_the_ones_that_measure_the_effect():
    assert set(WORTH) == {"min_gain", "every_fold", "noise_floor", "block_t", "carried_by_one_run",
                          "physical_floor"}
    assert all(isinstance(g.worth, bool) for g in GATES)


def test_a_member_that_harms_one_run_but_carries_the_rest_stays_only_on_worth():
    """The offset's drop-one step fails only no_harm (one run better without it) at a 40 % pooled
    worth: the default rule drops it, the worth rule keeps it.  A member failing its block t goes
    under both rules; a passing one stays under both."""
    steps = {"rudder_offset": _step({"no_harm"}, 0.40),
             "hull_nonlinearity": _step(set(), 0.55),
             "speed_loss": _step({"block_t", "min_gain"}, 0.02)}
    assert _backward(steps, backward_on_worth=False) == ("hull_nonlinearity",)
    assert _backward(steps, backward_on_worth=True) == ("rudder_offset", "hull_nonlinearity")


def test_soundness_failures_alone_never_remove_on_worth():
    for code in set(CODES) - set(WORTH):
        steps = {"rudder_offset": _step({code}, 0.3), "rudder_lag": _step(set(), 0.3)}
        assert _backward(steps, backward_on_worth=True) == ("rudder_offset", "rudder_lag"), code
        assert _backward(steps, backward_on_worth=False) == ("rudder_lag",), code


class _RefSearch:
    """The reference step's stub: ``fail[m]`` the gates member m's step fails, looked up by structure
    (frozenset of members) so a smaller group can pass where the full one did not."""

    memo = None  # no fit memo: no helper makes fits ahead (pipeline.diagnose.ahead)

    def __init__(self, fail):
        from pipeline.diagnose.effects import Context

        # reference_whole off unless a test turns it on
        self.cfg, self.fail, self.fitted = dc.replace(DiagnoseConfig(), reference_whole=False), fail, []
        self.ctx = Context(t_ship=5.0, h=0.08, d_max=35.0, r_max=3.0, v_max=0.1, u_ref=2.0, u_min_ratio=0.6)

    def fit(self, k, structure, start=None):
        self.fitted.append((tuple(e for e, _ in structure), None if start is None else "warm"))
        return tuple(structure)

    def step(self, ks, before, after, effect, noise_deg):
        return _step(self.fail.get(frozenset(e for e, _ in after), {}).get(effect, set()), 0.8)


def test_the_reference_step_leaves_out_a_member_below_its_floor_and_judges_the_rest():
    """A member whose step fails on its physical floor alone (an inner fold's 0.24 deg offset) is left
    out and the rest refitted from the full group's fit and judged; a member failing any other gate
    refuses the group, as does a hull term below its floor (the step needs hull terms)."""
    from pipeline.diagnose.select import _reference_group, reference_structure

    full = {e for e, _ in reference_structure(_RefSearch({}).ctx)}
    assert full == {"rudder_offset", "hull_nonlinearity", "speed_loss", "rudder_asymmetry"}
    s = _RefSearch({frozenset(full): {"rudder_offset": {"physical_floor"}}})
    first, st, step = _reference_group(s, [0], 0.1)
    assert {e for e, _ in st} == full - {"rudder_offset"} and step.passes
    assert s.fitted[-1] == (tuple(e for e, _ in st), "warm")          # from the full group's fit
    s = _RefSearch({frozenset(full): {"rudder_offset": {"physical_floor", "no_harm"}}})
    assert _reference_group(s, [0], 0.1) is None
    s = _RefSearch({frozenset(full): {"hull_nonlinearity": {"physical_floor"}}})
    assert _reference_group(s, [0], 0.1) is None
    assert _reference_group(_RefSearch({}), [0], 0.1)[1] == reference_structure(s.ctx)


def test_same_kind_left_counts_the_other_runs_of_a_runs_kind():
    """The jackknife's rule within a kind (``jackknife_same_kind``): two zigzags and a circle leave one
    zigzag beside a zigzag and no turn beside the circle."""
    import numpy as np

    from pipeline.diagnose.select import TURNING_DEG, same_kind_left

    class _Run:
        def __init__(self, swing):
            self.psi = np.array([0.0, swing])

    z1, z2, c = _Run(40.0), _Run(30.0), _Run(TURNING_DEG + 200.0)
    assert [same_kind_left(r, [z1, z2, c]) for r in (z1, z2, c)] == [1, 1, 0]
    assert same_kind_left(c, [z1, c, _Run(360.0)]) == 1


def test_the_reference_structure_is_not_split_by_the_backward_pass_where_it_is_a_candidate():
    """``reference_whole``: while every member of the reference structure is in the model, the
    backward pass drops none of them (their drop-one steps on the design's folds cannot tell what each
    carries); a member of the catalogue outside it is still judged, and without the setting the same
    failing steps drop the reference's members."""
    ref = _RefSearch({}).ctx
    steps = {"rudder_offset": _step({"physical_floor", "block_t"}, 0.14),
             "hull_nonlinearity": _step(set(), 0.86),
             "speed_loss": _step({"min_gain", "every_fold"}, 0.09),
             "rudder_asymmetry": _step(set(), 0.70),
             "rudder_lag": _step({"min_gain", "block_t"}, 0.01)}

    class _Ctx(_Search):
        ctx = ref

    def run(**over):
        cur = tuple((e, "form") for e in steps)
        cfg = dc.replace(DiagnoseConfig(), max_effects=len(cur), **over)
        out = _forward_backward(_Ctx(cfg, steps), [0], cur, None, 0.1, [(cur, None)], {}, {}, {})
        return {e for e, _ in out[0]}

    reference = {"rudder_offset", "hull_nonlinearity", "speed_loss", "rudder_asymmetry"}
    assert run(reference_whole=True) == reference
    assert run(backward_on_worth=True, reference_whole=False) == {"hull_nonlinearity", "rudder_asymmetry"}


def test_with_the_reference_as_a_candidate_a_member_below_its_floor_stays_in_the_group():
    """``reference_whole``: a member failing its physical floor alone stays in the group (not
    named, but the model judged is the whole structure), the group's step is the hull terms' (a
    passing one, so the one-standard-error rule can rank it); another failed gate still refuses it."""
    from pipeline.diagnose.select import _reference_group

    full = frozenset({"rudder_offset", "hull_nonlinearity", "speed_loss", "rudder_asymmetry"})
    s = _RefSearch({full: {"rudder_offset": {"physical_floor"}}})
    s.cfg = dc.replace(s.cfg, reference_whole=True)
    first, st, step = _reference_group(s, [0], 0.1)
    assert first == "hull_nonlinearity" and {e for e, _ in st} == full and step.passes
    s = _RefSearch({full: {"rudder_offset": {"physical_floor", "no_harm"}}})
    s.cfg = dc.replace(s.cfg, reference_whole=True)
    assert _reference_group(s, [0], 0.1) is None


def test_a_replacement_does_not_take_out_the_whole_reference():
    """``_best_swap`` tries swapping out every member but the fixed ones (the reference structure
    while whole, ``reference_whole``): with all fixed there is no swap, and ``_unsplit`` names the
    reference's members only while every one of them is in the model and the setting is on."""
    from pipeline.diagnose.select import _best_swap, _unsplit

    cur = tuple((e, "f") for e in ("rudder_offset", "hull_nonlinearity", "speed_loss", "rudder_asymmetry"))
    asked = []

    def round_(rest, against):
        asked.append({e for e, _ in rest})
        return {"nonlinear_yaw_damping": ((*rest, ("nonlinear_yaw_damping", "abs")), _step(set(), 0.5))}

    swap = _best_swap(cur, round_, fixed={"hull_nonlinearity", "speed_loss", "rudder_asymmetry"})
    assert asked == [{"hull_nonlinearity", "speed_loss", "rudder_asymmetry"}]     # the offset alone out
    assert swap[0] == "nonlinear_yaw_damping"
    assert _best_swap(cur, round_, fixed={e for e, _ in cur}) is None and len(asked) == 1
    on = _RefSearch({})
    on.cfg = dc.replace(on.cfg, reference_whole=True)
    assert _unsplit(on, cur) == {e for e, _ in cur}
    assert _unsplit(on, cur[1:]) == set()
    assert _unsplit(_RefSearch({}), cur) == set()


def test_the_reference_step_keeps_to_max_effects():
    """The reference structure (four members here) is not tried where the model may hold fewer."""
    from pipeline.diagnose.select import _reference_group

    s = _RefSearch({})
    assert _reference_group(s, [0], 0.1) is not None
    s = _RefSearch({})
    s.cfg = dc.replace(s.cfg, max_effects=3)
    assert _reference_group(s, [0], 0.1) is None and s.fitted == []


def test_the_bounded_form_comes_first_for_the_reference_structures_only():
    """``bound_reference`` (off by default, the reason at the setting): on, an unsound fit of a structure
    with the reference's hull terms is refitted in its bounded form first, one of a catalogue term in its
    anchored form; with ``bound_small_motion`` every structure in its bounded form; with neither (the
    defaults), none."""
    from pipeline.diagnose.select import Search

    ref = (("rudder_offset", "constant"), ("hull_nonlinearity", "mixed"))
    one = (("nonlinear_sway_damping", "abs"),)
    s = object.__new__(Search)
    s.cfg = dc.replace(DiagnoseConfig(), bound_reference=True)
    assert s.bounded_first(ref) and not s.bounded_first(one)
    s.cfg = dc.replace(DiagnoseConfig(), bound_small_motion=True)
    assert s.bounded_first(ref) and s.bounded_first(one)
    s.cfg = DiagnoseConfig()
    assert not s.bounded_first(ref) and not s.bounded_first(one)


def test_a_group_steps_ladder_name_follows_the_structure():
    """The ladder names a group step's effects in the structure's order, not a set's (which the
    string hash seed of each process orders: two runs of the virtual KCS wrote the reference step as
    "+hull_nonlinearity+speed_loss+..." and "+rudder_asymmetry+speed_loss+...")."""
    from pipeline.diagnose.core import rung_name

    ref = (("rudder_offset", "constant"), ("hull_nonlinearity", "abkowitz"), ("speed_loss", "power"),
           ("rudder_asymmetry", "two_sided"))
    assert rung_name((), ()) == "baseline"
    assert rung_name((), ref) == "+rudder_offset+hull_nonlinearity+speed_loss+rudder_asymmetry"
    assert rung_name(ref, ref[1:3] + (("rudder_lag", "first_order"),)) == \
        "+rudder_lag-rudder_offset-rudder_asymmetry"


def test_a_member_of_the_whole_reference_below_its_floor_is_carried_not_named():
    """``reference_names_material_only``: the whole reference's member whose drop-one step fails its
    physical floor (an asymmetry the data do not size) stays in the model but is carried, not named,
    and is never the cause; a member failing other gates only is named; a member outside the reference
    is never carried (the backward pass judges it), and neither is anything once the reference is not
    whole.  Off, every member is named."""
    from pipeline.diagnose.select import carried_members

    ref = _RefSearch({}).ctx
    steps = {"rudder_offset": _step({"no_harm"}, 0.40),
             "hull_nonlinearity": _step(set(), 0.86),
             "speed_loss": _step({"min_gain", "every_fold"}, 0.09),
             "rudder_asymmetry": _step({"physical_floor", "no_harm"}, 0.59)}

    class _Ctx(_Search):
        ctx = ref

    def carried(steps, **over):
        cur = tuple((e, "form") for e in steps)
        return carried_members(_Ctx(dc.replace(DiagnoseConfig(), **over), steps), cur, steps)

    assert carried(steps) == ("rudder_asymmetry",)
    assert carried(steps, reference_names_material_only=False) == ()
    assert carried(steps, reference_whole=False) == ()
    partial = {e: s for e, s in steps.items() if e != "speed_loss"}
    assert carried(partial) == ()
    outside = {**steps, "rudder_lag": _step({"physical_floor"}, 0.01)}
    assert carried(outside) == ("rudder_asymmetry",)
    # the hull terms stand for the group (the reference step): below their floor too they are named,
    # so a model with extensions is never reported as naming none
    small = {**steps, "hull_nonlinearity": _step({"physical_floor"}, 0.02)}
    assert carried(small) == ("rudder_asymmetry",)


def test_the_selection_names_all_but_the_carried_members_and_never_takes_the_cause_from_them(monkeypatch):
    """``Selection.named`` is the structure without ``carried``, in its order; ``select``'s cause is the
    named member of largest drop-one worth (here the asymmetry, carried, has the larger worth)."""
    from pipeline.diagnose import select as sl

    cur = tuple((e, "form") for e in ("rudder_offset", "rudder_asymmetry", "hull_nonlinearity"))
    sel = sl.Selection(structure=cur, ladder=[], alone={}, last={}, worth={}, cause="hull_nonlinearity",
                       untried={}, carried=("rudder_asymmetry",))
    assert sel.named == ["rudder_offset", "hull_nonlinearity"]

    ref = _RefSearch({}).ctx
    steps = {"rudder_offset": _step(set(), 0.30), "hull_nonlinearity": _step(set(), 0.50),
             "speed_loss": _step(set(), 0.20), "rudder_asymmetry": _step({"physical_floor"}, 0.90)}

    class _Whole(_Search):
        ctx = ref

        def choose_baseline(self, ks):
            pass

    full = tuple((e, "form") for e in steps)
    cfg = dc.replace(DiagnoseConfig(), max_effects=len(full))
    search = _Whole(cfg, steps)
    # the passes themselves stubbed: they end on the whole reference
    monkeypatch.setattr(sl, "_forward_backward",
                        lambda s, ks, cur, *a: (full, full, {}, {}, [((), None), (full, None)], False))
    out = sl.select(search, [0], 0.1)
    assert out.carried == ("rudder_asymmetry",) and out.cause == "hull_nonlinearity", (out.carried, out.cause)
    assert out.named == ["rudder_offset", "hull_nonlinearity", "speed_loss"]
