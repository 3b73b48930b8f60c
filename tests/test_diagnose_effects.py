"""The open effect catalogue: every effect object is complete, its term in the equations of motion does
what its module says, its null values give the baseline, and the kernel's feature copy is the definition."""

from __future__ import annotations

import importlib
import pkgutil

import numpy as np
import pytest

import pipeline.diagnose.effects as effects_pkg
from pipeline.diagnose.effects import BY_NAME, CATALOGUE, FEATURES, TRIAL, Context, Terms, feature_value
from pipeline.diagnose.extended import simulate_extended, simulate_terms
from pipeline.model import PAPER_TABLE4

SPEC_NAMES = {
    "rudder_offset",
    "nonlinear_yaw_damping",
    "rudder_delay",
    "rudder_lag",
    "speed_loss",
    "nonlinear_sway_damping",
    "sway_yaw_coupling",
    "rudder_saturation",
    "rudder_asymmetry",
}
#: effects the open catalogue has beyond docs/diagnosis.md's table ("open: more may be added, each with its
#: own name")
OPEN_NAMES = {"heading_misalignment"}
TRIAL_NAMES = {e.name for e in TRIAL}      # built and tested, not tried by the selection
CTX = Context(t_ship=5.0, h=0.08, d_max=20.0, r_max=3.0, v_max=0.1, u_ref=2.0, u_min_ratio=0.85)
THETA = np.array(list(PAPER_TABLE4.values()))
T = np.arange(1200) * 0.08
DELTA = np.clip(25 * np.sin(2 * np.pi * T / 25.0), -20, 20)
U_RATIO = 1.0 - 0.15 * np.sin(np.pi * T / T[-1])


def test_catalogue_is_the_spec_list_one_module_each():
    assert {e.name for e in CATALOGUE} == SPEC_NAMES | OPEN_NAMES
    assert len(BY_NAME) == len(CATALOGUE) + len(TRIAL) and TRIAL_NAMES == {"hull_nonlinearity"}
    modules = {m.name for m in pkgutil.iter_modules(effects_pkg.__path__)} - {"base"}
    assert modules == SPEC_NAMES | OPEN_NAMES | TRIAL_NAMES  # one module per effect, named as the effect
    for name in modules:
        assert importlib.import_module(f"pipeline.diagnose.effects.{name}").EFFECT is BY_NAME[name]


@pytest.mark.parametrize("effect", CATALOGUE + TRIAL, ids=lambda e: e.name)
def test_effect_object_is_complete(effect):
    assert effect.words and effect.term and effect.signature and effect.floor_reason
    for form in effect.forms:
        for p in form.params:
            lo, hi = p.bounds(CTX)
            assert lo <= p.null <= hi and lo <= p.start_value(CTX) <= hi, p
            assert p.unit and p.name
            if p.unit != "1":
                assert "_" in p.name  # the unit is in the name
        vals = {p.name: (p.bounds(CTX)[1] * 0.3 if p.bounds(CTX)[1] > 0 else 0.1) for p in form.params}
        ok, text = effect.material(form, vals, CTX, 0.2)
        assert isinstance(ok, bool) and text
        sentence = effect.physical(form, vals, CTX)
        assert isinstance(sentence, str) and len(sentence) > 30


@pytest.mark.parametrize("effect", CATALOGUE + TRIAL, ids=lambda e: e.name)
def test_null_values_give_the_baseline_exactly(effect):
    base = simulate_terms(THETA, Terms(), (0, 0, 0), T, DELTA, U_RATIO)
    for form in effect.forms:
        terms = Terms()
        effect.apply(form, {p.name: p.null for p in form.params}, terms)
        np.testing.assert_allclose(
            simulate_terms(THETA, terms, (0, 0, 0), T, DELTA, U_RATIO), base, atol=1e-12
        )


