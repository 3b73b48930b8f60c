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

    def __init__(self, cfg, steps):
        self.cfg, self.steps, self._fits = cfg, steps, {}

    def fit(self, k, structure, start=None):
        return None

    def refine(self, k, smaller, richer):
        return False

    def step(self, ks, before, after, effect, noise_deg):
        return self.steps[effect]


def _backward(steps: dict, **over) -> tuple:
    cur = tuple((e, "form") for e in steps)
    cfg = dc.replace(DiagnoseConfig(), max_effects=len(cur), **over)
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
    assert _backward(steps) == ("hull_nonlinearity",)
    assert _backward(steps, backward_on_worth=True) == ("rudder_offset", "hull_nonlinearity")


def test_soundness_failures_alone_never_remove_on_worth():
    for code in set(CODES) - set(WORTH):
        steps = {"rudder_offset": _step({code}, 0.3), "rudder_lag": _step(set(), 0.3)}
        assert _backward(steps, backward_on_worth=True) == ("rudder_offset", "rudder_lag"), code
        assert _backward(steps) == ("rudder_lag",), code
