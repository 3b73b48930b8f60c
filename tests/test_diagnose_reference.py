"""The reference fit beside the selection (docs/diagnosis.md, "The reference fit"): the catalogue's terms
told everything at once, measured on the same held-out runs as the selection.

The known answer is the virtual tank's: its hull is the MMG model of the KCS (pipeline.tank), nonlinear
in v and r, and it slows in turns, so a model with the hull's nonlinear terms predicts its held-out
mirror runs far better than the best linear model does.  The MMG model is not written in the
reference's terms (its forces are polynomials in the drift angle and the non-dimensional yaw rate, its
rudder and propeller are their own models), so the cut is a property of the tank, not of the method's
formulas."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from tank_search import tank_search  # the virtual tank's runs as a two-fold search

from pipeline import tank
from pipeline.config import DiagnoseConfig
from pipeline.diagnose.core import _Design, reference_fit
from pipeline.diagnose.effects import REFERENCE, Context
from pipeline.diagnose.fit import FitMemo
from pipeline.diagnose.select import Fold, Search, heading_noise_deg


def _design(search):
    return _Design(search.folds, [], search.ctx, search.cfg,
                   heading_noise_deg(search.folds[0].val, search.ctx.t_ship), FitMemo())


@pytest.mark.slow
def test_reference_fit_on_the_virtual_tank_is_the_known_answer():
    """The virtual KCS's 20/20 and 10/10 zigzags, each fold validated on the mirror runs: the reference
    structure fitted on two runs predicts the two it has not seen at under half the best linear model's
    error, in each fold.  Half: a hull whose nonlinear terms are right leaves the error of its
    linear part's estimate and of the tank's terms the reference lacks (the propeller's and the
    rudder's own nonlinearity), not the bulk of the linear model's (measured: best linear 6.43 / 3.35
    deg, the reference 0.45 / 0.82 deg, -87 % pooled)."""
    legs = ([tank.zigzag(20, 20, "starboard", duration=80.0), tank.zigzag(10, 10, "port", duration=80.0)],
            [tank.zigzag(20, 20, "port", duration=80.0), tank.zigzag(10, 10, "starboard", duration=80.0)])
    s = tank_search(*legs, best_linear_baseline=True)
    s.choose_baseline([0, 1])
    ref = reference_fit(_design(s), s, [0, 1], adequate=False)
    assert ref.computed and ref.reason is None
    # the structure: every effect of REFERENCE applies (v and u measured, the tank slows in turns)
    assert set(ref.effects) == {e for e, _ in REFERENCE}
    assert len(ref.per_fold) == 2
    for k, f in enumerate(ref.per_fold):
        # beside the reported baseline (the best linear model), on the same validation runs
        assert f.baseline_mae_psi_deg == pytest.approx(s.linear_eval(k)[0]["mae_psi_deg"])
        assert f.validation_runs == [x.name for x in s.folds[k].val]
        assert f.reference_mae_psi_deg < 0.5 * f.baseline_mae_psi_deg, f
    assert ref.validation_mae_psi_relative_reduction > 0.5, ref
    assert ref.material is True and ref.material_threshold == s.cfg.min_gain


def test_reference_fit_is_not_made_where_it_has_nothing_to_carry():
    """Not made where the baseline is adequate, nor where it is switched off, nor without v; each says
    why, and no fit is made."""
    ctx = Context(t_ship=10.0, h=0.1, d_max=20.0, r_max=2.0, v_max=0.1, u_ref=1.0, u_min_ratio=0.8)
    cases = ((ctx, DiagnoseConfig(), True, "adequate"),
             (ctx, DiagnoseConfig(reference_fit=False), False, "reference_fit"),
             (replace(ctx, v_measured=False), DiagnoseConfig(), False, "sway velocity"))
    for c, cfg, adequate, why in cases:
        s = Search([Fold([], [])], c, cfg, baseline_bounded=True)
        ref = reference_fit(_Design(s.folds, [], c, cfg, 0.05, FitMemo()), s, [0], adequate=adequate)
        assert not ref.computed and why in ref.reason and s._fits == {}, ref
        assert ref.validation_mae_psi_deg is None and ref.per_fold == []
    assert "hull_nonlinearity" not in ref.effects


def _truth_search(cfg: DiagnoseConfig) -> Search:
    """Two folds of the LINEAR truth model (pipeline.diagnose.truth, the paper's Table 4 hull, noise on):
    20/20 starboard and 10/10 port train, their mirror runs validate, and the reverse."""
    from pipeline.diagnose.core import _context
    from pipeline.diagnose.fit import series_from_run, with_initial_states
    from pipeline.diagnose.truth import TruthConfig, zigzag_truth

    def leg(seed, first):
        return [series_from_run(zigzag_truth(a, a, side, duration=60.0, cfg=TruthConfig(seed=seed + i)))
                for i, (a, side) in enumerate(((20, first), (10, "port" if first == "starboard" else
                                                             "starboard")))]

    tr, va = leg(1, "starboard"), leg(3, "port")
    ctx = _context(tr + va)
    tr, va = (with_initial_states(x, cfg.x0_window_T * ctx.t_ship, cfg.x0_model_window_T * ctx.t_ship,
                                  cfg.x0_box_sigma) for x in (tr, va))
    return Search([Fold(tr, va), Fold(va, tr)], ctx, cfg)


def test_reference_fit_on_a_linear_ship_is_not_material_and_the_report_says_so():
    """The known answer is the truth's: its hull is linear, so the catalogue's terms told everything at
    once have nothing to carry, and on the runs they did not see they cannot cut the best linear
    model's error by the 10 % a model change needs (``reference.material`` false; the fit is forced
    here, as the stage makes it only where the baseline is inadequate).  Where the verdict is none the
    report then says plainly that what the linear model lacks is not in the catalogue, with the honest
    gain and its interval; where the verdict names a cause, or the reference is material, it does not.
    Measured: best linear 0.042 / 0.043 deg held out, the reference 0.045 / 0.049 deg (-11 % pooled:
    eight hull terms, an offset and a rudder asymmetry fitted to the noise of two runs)."""
    from pipeline.report import diagnosis_text as dt

    cfg = DiagnoseConfig()
    s = _truth_search(cfg)
    s.choose_baseline([0, 1])
    ref = reference_fit(_design(s), s, [0, 1], adequate=False)
    assert ref.computed, ref
    assert ref.material_threshold == cfg.min_gain
    assert ref.validation_mae_psi_relative_reduction < cfg.min_gain, ref
    assert ref.material is False
    ref = ref.to_json()
    # the sentence, from those keys and the honest gain's (a test-run case as the stage writes it)
    dg = {"cause": "none", "reference": ref, "ladder": [{"validation_mae_psi_deg": 1.0}],
          "test_runs": ["t1"], "extended": {"effects": []},
          "gain": {"mae_psi_relative_reduction": 0.0, "interval_95": [-0.02, 0.03], "measured_on": ["t1"],
                   "baseline_mae_psi_deg": 2.905, "extended_mae_psi_deg": 2.905}}
    text = dt.reference_text(dg)
    assert text.startswith("Reference fit (not chosen:")
    # the selection that took the reference's structure (its step) is said to have chosen it; the
    # same effects in another form are not that structure
    took = {"effects": list(ref["effects"]), "forms": dict(ref["forms"])}
    assert dt.reference_text(dg | {"extended": took}).startswith(
        "Reference fit (the structure the selection chose:")
    other = {"effects": list(ref["effects"]), "forms": {e: "other" for e in ref["forms"]}}
    assert dt.reference_text(dg | {"extended": other}).startswith("Reference fit (not chosen:")
    # a member the model carries without naming it (extended.carried) is still in the structure
    last = ref["effects"][-1]
    carrying = took | {"effects": list(ref["effects"][:-1]), "carried": [last]}
    assert dt.reference_text(dg | {"extended": carrying}).startswith(
        "Reference fit (the structure the selection chose:")
    assert dt.carried_text(carrying) == ("; also carried, not named (below its physical floor): "
                                         + dt.effect_label(last))
    assert dt.carried_text(took) == "" and dt.carried_text({"carried": []}) == ""
    reading = dt.reference_reading(dg)
    assert reading and reading in text
    assert "not carried by the catalogue" in reading and "short of the 10 % cut" in reading
    # measured -11 %: said as the worse error it is
    assert f"worse by {dt.pct(-ref['validation_mae_psi_relative_reduction'])}" in reading
    assert "cuts the baseline's held-out heading error by only 4 %" in dt.reference_reading(
        dg | {"reference": ref | {"validation_mae_psi_relative_reduction": 0.04}})
    assert "[-2 %, 3 %]" in reading and "2.905 deg" in reading      # the honest gain and its interval
    assert dt.reference_reading(dg | {"cause": "rudder_offset"}) == ""
    assert dt.reference_reading(dg | {"reference": ref | {"material": True}}) == ""
    assert dt.reference_reading(dg | {"reference": ref | {"material": None, "computed": False}}) == ""


#: the drop-one structures of the reference on the virtual tank's default design (docs/diagnosis.md,
#: "Known limits", the turning circles): the reference without its hull terms, and its hull terms
#: without the sway cross-flow drag v|v| (r|r| and the cross terms kept)
_OFFSET, _SPEED = ("rudder_offset", "constant"), ("speed_loss", "power")
_DROP = {"reference": REFERENCE, "without hull terms": (_OFFSET, _SPEED),
         "without v|v|": (_OFFSET, _SPEED, ("nonlinear_yaw_damping", "abs"),
                          ("sway_yaw_coupling", "abkowitz"))}


@pytest.mark.slow
@pytest.mark.long
def test_what_brings_the_turning_circles_down_in_the_reference():
    """The virtual tank's six selection runs in the design's two folds (three training, three held-out
    runs each, a 35 deg turning circle on each side): refitted without its hull terms, the reference
    predicts each held-out circle worse than with them (measured 2026-11-28, the mixed hull form: port
    11.38 against 2.58 deg, starboard 19.58 against 3.51), and with the hull terms but without the sway
    cross-flow drag v|v| each circle far worse (port 12.87 deg) or not at all (starboard: 6186 deg).
    Until 2026-11-27 both circles diverged without v|v|; with the libraries of 2026-11-28 (numpy 2.4,
    scipy 1.17) the port one lands at 12.87 deg, the same fit at another optimum (the same at the
    code of 7338ee8, checked).  The truth is the tank's MMG hull, whose cross-flow drag
    grows with the drift of a steady turn; nothing here is written in the reference's formulas."""
    from pipeline.config import TankConfig
    from pipeline.diagnose.core import _context
    from pipeline.diagnose.design import pick_catalog_runs
    from pipeline.diagnose.fit import (
        evaluate,
        fit_structure,
        series_from_run,
        structure_of,
        with_initial_states,
    )
    from pipeline.tank.manoeuvres import selection_set

    runs = {}
    for m in selection_set():
        r = tank.simulate(m, TankConfig())
        runs[r.meta["run_id"]] = r
    keys = ("kind", "rudder_deg", "heading_deg", "first_side")
    a, b, _ = pick_catalog_runs([{"run_id": k, **{m: r.meta.get(m) for m in keys}} for k, r in runs.items()])
    cfg = DiagnoseConfig()
    tr, va = [series_from_run(runs[k]) for k in a], [series_from_run(runs[k]) for k in b]
    ctx = _context(tr + va)
    tr, va = (with_initial_states(x, cfg.x0_window_T * ctx.t_ship, cfg.x0_model_window_T * ctx.t_ship,
                                  cfg.x0_box_sigma) for x in (tr, va))
    s = Search([Fold(tr, va), Fold(va, tr)], ctx, cfg, memo=FitMemo())
    s.choose_baseline([0, 1])
    circle = {}
    for name, st in _DROP.items():
        for k in (0, 1):
            f = fit_structure(s.folds[k].train, structure_of(*st), ctx, start=s.fit(k, ()),
                              max_nfev=cfg.max_nfev, block_T=cfg.block_T, sign_bounds=s.family_bounds,
                              memo=s.memo)
            for p in evaluate(f, s.folds[k].val)[1]:
                if "turning" in p["run_id"]:
                    circle[(name, p["run_id"])] = p["mae_psi_deg"]
    circles = sorted({run for _, run in circle})
    assert len(circles) == 2, circle
    unmade = 0
    for run in circles:
        swing = float(np.ptp(next(x for x in tr + va if x.name == run).psi))
        assert circle[("reference", run)] < circle[("without hull terms", run)], circle
        # without v|v| the circle is predicted far worse (threefold: more than the sampling of a
        # refit moves it), and not made at all (an error beyond the run's whole heading swing) on one
        # side at least
        assert circle[("without v|v|", run)] > 3.0 * circle[("reference", run)], circle
        unmade += circle[("without v|v|", run)] > swing
    assert unmade >= 1, circle


def test_the_nested_reference_figure_is_made_over_every_held_out_run_or_not_at_all():
    """``reference.nested_*`` pools the reference over the honest gain's held-out runs against the same
    baseline evaluations, or is not given: a figure over some of the runs would be no figure of the
    protocol.  Known answer: two runs where the reference halves a 2 deg and a 4 deg error, gain 50 %."""
    from pipeline.diagnose.core import _reference_nested
    from pipeline.diagnose.fit import Series

    def run(name, err_b, err_r):
        n = 400
        s = Series(name, np.arange(n) * 0.1, np.zeros(n), np.zeros(n), np.zeros(n))
        ev = []
        for err in (err_b, err_r):
            sim = np.zeros((n, 3))
            sim[:, 2] = err
            ev.append([{"sim": sim, "mae_psi_deg": err}])
        return [s], ev[0], ev[1]

    refs = [run("a", 2.0, 1.0), run("b", 4.0, 2.0)]
    got = _reference_nested(refs, DiagnoseConfig(), block_s=5.0)
    assert got["measured_on"] == ["a", "b"]
    assert got["baseline_mae_psi_deg"] == pytest.approx(3.0) and got["mae_psi_deg"] == pytest.approx(1.5)
    assert got["mae_psi_relative_reduction"] == pytest.approx(0.5)
    lo, hi = got["interval_95"]
    assert lo <= 0.5 <= hi
    assert _reference_nested([refs[0], None], DiagnoseConfig(), block_s=5.0) is None
    assert _reference_nested([], DiagnoseConfig(), block_s=5.0) is None


def test_a_material_reference_beside_a_none_says_the_cause_was_not_named():
    """Where the verdict is none but the reference, measured under the honest gain's protocol, cuts the
    baseline's error by at least the material threshold at 95 % (the virtual KCS: 9.68 -> 2.08 deg,
    79 % [74 %, 82 %]), the report says the catalogue's terms carry the error together and that none
    means the cause could not be named; with an interval reaching below the threshold, or a cause
    named, it says nothing of the kind."""
    from pipeline.report import diagnosis_text as dt

    ref = {"computed": True, "material": True, "material_threshold": 0.1,
           "nested_mae_psi_relative_reduction": 0.43, "nested_interval_95": [0.30, 0.53]}
    dg = {"cause": "none", "reference": ref}
    reading = dt.reference_reading(dg)
    assert "taken together" in reading and "at least 30 % at 95 %" in reading and "10 %" in reading
    assert "not that the linear model will do" in reading
    assert dt.reference_reading(dg | {"reference": ref | {"nested_interval_95": [0.05, 0.53]}}) == ""
    assert dt.reference_reading(dg | {"reference": ref | {"nested_interval_95": None}}) == ""
    assert dt.reference_reading(dg | {"cause": "hull_nonlinearity"}) == ""