@pytest.mark.parametrize("y_vv,drag", [(-2.0, True), (+1.24, False)])
def test_sway_damping_reading_follows_the_sign_of_its_estimate(y_vv, drag):
    """Cross-flow drag opposes the drift (y_vv < 0): only then is the term read as damping.  A fitted
    y_vv > 0 (measured 2026-11-26 on a user's two 20/20 KCS zigzags: +1.24 1/m, named at +92 % on one
    validation run) pushes the drift further and must not be read as "drift limited more"."""
    eff = BY_NAME["nonlinear_sway_damping"]
    text = eff.physical(eff.form(), {"y_vv_per_m": y_vv, "n_vv_deg_per_m2": 14.1}, CTX)
    assert ("cross-flow drag:" in text and "limited more" in text) is drag, text
    assert ("opposite to cross-flow drag" in text) is not drag, text
    # the magnitudes at the largest sway velocity: |y_vv| v_max^2 m/s^2, n_vv v_max^2 deg/s^2
    assert f"{abs(y_vv) * CTX.v_max**2:.3g} m/s^2" in text and f"{14.1 * CTX.v_max**2:+.3g} deg/s^2" in text


@pytest.mark.parametrize("cubic,stall", [(-2e-4, True), (+2e-4, False)])
def test_saturation_reading_names_stall_only_for_less_force(cubic, stall):
    eff = BY_NAME["rudder_saturation"]
    text = eff.physical(eff.form(), {"rudder_cubic_per_deg2": cubic}, CTX)
    # at d_max = 20 deg: c d_max^2 = 8 % less (stall) or more force than linear
    assert ("8% less force" in text) is stall and ("8% more force" in text) is not stall, text
    assert ("stall or saturation" in text) is stall, text


def test_kernel_features_are_the_definition():
    from pipeline.diagnose.extended import _feature

    rng = np.random.default_rng(1)
    for code in FEATURES:
        for v, r in rng.normal(0, [0.2, 3.0], (20, 2)):
            assert _feature(code, v, r) == pytest.approx(
                float(feature_value(code, v, r)), rel=1e-14, abs=1e-300
            )
            assert _feature(code, v, r, 0.7) == pytest.approx(
                float(feature_value(code, v, r, 0.7)), rel=1e-14, abs=1e-300
            )
    # the non-dimensional cubic terms (v'^2 r' on u^2) are the dimensional ones divided by u/U
    assert feature_value(8, 0.1, 2.0, 0.5) == pytest.approx(2.0 * feature_value(3, 0.1, 2.0))
    assert feature_value(9, 0.1, 2.0, 0.5) == pytest.approx(2.0 * feature_value(4, 0.1, 2.0))


def _sim(effect, **vals):
    e = BY_NAME[effect]
    terms = Terms()
    e.apply(e.forms[0], vals, terms)
    return simulate_terms(THETA, terms, (0, 0, 0), T, DELTA, U_RATIO)


def test_offset_is_a_constant_added_to_the_rudder():
    np.testing.assert_allclose(
        _sim("rudder_offset", offset_deg=1.5),
        simulate_terms(THETA, Terms(), (0, 0, 0), T, DELTA + 1.5),
        atol=1e-12,
    )


def test_delay_shifts_the_rudder():
    shifted = np.interp(T - 0.4, T, DELTA)
    np.testing.assert_allclose(
        _sim("rudder_delay", delay_s=0.4), simulate_terms(THETA, Terms(), (0, 0, 0), T, shifted), atol=2e-3
    )


def test_lag_is_a_first_order_filter_of_the_rudder():
    from scipy.signal import lsim

    _, filt, _ = lsim(([1.0], [0.8, 1.0]), DELTA, T)
    ref = simulate_terms(THETA, Terms(), (0, 0, 0), T, filt)
    got = _sim("rudder_lag", lag_s=0.8)
    assert np.max(np.abs(got - ref)[:, 2]) < 0.01 * np.max(np.abs(ref[:, 2]))
    # and it is not a dead time of the same size
    assert np.max(np.abs(got - _sim("rudder_delay", delay_s=0.8))[:, 2]) > 0.05


def test_saturation_and_asymmetry_act_on_the_rudder_force():
    """Same as driving the linear model with the transformed rudder (up to the interpolation of a
    nonlinear function between samples: the kernel transforms the interpolated angle)."""

    def close(a, b):
        assert np.max(np.abs(a - b)) < 2e-3 * np.max(np.abs(b)), np.max(np.abs(a - b))

    c = -5e-4
    close(
        _sim("rudder_saturation", rudder_cubic_per_deg2=c),
        simulate_terms(THETA, Terms(), (0, 0, 0), T, DELTA + c * DELTA**3),
    )
    a = 0.1
    close(
        _sim("rudder_asymmetry", asymmetry=a),
        simulate_terms(THETA, Terms(), (0, 0, 0), T, DELTA * (1 + a * np.sign(DELTA))),
    )


