"""Extensions sound at every amplitude (docs/diagnosis.md, "Sound at every amplitude").

The truth here is a measured manoeuvre, not a formula of the method: the HSVA KVLCC2's 1 deg zigzag
10/1, which no fit below sees.  Fitted freely on the catalog design's training runs (10 to 35 deg
rudder), nonlinear sway damping buys its large zigzags with a course-unstable linear part and runs
away on 10/1; its anchored form holds there."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipeline.config import DiagnoseConfig
from pipeline.diagnose.effects import BY_NAME, Context
from pipeline.diagnose.fit import Layout, growth_rate, structure_of


def test_growth_rate_is_the_least_stable_eigenvalue():
    # diagonal: the eigenvalues are the diagonal, the largest real part wins
    assert growth_rate([-0.5, 0.0, 0.0, -2.0, 0, 0]) == pytest.approx(-0.5)
    # a12 a21 > a11 a22: course-unstable; eigenvalues of [[-1, -1], [-3, -1]] are -1 +- sqrt(3)
    assert growth_rate([-1.0, -1.0, -3.0, -1.0, 0, 0]) == pytest.approx(-1.0 + np.sqrt(3.0))
    # complex pair -0.2 +- 1j: the real part
    assert growth_rate([-0.2, 1.0, -1.0, -0.2, 0, 0]) == pytest.approx(-0.2)
    assert growth_rate([np.nan, 0, 0, -1, 0, 0]) == np.inf


def test_anchored_layout_holds_the_linear_part_and_signs_the_damping():
    ctx = Context(t_ship=10.0, h=0.1, d_max=20.0, r_max=2.0, v_max=0.2, u_ref=1.0, u_min_ratio=0.8)
    st = structure_of("nonlinear_sway_damping", "sway_yaw_coupling")
    free_lo, free_hi = Layout(st, ctx).bounds()
    hold = (-0.03, -0.002, -0.5, -0.09)
    lo, hi = Layout(st, ctx, hold_linear=hold).bounds()
    assert np.allclose(lo[:4], hold, rtol=1e-8) and np.allclose(hi[:4], hold, rtol=1e-8)
    assert np.all(lo[:4] < hi[:4])                   # least_squares needs lo < hi
    names = Layout(st, ctx).names
    signed = {"y_vv_per_m", "y_vrr_s2_per_deg2", "n_vvr_s_per_m2"}
    for i, n in enumerate(names[6:], start=6):
        if n in signed:
            assert hi[i] == 0.0 and free_hi[i] > 0.0, n     # damping damps, in the anchored form only
        else:
            assert hi[i] == free_hi[i] and lo[i] == free_lo[i], n
    # which parameters are damping: the physics says so, per effect (a coupling has either sign)
    damping = {p.name for e in BY_NAME.values() for f in e.forms for p in f.params if p.damping}
    assert damping == signed | {"n_rrr_s_per_deg2", "n_rr_per_deg", "y_var_per_deg", "n_avr_per_m"}


@pytest.fixture(scope="module")
def hsva_fold(hsva_dir):
    from pipeline.cli.diagnose import load_run
    from pipeline.diagnose.core import _context
    from pipeline.diagnose.design import pick_catalog_runs
    from pipeline.diagnose.fit import series_from_run, with_initial_states

    runs = {p.stem: load_run(p) for p in sorted(hsva_dir.glob("*.dat"))}
    keys = ("kind", "rudder_deg", "heading_deg", "first_side")
    entries = [{"run_id": k, **{m: r.meta.get(m) for m in keys}} for k, r in runs.items()]
    tr, va, _ = pick_catalog_runs(entries)
    train = [series_from_run(runs[k]) for k in tr]
    small = series_from_run(runs["HSVA_CPMC_KVLCC2_Z_10_01"])
    assert small.name in va                          # the catalog rule holds it out of this fold
    cfg = DiagnoseConfig()
    ctx = _context(train + [series_from_run(runs[k]) for k in va])
    *train, small = with_initial_states(train + [small], cfg.x0_window_T * ctx.t_ship, None, cfg.x0_box_sigma)
    return train, small, ctx, cfg


@pytest.mark.slow
# make test: anchored at the best linear model (the default); anchored at the bounded fit in make test-long
@pytest.mark.parametrize("bounded", [pytest.param(True, marks=pytest.mark.long, id="bounded_baseline"),
                                     pytest.param(False, id="best_linear_baseline")])
def test_sway_damping_runs_away_at_small_amplitude_in_the_free_form_and_holds_anchored(hsva_fold, bounded):
    """Anchored at the bounded linear fit or at the unconstrained one (the best linear model on the HSVA
    selection: docs/diagnosis.md, "The baseline"), the anchored form makes the 1 deg zigzag the free
    form runs away on."""
    from pipeline.diagnose.fit import evaluate
    from pipeline.diagnose.select import Fold, Search, ran_away

    train, small, ctx, cfg = hsva_fold
    st = structure_of("nonlinear_sway_damping")
    out = {}
    for anchor in (False, True):
        search = Search([Fold(train, [small])], ctx, replace(cfg, anchor_small_motion=anchor),
                        baseline_bounded=bounded)
        base = search.linear(0)
        ext = search.fit(0, st, start=search.fit(0, ()))
        mb = evaluate(base, [small])[0]["mae_psi_deg"]
        me = evaluate(ext, [small])[0]["mae_psi_deg"]
        out[anchor] = (base, ext, mb, me, ran_away(small, mb, me), search.growth_allowance(0),
                       search.other_linear(0))
    base, free, mb, me, away, allow, _ = out[False]
    # the free form: the linear part refitted course-unstable (measured: growth rate -0.032 -> +0.018
    # 1/s, a21 0 -> -2.80), held up at large amplitude by the added terms; on the unseen 1 deg zigzag
    # its heading error grows by more than the run's heading swing (measured 5.3 -> 28.3 deg)
    assert free.hold_linear is None
    assert growth_rate(base.theta) < 0.0 < growth_rate(free.theta)
    assert growth_rate(free.theta) > allow
    assert away, (mb, me)
    # the anchored form: the linear part is a linear fit's (DiagnoseConfig.anchor_either_linear: the
    # baseline's or the fold's other one, the lower training cost), the sway damping damps, and the
    # 1 deg zigzag is made (no run-away).  With the bounded fit as the baseline it is better there than
    # that baseline (measured 5.32 -> 5.05 deg held at the bounded fit; since anchor_either_linear it is
    # held at the unconstrained fit); with the unconstrained fit as the baseline, which predicts 10/1 at
    # 1.74 deg, the anchored form keeps it within the run's swing (measured 1.92 deg), where the free
    # form ran away
    base, held, mb, me, away, _, other = out[True]
    assert held.hold_linear is not None
    anchors = [base] + ([other] if other is not None else [])
    assert any(np.allclose(held.theta[:4], a.theta[:4], rtol=1e-6, atol=1e-8) for a in anchors), \
        (held.theta[:4], [a.theta[:4] for a in anchors])
    assert held.values["nonlinear_sway_damping"]["y_vv_per_m"] <= 0.0
    assert not away, (mb, me)
    if bounded:
        assert me < mb, (mb, me)


def _response_gap(base, ext, small, k: float) -> float:
    """Largest |psi_ext - psi_base| over max |psi_base| (both free runs from rest, no speed factor) under
    the run's rudder about its approach value, scaled by ``k``: how far the extension is from the
    baseline at k times the run's amplitude."""
    from pipeline.diagnose.extended import simulate_terms

    rudder = k * (small.delta - small.delta[:20].mean())
    x0 = np.zeros(3)
    pb = simulate_terms(base.theta, base.terms, x0, small.t, rudder, None)[:, 2]
    pe = simulate_terms(ext.theta, ext.terms, x0, small.t, rudder, None)[:, 2]
    return float(np.max(np.abs(pe - pb)) / np.max(np.abs(pb)))


