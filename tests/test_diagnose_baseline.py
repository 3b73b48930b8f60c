"""The linear baseline is the best linear model on the selection's runs (docs/diagnosis.md, "The
baseline"): fitted with and without the ship-sign bounds, the one of lower held-out error is kept."""

from __future__ import annotations

import pytest
from tank_search import tank_search  # the virtual tank's runs as a two-fold search

from pipeline import tank
from pipeline.config import DiagnoseConfig
from pipeline.diagnose.core import _adequacy, residual_structure
from pipeline.diagnose.effects import Context
from pipeline.diagnose.fit import evaluate
from pipeline.diagnose.select import Search, heading_noise_deg


@pytest.mark.slow
def test_the_baseline_is_the_unconstrained_fit_where_the_bound_cripples_it():
    """The virtual KCS's 20/20 and 10/10 zigzags (its hull nonlinear in v and r): the linear fit with
    the sign bounds sits on a21 = 0, and the unconstrained one predicts the held-out mirror runs far
    better (measured: 12.8 / 7.5 deg against 6.4 / 3.4 deg in the two folds), so the unconstrained fit
    is the best linear model, the reported baseline (DiagnoseConfig.best_linear_baseline), with the
    bounded one kept beside it; switched off, the reverse.  The selection's structures keep the bounds
    unless DiagnoseConfig.family_follows_baseline.  Even so the best linear model is not adequate there
    (4.9 deg pooled against a 1 deg limit of ten noise floors)."""
    legs = ([tank.zigzag(20, 20, "starboard", duration=80.0), tank.zigzag(10, 10, "port", duration=80.0)],
            [tank.zigzag(20, 20, "port", duration=80.0), tank.zigzag(10, 10, "starboard", duration=80.0)])
    # switched off, the bounded fit is the reported baseline, the better one beside it
    d = tank_search(*legs, best_linear_baseline=False)
    d.choose_baseline([0, 1])
    assert d.baseline_bounded is True and d.best_bounded is False
    assert d.linear(0) is d.fit(0, ()) and not d.other_linear(0).sign_bounds
    s = tank_search(*legs)
    s.choose_baseline([0, 1])
    assert s.baseline_bounded is False and s.best_bounded is False and s.family_bounds is True
    for k in (0, 1):
        base, other = s.linear(k), s.other_linear(k)
        assert not base.sign_bounds and other.sign_bounds
        assert "a21" in other.at_bound and base.at_bound == ()
        # the selection's own linear rung keeps the bounds (every extension contains it)
        assert s.fit(k, ()) is other and s.bounded(k) is other
        mb = s.linear_eval(k)[0]["mae_psi_deg"]
        mo = s.linear_eval(k, bounded=True)[0]["mae_psi_deg"]
        assert mo == pytest.approx(evaluate(other, s.folds[k].val)[0]["mae_psi_deg"])
        assert mb < 0.7 * mo, (mb, mo)
    # the family following the baseline: its linear rung is the unconstrained fit, the bounded beside it
    f = tank_search(*legs, family_follows_baseline=True)
    f.choose_baseline([0, 1])
    assert f.family_bounds is False
    for k in (0, 1):
        assert f.fit(k, ()) is f.linear(k) and not f.linear(k).sign_bounds
        assert f.bounded(k) is f.other_linear(k) and f.bounded(k).sign_bounds
        assert f.linear_eval(k)[0]["mae_psi_deg"] == pytest.approx(s.linear_eval(k)[0]["mae_psi_deg"])
    # even the best linear model is far off on these runs (its hull is nonlinear): not adequate, and
    # its residual follows hull signatures
    pooled = sum(s.linear_eval(k)[0]["mae_psi_deg"] for k in (0, 1)) / 2
    noise = heading_noise_deg(s.folds[0].val, s.ctx.t_ship)
    res = residual_structure(s.linear(0), s.folds[0].val, s.linear_eval(0)[1], s.ctx)
    a = _adequacy(pooled, noise, s.cfg, res).to_json()
    assert a["adequate"] is False and pooled > a["threshold_deg"], a
    assert {x["effect"] for x in a["signatures"]} & {"nonlinear_sway_damping", "sway_yaw_coupling",
                                                      "nonlinear_yaw_damping", "speed_loss"}, a


def test_a_given_choice_is_not_made_again():
    """A Search told its baseline (the honest gain's refits, the jackknife) keeps it: no fit is made."""
    ctx = Context(t_ship=10.0, h=0.1, d_max=20.0, r_max=2.0, v_max=0.1)
    for given in (True, False):
        s = Search([], ctx, DiagnoseConfig(), baseline_bounded=given)
        s.choose_baseline([0])
        assert s.baseline_bounded is given and s._fits == {}