def test_feature_effects_add_their_terms():
    """Yaw damping cuts the yaw rate; sway damping and coupling change it; both forms of yaw damping and of
    the coupling work."""
    base = simulate_terms(THETA, Terms(), (0, 0, 0), T, DELTA)
    cubic = _sim("nonlinear_yaw_damping", n_rrr_s_per_deg2=-0.01)
    assert np.abs(cubic[:, 1]).max() < 0.9 * np.abs(base[:, 1]).max()
    e = BY_NAME["nonlinear_yaw_damping"]
    terms = Terms()
    e.apply(e.form("abs"), {"n_rr_per_deg": -0.05}, terms)
    assert terms.feat_code == [1] and terms.feat_eq == [1]
    assert (
        np.abs(simulate_terms(THETA, terms, (0, 0, 0), T, DELTA)[:, 1]).max() < 0.9 * np.abs(base[:, 1]).max()
    )
    sway = _sim("nonlinear_sway_damping", y_vv_per_m=-5.0, n_vv_deg_per_m2=0.0)
    assert np.abs(sway[:, 0]).max() < np.abs(base[:, 0]).max()
    coup = _sim(
        "sway_yaw_coupling",
        y_vvr_s_per_m_deg=0.0,
        y_vrr_s2_per_deg2=0.0,
        n_vvr_s_per_m2=0.0,
        n_vrr_s_per_m_deg=-2.0,
    )
    assert np.max(np.abs(coup - base)[:, 1]) > 0.05
    # the modulus form (docs/diagnosis.md: v|r|, r|v|): |v| r and v |r| in both equations, in that order
    e = BY_NAME["sway_yaw_coupling"]
    terms = Terms()
    e.apply(e.form("modulus"), {"y_avr_per_deg": 0.0, "y_var_per_deg": 0.0, "n_avr_per_m": -5.0,
                                "n_var_per_m": 0.0}, terms)
    assert terms.feat_code == [6, 5, 6, 5] and terms.feat_eq == [0, 0, 1, 1]
    mod = simulate_terms(THETA, terms, (0, 0, 0), T, DELTA)
    # n |v| r < 0 is yaw damping that grows with the drift: the yaw rate peaks lower
    assert np.abs(mod[:, 1]).max() < 0.95 * np.abs(base[:, 1]).max()


def test_speed_loss_scales_hull_and_rudder_terms():
    slow = _sim("speed_loss", speed_exponent=1.0)
    base = simulate_terms(THETA, Terms(), (0, 0, 0), T, DELTA)
    # the slower ship turns less (rudder ~ U^2, damping ~ U)
    assert np.abs(slow[:, 1]).max() < np.abs(base[:, 1]).max()
    assert BY_NAME["speed_loss"].applicable(Context(5.0, 0.08, 20, 3, 0.1, 2.0, 0.99)) is not None
    assert BY_NAME["speed_loss"].applicable(CTX) is None


def test_simulate_extended_keywords_match_terms():
    a = simulate_extended(THETA, (0, 0, 0), DELTA, 0.08, offset_deg=1.0, n_rrr_s_per_deg2=-0.01, delay_s=0.3)
    terms = Terms(feat_code=[0], feat_eq=[1], feat_coef=[-0.01], offset_deg=1.0, delay_s=0.3)
    np.testing.assert_allclose(a, simulate_terms(THETA, terms, (0, 0, 0), T, DELTA), atol=1e-12)


def test_diverging_trial_model_stays_finite():
    """A trial model that diverges (negative cubic damping, unstable) is clipped, never overflows: the
    free-run heading grows at most at the clip rate (residuals large and finite for the optimiser)."""
    x = simulate_extended(THETA, (0, 0, 0), DELTA, 0.08, n_rrr_s_per_deg2=0.5, lag_s=0.3)
    assert np.all(np.isfinite(x)) and np.abs(x[:, 2]).max() <= 500.0 * T[-1] + 1e-6