@pytest.mark.slow
def test_the_anchored_form_is_the_baseline_at_small_motion_only_with_its_rudder_gains_held(hsva_fold):
    """The anchored sway damping of the same fold, anchored at the best linear model: with the rudder
    gains b11, b21 refitted (``DiagnoseConfig.anchor_rudder_gains`` off) the extension does not tend to
    the baseline as the motion vanishes: the gains it bought at large amplitude stay, and under the 1 deg
    zigzag's rudder scaled down a hundredfold it is as far from the baseline as at full size (measured:
    27 % at full size, 62 % at 1/100).  With them held (the default) its added terms vanish at small
    motion as a hull's do: the gap falls with the amplitude (second-order terms: in proportion; measured
    15 % -> 0.19 %), and the 1 deg zigzag the fit never saw is predicted better (1.92 -> 1.65 deg against
    the baseline's 1.74 deg).  The truth is the scaling law of a term of second order, not a fitted
    value: at 1/100 of the amplitude its share of the response is about 1/100, and a tenfold drop is
    asked."""
    from pipeline.diagnose.fit import evaluate
    from pipeline.diagnose.select import Fold, Search, ran_away

    train, small, ctx, cfg = hsva_fold
    st = structure_of("nonlinear_sway_damping")
    gaps, maes = {}, {}
    for held in (False, True):
        search = Search([Fold(train, [small])], ctx, replace(cfg, anchor_rudder_gains=held),
                        baseline_bounded=False)
        base = search.linear(0)
        ext = search.fit(0, st, start=search.fit(0, ()))
        assert ext.hold_linear is not None and len(ext.hold_linear) == (6 if held else 4)
        assert np.allclose(ext.theta[:4], base.theta[:4], rtol=1e-6, atol=1e-8)
        gaps[held] = [_response_gap(base, ext, small, k) for k in (1.0, 0.01)]
        mb, me = (evaluate(f, [small])[0]["mae_psi_deg"] for f in (base, ext))
        assert not ran_away(small, mb, me), (held, mb, me)
        maes[held] = me
        if held:
            assert np.allclose(ext.theta[4:], base.theta[4:], rtol=1e-6, atol=1e-8)   # held to 1e-9
    assert gaps[False][1] > 0.1 * gaps[False][0], gaps       # today's gains: no vanishing at small motion
    assert gaps[True][1] < 0.1 * gaps[True][0], gaps         # held: the added terms vanish with the motion
    assert maes[True] < maes[False], maes