def test_every_effect_carries_its_words_and_estimate_key():
    """An effect is one file: its label, signature axis and estimate key live on it (an effect added
    without them would draw an empty name in the report and a missing size in the studies)."""
    from pipeline.diagnose.effects import CATALOGUE, TRIAL

    for e in CATALOGUE + TRIAL:
        assert e.label and e.label != e.name, e.name
        assert e.signature_axis[0] != "time", e.name
        assert e.estimate_key, e.name


def test_rudder_asymmetry_floor_is_the_offset_floor_at_the_largest_rudder_angle():
    """An asymmetry a moves the effective rudder by a |delta| on each side, so it is held to the rudder
    offset's floor (0.3 deg) at the runs' largest rudder angle: the virtual KCS's 3.0 % at 35 deg is
    1.04 deg of rudder (named); the same 3.0 % on 1 deg zigzags is 0.03 deg (refused), and the floor
    moves with d_max, not with the ship."""
    from dataclasses import replace

    from pipeline.diagnose.effects.rudder_offset import MIN_OFFSET_DEG

    eff, form = BY_NAME["rudder_asymmetry"], BY_NAME["rudder_asymmetry"].forms[0]
    at35, at1 = replace(CTX, d_max=35.0), replace(CTX, d_max=1.0)
    ok, text = eff.material(form, {"asymmetry": -0.0298}, at35, 0.0)
    assert ok and "1.04 deg of rudder at 35 deg" in text and f"floor {MIN_OFFSET_DEG} deg" in text
    assert not eff.material(form, {"asymmetry": 0.0298}, at1, 0.0)[0]
    # exactly at the floor: a d_max = 0.3 deg is named, just under it is not
    assert eff.material(form, {"asymmetry": MIN_OFFSET_DEG / 20.0}, CTX, 0.0)[0]
    assert not eff.material(form, {"asymmetry": 0.99 * MIN_OFFSET_DEG / 20.0}, CTX, 0.0)[0]


def test_hull_nonlinearity_mixed_form_is_the_abkowitz_set_and_the_modulus_cross_terms():
    """The mixed form (the reference structure's) is the Abkowitz set's eight terms and the modulus cross
    terms |v| r, v |r| in both equations, each with the bounds and sign of the same term's single effect;
    simulated, it is the sum of the two sets' terms (the same run as the abkowitz form with the
    sway-yaw coupling's modulus form beside it), and its reading counts the |v| r moment (known answer:
    n_avr = -2 1/m at v 0.1 m/s, r 2 deg/s adds -0.4 deg/s^2)."""
    hull, coup = BY_NAME["hull_nonlinearity"], BY_NAME["sway_yaw_coupling"]
    mixed, abk, mod = hull.form("mixed"), hull.form("abkowitz"), coup.form("modulus")
    assert mixed.params == abk.params + mod.params
    vals = {p.name: 0.0 for p in mixed.params} | {"n_rr_per_deg": -0.05, "n_avr_per_m": -5.0,
                                                  "y_var_per_deg": -0.5}
    one, two = Terms(), Terms()
    hull.apply(mixed, vals, one)
    hull.apply(abk, {p.name: vals[p.name] for p in abk.params}, two)
    coup.apply(mod, {p.name: vals[p.name] for p in mod.params}, two)
    assert sorted(zip(one.feat_code, one.feat_eq, one.feat_coef, strict=True)) == \
        sorted(zip(two.feat_code, two.feat_eq, two.feat_coef, strict=True))
    np.testing.assert_allclose(simulate_terms(THETA, one, (0, 0, 0), T, DELTA),
                               simulate_terms(THETA, two, (0, 0, 0), T, DELTA), rtol=1e-12, atol=1e-12)
    ctx = Context(t_ship=10.0, h=0.08, d_max=20.0, r_max=2.0, v_max=0.1)
    zero = {p.name: 0.0 for p in mixed.params}
    assert "-0.4 from both together" in hull.physical(mixed, zero | {"n_avr_per_m": -2.0}, ctx)
    assert "+0 from both together" in hull.physical(abk, {p.name: 0.0 for p in abk.params}, ctx)