def test_the_anchored_form_holds_the_linear_fit_that_fits_the_training_runs_better():
    """``DiagnoseConfig.anchor_either_linear``: the anchored form is fitted held at each of the fold's two
    linear fits (with and without the ship-sign bounds) and the one of least TRAINING cost is kept.
    Truth: the bench case's seeded offset and cubic yaw damping (tests nothing of the tanker it was
    measured on), two 80 s zigzags training, sway damping anchored.  With the bounded fit as the
    reported baseline the bounded anchor leaves the training runs far worse fitted than the
    unconstrained one (measured 1.094 against 0.215): on, the unconstrained anchor is held; off, the
    baseline's.  With the unconstrained fit as the baseline both settings hold it."""
    import dataclasses as dc

    from pipeline.diagnose import TruthConfig, zigzag_truth
    from pipeline.diagnose.core import _context
    from pipeline.diagnose.fit import series_from_run, with_initial_states
    from pipeline.diagnose.select import Fold, Search
    from pipeline.diagnose.truth import damping_for_cut

    truth = TruthConfig(seed=5, rudder_offset=2.0, n_rrr=damping_for_cut(0.3))
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
    ser = [series_from_run(zigzag_truth(a, a, s, 80.0, dc.replace(truth, seed=truth.seed + j)))
           for j, (a, s) in enumerate(legs)]
    ctx = _context(ser)
    cfg = DiagnoseConfig()
    ser = with_initial_states(ser, cfg.x0_window_T * ctx.t_ship, None, cfg.x0_box_sigma)
    st = structure_of("nonlinear_sway_damping")
    for bounded in (True, False):
        fits = {}
        for on in (False, True):
            search = Search([Fold(ser[:2], ser[2:])], ctx, replace(cfg, anchor_either_linear=on),
                            baseline_bounded=bounded)
            fits[on] = search._anchored(0, st, [])
            base, other = search.linear(0), search.other_linear(0)
        assert np.allclose(fits[False].hold_linear, base.theta[:6], rtol=1e-9, atol=1e-12)
        winner = other if bounded else base
        assert np.allclose(fits[True].hold_linear, winner.theta[:6], rtol=1e-9, atol=1e-12)
        assert fits[True].cost <= fits[False].cost
        if bounded:
            assert fits[True].cost < 0.5 * fits[False].cost, (fits[True].cost, fits[False].cost)
