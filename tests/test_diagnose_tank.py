"""Hidden-effect cases on the virtual tank: effects injected into the MMG KCS.

Unlike the linear truth model (tests/test_diagnose_cases.py) the KCS is not linear: it has cubic yaw
damping of its own (Yoshimura's N'_rrr, N'_vvr, ... and the rudder's inflow), so a "clean" tank is
not "none": the diagnosis must name the ship's own nonlinear_yaw_damping, and an injected effect must
be found *on top of it*.  The criteria of the issue then read:

- right cause: the injected effect is significant and in the extended model, next to nothing but the
  ship's own cubic damping; the clean ship gives nonlinear_yaw_damping and nothing else;
- gain >= 30 %: what the injected effect is worth inside the extended model (held-out MAE psi of the
  extended model refitted without it, against with it: ``validation_gain_in_extended``), in both
  folds.  (Its gain alone over the linear model mixes in the ship's own misfit: an injected 1.5 deg
  offset alone cuts the held-out error by 25 % in one fold and 89 % in the other.)
- estimate within 25 %: an offset directly (the symmetric KCS has none of its own); extra damping as
  the increment of n_rrr over the same diagnosis of the clean ship, against the injected N'_rrr
  converted to n_rrr by the tank's own equations (:func:`pipeline.tank.effects.n_rrr_equivalent`).

Design: the port/starboard-symmetric KCS (gamma_R equal both ways: the default KCS's propeller
asymmetry makes the rudder's effectiveness depend on the side, see
test_default_kcs_claims_no_dead_time_or_speed), speed held unless the case frees it, seeded measurement
noise; train on 10/10 starboard + 5/5 port, validate on 10/10 port + 5/5 starboard (both sides, two
amplitudes; two folds).  Small zigzags, because there a linear model is the right baseline: on 20/20
zigzags the KCS's own nonlinearity (its K falls 43 % from 10/10 to 20/20) dominates every run.

Not demonstrable on this ship (strict xfail, measured, so an improvement shows up as a failure to
update): a rudder dead time of 0.3-1 s, which the linear time constants absorb (0.6 s injected: on
top of the ship's own cubic damping the dead time cuts the held-out error by 8 % in one fold, where
one of the two runs gets worse, and 40 % in the other; its estimate 0.56 / 0.52 s is right), and
speed loss with the speed free (11 % in these zigzags): at constant propeller rps the slipstream keeps
the rudder's inflow up (u_R falls 2.5 % for a 10 % speed loss, so the rudder force falls 5 %, not
19 %), the yaw dynamics hardly change, and speed dependence gains -5 % / -1 % held-out with a fitted
exponent of 0.10 / 0.06.  On the linear truth model both are found (test_diagnose_cases.py).

Other designs, judged first by an oracle: the truth's structure as far as the
diagnosis can write it (the ship's own cubic damping + the injected effect) fitted on the same runs,
against the same without the effect, held-out MAE psi in both folds (:func:`_oracle`).

Dead time 0.6 s.  Physics: the KCS's fitted linear model has a fast yaw pole near -0.9 1/s and a slow
one near -0.05 1/s (T1 ~ 20 s: the ship is close to its stability margin, a 10/10 zigzag overshoots by
10.5 deg).  A dead time tau and a slower fast pole both lag the yaw response by omega tau at the zigzag
frequency (period ~30 s whatever the zigzag's size, omega tau = 7 deg), and differ only near omega ~
1/tau = 1.7 rad/s, which only the rudder's reversal ramp excites: with the dead time the fitted fast pole
moves from -0.88 to -1.65 1/s, i.e. without it the fit absorbs 0.5 s into the time constant.  A faster
rudder sharpens the ramp (10/10 reversal: 1.4 s at 14.28 deg/s, 0.4 s at 50 deg/s), smaller zigzags cut
the ship's own nonlinearity, more reversals and longer runs give more blocks.  Measured, 2026-11-23
(fold gains: train -> validate, then reversed; the estimate of the dead time is 0.5-0.6 s throughout):

  design (train S/P; validate mirrored) rudder     baseline->oracle, deg     gains
  10/10 + 5/5, 80 s (the design above)  14.3 deg/s 0.349->0.311, 0.424->0.234  11 % / 45 %
  10/10 + 5/5                           30 deg/s   0.362->0.305, 0.424->0.219  16 % / 48 %
  10/10 + 5/5                           50 deg/s   0.368->0.309, 0.419->0.208  16 % / 50 %
  10/10 + 5/5, 120 s                    14.3 deg/s 0.675->0.554, 0.412->0.573  18 % / -39 %
  10/10 + 5/5, 50 s                     14.3 deg/s 0.323->0.711, 0.550->0.493  -120 % / 10 %
  7.5/7.5 + 5/5                         14.3 / 30  0.427->0.377, 0.550->0.357  12 % / 35 % (30: 14 / 37)
  5/5 + 10/5 (twice the reversals)      14.3 / 30  0.895->0.720, 0.433->0.829  20 % / -91 % (30: 21 / -74)
  5/5 + 10/5, 150 s                     30 deg/s   0.356->0.516, 0.329->0.147  -45 % / 55 %
  10/5 + 15/5                           30 deg/s   0.318->0.726, 0.727->0.618  -128 % / 15 %
  10/10 + 10/5                          14.3 deg/s 0.861->0.849, 0.602->0.949  1 % / -58 %
  10/10 + 5/5 + 10/5 (three a side)     14.3 deg/s 0.249->0.495, 0.646->0.472  -99 % / 27 %
  5/5 + 7.5/7.5 + 10/10 (three a side)  14.3 deg/s 0.471->0.331, 0.217->0.210  30 % / 3 %
  5/5 S + 7.5/7.5 S vs the same to port 14.3 / 30  0.510->0.317, 0.330->0.346  38 % / -5 % (30: 40 / -4)
  7.5/7.5 both sides vs 6.5/6.5 both    14.3 / 30  0.536->1.230, 0.339->0.347  -129 % / -2 % (30: -147 / -4)
  10/10 both sides vs 9/9 both          14.3 deg/s 0.541->1.028, 0.453->0.813  -90 % / -80 %
  5/5 both sides vs 5.5/5.5 both        14.3 deg/s 0.715->0.648, 0.486->0.439  9 % / 10 %

More reversals by a small heading trigger (x/1, x/2: the rudder reverses as soon as the heading moves
1-2 deg, every 4-8 s), measured 2026-11-25 (80 s runs unless said):

  10/1 + 5/1                            50 / 30    0.363->0.236, 0.161->0.122  35 % / 24 % (30: 35 / 24)
  10/1 + 5/1                            14.3 deg/s 0.382->0.262, 0.138->0.171  31 % / -23 %
  10/1 + 5/1, 150 s                     50 deg/s   0.265->0.238, 1.698->0.517  10 % / 70 % (2.19 s fitted)
  10/2 + 5/2                            50 deg/s   0.364->0.204, 0.351->0.309  44 % / 12 %
  10/2 + 5/1                            14.3 deg/s 0.535->0.247, 0.208->0.121  54 % / 42 %
  10/2 + 5/1                            30 / 50    0.550->0.239, 0.217->0.104  57 % / 52 % (50: 56 / 41)
  10/2 + 5/1, 60 s                      50 deg/s   0.186->0.190, 0.160->0.116  -2 % / 28 %
  10/2 + 5/1, 100 s                     50 deg/s   0.237->0.226, 2005->0.425   5 % / (base runs away)
  10/2 + 7.5/5                          50 deg/s   0.366->0.250, 0.408->0.345  32 % / 15 %
  10/3 + 5/1                            50 deg/s   0.863->0.646, 0.511->0.322  25 % / 37 %
  7.5/2 + 5/1                           50 deg/s   0.527->0.404, 0.188->0.267  23 % / -42 %
  15/1 + 10/1                           50 deg/s   0.226->0.694, 0.259->0.149  -207 % / 42 %

10/2 + 5/1 at 80 s clears 30 % in both folds at every rudder rate, and not at 60 or 100 s.  Its gains
are against a base that predicts worse than the linear baseline (the own cubic damping, 0.54 / 0.21
deg, where the diagnosis's linear baseline makes 0.18): the full diagnosis of that design with the
current rudder (14.3 deg/s) names none, the dead time alone +28 % / +28 % but a held-out cut of 0.05
deg, under the 0.1 deg heading-noise floor, beside the ship's own cross terms at +35 % (+20 % without
the dead time).  A 0.6 s dead time moves the heading of these small zigzags by hundredths of a degree.

No exchangeable design clears 30 % in both folds robustly (5/5 both sides against 7.5/7.5 both sides
does, 60 % / 48 %, but its amplitudes differ by 50 %, so the diagnosis asks it in one direction only,
and its neighbours above swing from -147 % to +40 %; 10/2 + 5/1 does at 80 s only, and immaterially).  A
pull-out was not simulated (the tank has no such manoeuvre): its one rudder step excites frequencies
near 1/tau no more than each zigzag reversal does, and its decay is the slow pole's.  With the slow pole
near the margin the held-out heading error is dominated by how the fit places that pole, not by the 0.6
s.  So the dead time stays a strict xfail on the current design and on the best faster-rudder one
(test_tank_dead_time_is_found_with_a_fast_rudder), and the oracle's figures on both are a test
(test_tank_dead_time_oracle_is_below_the_bar).

Speed loss, speed free (hull forces scale with U^2; at constant rps the rudder force with u_R^2, which
the slipstream holds up).  Larger manoeuvres lose more speed, but the ship's own large-amplitude
nonlinearity grows faster than what speed dependence can explain, and the fitted exponent then stands
for amplitude, not speed.  Oracle (own cubic damping + speed_loss's power form, fitted, both folds;
measured 2026-11-23):

  design                        lowest u/U  baseline->oracle, deg     gains          exponent n
  10/10 + 5/5 (the design above)  0.88      0.240->0.256, 0.197->0.199  -7 % / -1 %    0.10 / 0.07
  20/20 + 10/10                   0.70      1.227->1.140, 1.110->1.030  7 % / 7 %      0.16 / 0.16
  35/35 + 20/20                   0.47      2.305->1.767, 2.381->1.884  23 % / 21 %    0.13 / 0.11
  35 deg turn + 20/20 zigzag      -         3.073->1.741, 2.895->2.792  43 % / 4 %     0.56 / 0.02

With sway-yaw coupling added to the base (35/35 + 20/20) speed dependence gains 36 % / 36 % (n = 0.31),
but that base is worse held-out than the cubic damping alone (3.03 vs 2.31 deg), and the full diagnosis
of that design names cubic damping + rudder saturation, with speed dependence at -3 % / -1 % and
n = 0.00 (53 % of the speed lost).  A hull-only form (rudder force not scaled; fitted outside the method
for this check) gains -1 % / 15 % on 20/20 + 10/10 (n = 1.11 / -2.4) and 41 % / -49 % on 35/35 +
20/20 (n = 5.1 / 0.4): no fold-stable, physical exponent.  So speed loss is not material on this ship
at constant rps on any zigzag design tried (nor a turning circle beside a zigzag); the xfail below
stays for the zigzag design, with these figures as its reason.  A pull-out is where it is found.

A pull-out (the tank's turning circle with ``pull_out_s``: the rudder returned to midships once the
turn is steady), measured 2026-11-26.  Designs are written train / validate, the validation runs the
mirror image ("po a S" = an a deg turning circle to starboard, pulled out at 40 s of 80 s; "z10 S" =
10/10 zigzag); oracle gains per fold at the default noise seed, then at noise seeds 11, 12, 13:

  design              effect, oracle base         gains (default seed)  at seeds 11 / 12 / 13
  po10 S + po20 P     dead time, own cubic        +3 % / -4 % (0.16 s)  -
  po5 S + po10 P      dead time, own cubic        0 % / -12 % (0.28 s)  -
  po20 S + po35 P     dead time, own cubic        +1 % / -4 % (0.10 s)  (50 deg/s rudder: -1 / -8 %)
  z10 S + po10 P      dead time, own cubic        -44 % / -4 %          -
  z10 S + po10 P      dead time, all hull terms   +46 % / +54 %         -104/+11, -9/-63, +21/-39 %
  po10 S + po20 P     dead time, all hull terms   +32 % / -27 %         -18/-19, +37/+71, -21/-11 %
  po20 S + po35 P     dead time, all hull terms   +35 % / +26 %         +15/+1, +57/+60, -11/+40 %
  z10 S + z5 P        dead time, all hull terms   +48 % / +37 %         +6/+1, -16/-14, +26/+15 %
  po20 S + po35 P     speed, own cubic            +70 % / +67 % (n .58) +64/+62, +69/+64, +64/+62 %
  z10 S + po10 P      speed, own cubic            +28 % / +41 % (n .69) +23/+47, +18/+19, +24/+47 %
  z10 S + po10 P      speed, all hull terms       +71 % / +54 % (n .50) +40/+22, +31/+36, +28/+35 %

(own cubic: the base of the tables above; all hull terms: v|v|, v^2 r / v r^2 and r^3 together, the
hull as far as the catalogue can write it.  With that base the dead time is worth 30 % on the current
zigzag design too, at the default seed only: which noise seed the fit sees decides it.)

Pulling out of a steady turn is where the KCS's speed matters: it turns at 77 % of its approach
speed in the 10 deg circle and 42 % in the 35 deg one, then accelerates, so hull forces that scale
with u separate from the rudder's, which the slipstream holds.  The full diagnosis of z10 S + po10 P
(the design of the tests below, PULL_OUT) names speed dependence beside hull terms at all four seeds:

  seed      speed free: extended model, speed gain per fold (n)     speed held      dead time 0.6 s
  default   sway damping + speed, +75 % / +79 % (0.60)              sway damping    named, +49 / +67 %
  11        cross terms + speed, +43 % / +54 % (0.40)               sway damping    named, +53 / +43 %
  12        cross terms + speed, +53 % / +54 % (0.42)               sway damping    not named
  13        cross terms + speed, +47 % / +44 % (0.42)               sway damping    not named

The dead time, alone on the linear baseline, is worth +43 % to +68 % in both folds at every seed,
estimated 0.54-0.56 s; but at seeds 12 and 13, added to the final model, it made the held-out 10/10
zigzags significantly worse (seed 12: 0.45 -> 0.86 deg, block t = -6.2) while it cut the pull-outs,
and the diagnosis names nothing that worsens a held-out manoeuvre.

Why, measured 2026-11-26: the tank's runs execute at their first sample, so a run's start is one
sample's noise (r0 +- 0.07 deg/s, v0 +- 0.005 m/s), and the per-run no-harm test compares the models
from that one start.  On this ship near its margin the start error grows into a drift that differs
from model to model, the same in every block of the run.  Fold 1, seed 12, held-out 10/10 zigzag
(sway damping -> + dead time): from the common start 0.455 -> 0.862 deg; from the noise-free start
(noise off) 0.542 -> 0.316; with only the v noise removed 0.179 -> 0.104; from each model's own
start in the approach's box 0.179 -> 0.103, and 0.18-0.19 -> 0.10-0.11 at every seed.  With the
dead time applied exactly (the logged rudder shifted 0.6 s, nothing fitted) the same zigzag goes
0.45 -> 0.89 deg from the common start: the harm was the start's, not the dead time's.  So the
per-run harm t-test now carries the start's uncertainty, propagated through both models, for a
start that is one sample as here (pipeline.diagnose.select, Search._start_sd; test_diagnose.py's
known answer; a start fitted over a quiet approach keeps the plain block test, measured on the
disturbed Mariner of test_diagnose_generalise.py).  Then, on the 10 deg design:

  seed      final model                   dead time
  default   dead time + cross terms       named, +49 % / +67 % inside
  11        cross terms                   not named: held-out cut 0.098 deg under the 0.1 deg floor
  12        dead time + cross terms       named, +64 % / +66 % inside
  13        cross terms                   not named: held-out cut 0.092 deg under the 0.1 deg floor

The final model already predicts the held-out runs within about 0.1 deg, and a 0.6 s dead time at
a 10 deg turn's yaw rate moves them by about as much as the gyro's repeatability.  Twice the rudder
(PULL_OUT_20: a 20/20 zigzag and a 20 deg circle pulled out, the mirror image held out) doubles the
yaw rate and so the r tau a dead time costs; named at the four seeds above and at four drawn after
the design was chosen (21-24), per-fold worth inside the final model +39 % to +71 %, cut 0.11-0.27
deg, estimate 0.47-0.54 s; without the dead time (seeds default, 12, 21, 22) only hull terms.  A 15
deg design named it at all four first seeds but at +19 % in one fold at seed 12.  Other designs
measured with the new test (default, 11, 12, 13): the 10 deg design + a 15 deg pull-out (three runs
a side) named it at default and 13; 10/10 + 20 deg pull-out at none (the zigzag's small rates beside
the circle's large ones).  Asserted: test_tank_dead_time_is_found_with_a_pull_out (20 deg,
two seeds), test_tank_clean_pull_out_has_no_dead_time, test_tank_dead_time_is_seen_on_a_pull_out
(10 deg) and a strict xfail for the 10 deg design at seed 13.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest

from pipeline.config import DiagnoseConfig, TankConfig
from pipeline.diagnose import diagnose

tank = pytest.importorskip("pipeline.tank")
from selection_only import SELECTION_ONLY  # noqa: E402  (the setting, and its reason, of selection-only tests)

from pipeline.tank.effects import extra_damping_for_cut, n_rrr_equivalent  # noqa: E402

TRAIN = [(10, "starboard"), (5, "port")]
VALIDATE = [(10, "port"), (5, "starboard")]
OWN = "nonlinear_yaw_damping"
#: the KCS's own hull nonlinearity (MMG: Y'vvv, Y'vrr, N'vvr, N'rrr, ...) may be named by any hull
#: effect: in a zigzag the drift follows the turn (v ~ -c r), so v|v|, v^2 r and r^3 carry the same
#: signal (the reasoning of tests/truths/cases.py HULL_NL).  Measured 2026-11-23: with the held-out
#: start boxed by the approach's own uncertainty the clean ship is named nonlinear_sway_damping
#: (held-out 0.66 -> 0.08 deg), and with an offset injected offset + sway_yaw_coupling.
#: hull_nonlinearity is the same hull nonlinearity carried by the Abkowitz-type set in one step
#: (docs/diagnosis.md, "The catalogue"): a right name for it, not a rival
HULL_NL = ("nonlinear_sway_damping", "sway_yaw_coupling", "nonlinear_yaw_damping", "hull_nonlinearity")
KINDS = ("none", "rudder_offset", "nonlinear_yaw_damping", "rudder_offset", "nonlinear_yaw_damping")


def _symmetric():
    base = tank.KCSCoefficients()
    return dc.replace(base, gamma_minus=base.gamma_plus)


def _draw_cases():
    rng = np.random.default_rng(DiagnoseConfig().seed + 1)
    cases = []
    for i, kind in enumerate(KINDS):
        mag = {
            "none": 0.0,
            "rudder_offset": rng.uniform(1.0, 3.0) * rng.choice([-1.0, 1.0]),
            "nonlinear_yaw_damping": rng.uniform(0.15, 0.35),  # cut of the 20/20 yaw-rate amplitude
        }[kind]
        cases.append((i, kind, float(mag)))
    return cases


CASES = _draw_cases()


def _runs(cfg: TankConfig, coeffs):
    def make(legs):
        return [tank.simulate(tank.zigzag(a, a, side, duration=80.0), cfg, coeffs=coeffs) for a, side in legs]

    return make(TRAIN), make(VALIDATE)


_CACHE: dict = {}


def _diagnosis(**kw):
    key = tuple(sorted(kw.items()))
    if key not in _CACHE:
        coeffs = _symmetric()
        cfg = dc.replace(TankConfig(), **{"hold_speed": True, **kw})
        _FULL[key] = diagnose(*_runs(cfg, coeffs), cfg=SELECTION_ONLY)
        _CACHE[key] = _FULL[key].report
    return _CACHE[key]


_FULL: dict = {}


def _clean_own_n_rrr() -> float:
    """n_rrr (s/deg^2) of the clean symmetric KCS fitted as linear + cubic yaw damping on fold 1's
    training runs (the search's first-round fit, kept in Diagnosis.fits)."""
    _diagnosis()
    fit = _FULL[()].fits["0:nonlinear_yaw_damping/cubic"]
    return float(fit.values["nonlinear_yaw_damping"]["n_rrr_s_per_deg2"])


def _summary(rep):
    return {
        f["effect"]: (
            f["significant"], f.get("validation_gain_folds"), f.get("validation_gain_in_extended_folds")
        )
        for f in rep["findings"]
    }


def _estimate(rep, effect, name):
    return rep["extended"]["effect_estimates"][effect]["estimate"][name]


def _found_on_top_of_the_ship(rep, kind: str) -> dict:
    """The criteria of an effect injected into the tank (module docstring), asserted: ``kind`` is in
    the extended model beside nothing but the ship's own hull terms, significant, worth >= 30 % in
    both folds inside the extended model, and nothing else significant (no false effect).  Returns
    its finding."""
    summary = _summary(rep)
    assert kind in rep["extended"]["effects"], summary
    assert set(rep["extended"]["effects"]) <= {kind, *HULL_NL}, summary
    finding = next(f for f in rep["findings"] if f["effect"] == kind)
    assert finding["significant"], finding["evidence"]
    assert min(finding["validation_gain_in_extended_folds"]) >= 0.30, summary
    sig = {f["effect"] for f in rep["findings"] if f["significant"]}
    assert sig <= {kind, *HULL_NL}, summary
    return finding


#: the tank cases in make test: the first draw of each kind (none, offset, yaw damping); the second
#: draws of the offset and the yaw damping are marked long (make test-long)
TANK_CI_DRAWS = 3


@pytest.mark.slow
@pytest.mark.parametrize("case", [
    pytest.param(c, id=f"{c[0]:02d}-{c[1]}", marks=[] if c[0] < TANK_CI_DRAWS else [pytest.mark.long])
    for c in CASES])
def test_tank_hidden_effect_is_found_on_top_of_the_ship(case):
    i, kind, mag = case
    if kind == "none":
        rep = _diagnosis()
        # the KCS's own hull nonlinearity, and nothing else
        assert rep["cause"] in HULL_NL, _summary(rep)
        assert rep["extended"]["effects"] and set(rep["extended"]["effects"]) <= set(HULL_NL), _summary(rep)
        own = next(f for f in rep["findings"] if f["effect"] == rep["cause"])
        assert min(own["validation_gain_folds"]) >= 0.30, _summary(rep)
        # more damping, whichever the form: the physical sign of the named term
        # (yaw: n_rrr of the r^3 form or n_rr of the r|r| form; sway: y_vv)
        sign_keys = {"nonlinear_yaw_damping": ("n_rrr_s_per_deg2", "n_rr_per_deg"),
                     "nonlinear_sway_damping": ("y_vv_per_m",)}
        if rep["cause"] in sign_keys:
            est = rep["extended"]["effect_estimates"][rep["cause"]]["estimate"]
            damping = [est[k] for k in sign_keys[rep["cause"]] if k in est]
            assert damping and all(x < 0.0 for x in damping), est
        return
    if kind == "rudder_offset":
        rep = _diagnosis(rudder_offset=mag)
        name, truth = "offset_deg", mag
        est = _estimate(rep, kind, name)
    else:
        coeffs = _symmetric()
        extra = extra_damping_for_cut(mag, dc.replace(TankConfig(), hold_speed=True), coeffs)
        rep = _diagnosis(extra_yaw_damping=extra)
        name = "n_rrr_s_per_deg2"
        truth = n_rrr_equivalent(extra, dc.replace(TankConfig(), hold_speed=True), coeffs)
        # the increment over the clean ship's fit of the same structure (linear + cubic yaw damping,
        # fold 1, as the search fitted it in its first round)
        est = _estimate(rep, kind, name) - _clean_own_n_rrr()
    # found, and no false effect: offset / dead time / speed are absent unless injected
    _found_on_top_of_the_ship(rep, kind)
    assert rep["cause"] in (kind, *HULL_NL), _summary(rep)
    assert abs(est - truth) <= 0.25 * abs(truth), (name, est, truth)
    assert rep["extended"]["effect_estimates"][kind]["uncertainty"][name] > 0


@pytest.mark.slow
def test_default_kcs_claims_no_dead_time_or_speed():
    """The default KCS's propeller makes the flow straightening gamma_R differ port and starboard: a
    rudder effectiveness that depends on the side, which is neither a dead time nor a speed effect.
    (Nor is it a constant offset: with the design here the offset cuts the held-out error on one fold,
    +27 %, and worsens it on the other, -7 %, and offset + cubic damping worsen both, so the diagnosis
    names none; on 20/20 zigzags alone an offset of -0.99 deg passes.)"""
    cfg = dc.replace(TankConfig(), hold_speed=True)
    rep = diagnose(*_runs(cfg, None), cfg=SELECTION_ONLY).report
    sig = {f["effect"] for f in rep["findings"] if f["significant"]}
    assert not sig & {"rudder_delay", "speed_loss"}, _summary(rep)
    assert set(rep["extended"]["effects"]) <= {"rudder_offset", "rudder_asymmetry", *HULL_NL}, _summary(rep)


@pytest.mark.long     # CI cut: the hidden-effect cases, the clean and default ship, a pull-out (make test)
@pytest.mark.xfail(strict=True, reason="measured: a dead time is absorbed by the KCS's linear time "
                   "constants; on top of its own cubic damping 0.6 s adds 8 % / 40 % held-out (folds); "
                   "2026-11-24, boxed start: -3 % / -6 % alone, not named")
def test_tank_dead_time_is_found():
    rep = _diagnosis(rudder_delay=0.6)
    finding = next(f for f in rep["findings"] if f["effect"] == "rudder_delay")
    assert "rudder_delay" in rep["extended"]["effects"], _summary(rep)
    assert min(finding["validation_gain_in_extended_folds"]) >= 0.30


@pytest.mark.long     # CI cut: the hidden-effect cases, the clean and default ship, a pull-out (make test)
def test_tank_dead_time_is_measured_not_claimed():
    """What the diagnosis does say about a 0.6 s dead time on the KCS: the dead time fitted (alone) is
    within 25 % of 0.6 s, and no false offset is claimed."""
    rep = _diagnosis(rudder_delay=0.6)
    finding = next(f for f in rep["findings"] if f["effect"] == "rudder_delay")
    assert abs(finding["estimate"]["delay_s"] - 0.6) <= 0.25 * 0.6, finding["estimate"]
    sig = {f["effect"] for f in rep["findings"] if f["significant"]}
    assert "rudder_offset" not in sig, _summary(rep)


#: the best faster-rudder design for the dead time (module docstring's table): the current 10/10 + 5/5
#: design with a 50 deg/s servo; manoeuvres to train on and to validate on (their mirror images)
def _zigzags(legs):
    return tuple(tank.zigzag(a, h, s, duration=80.0) for a, h, s in legs)


_LEGS = {
    "train": _zigzags(((10, 10, "starboard"), (5, 5, "port"))),
    "validate": _zigzags(((10, 10, "port"), (5, 5, "starboard"))),
}
FAST = {**_LEGS, "rudder_rate": 50.0}
CURRENT = {**_LEGS, "rudder_rate": TankConfig().rudder_rate}
def _pull_out_design(deg: int) -> dict:
    """A deg/deg zigzag to starboard and a deg turning circle to port, its rudder returned to midships
    after 40 s, validated on the mirror image; the current rudder."""
    return {
        "train": (tank.zigzag(deg, deg, "starboard", duration=80.0),
                  tank.turning_circle(deg, "port", duration=80.0, pull_out_s=40.0)),
        "validate": (tank.zigzag(deg, deg, "port", duration=80.0),
                     tank.turning_circle(deg, "starboard", duration=80.0, pull_out_s=40.0)),
        "rudder_rate": TankConfig().rudder_rate,
    }


#: the pull-out design (docs/diagnosis.md names the manoeuvre; module docstring's last tables) at 10 deg
PULL_OUT = _pull_out_design(10)
#: the same at 20 deg: twice the yaw rate, so a dead time's heading error (r tau after each rudder
#: step) twice the 10 deg design's, above the 0.1 deg heading floor where the 10 deg design's sits on it
PULL_OUT_20 = _pull_out_design(20)


def _design_runs(design, **kw):
    cfg = dc.replace(TankConfig(), **{"hold_speed": True, "rudder_rate": design["rudder_rate"], **kw})

    def make(manoeuvres):
        coeffs = _symmetric()
        return [tank.simulate(m, cfg, coeffs=coeffs) for m in manoeuvres]

    return make(design["train"]), make(design["validate"])


_DESIGN_CACHE: dict = {}


def _design_diagnosis(name: str, **kw):
    """The diagnosis (selection only) of design ``name`` (a module constant) with the tank's ``kw``."""
    key = (name, tuple(sorted(kw.items())))
    if key not in _DESIGN_CACHE:
        _DESIGN_CACHE[key] = diagnose(*_design_runs(globals()[name], **kw), cfg=SELECTION_ONLY).report
    return _DESIGN_CACHE[key]


def _oracle(train, validate, base: tuple, effect: str):
    """Per fold (train -> validate, then reversed): held-out MAE psi (deg) of ``base`` and of ``base`` +
    ``effect`` fitted on the same runs (the truth's structure as far as the diagnosis can write it),
    their relative gain, and the effect's fitted values."""
    from pipeline.diagnose.core import _context
    from pipeline.diagnose.fit import series_from_run, structure_of
    from pipeline.diagnose.select import Fold, Search

    tr, va = [series_from_run(r) for r in train], [series_from_run(r) for r in validate]
    search = Search([Fold(tr, va), Fold(va, tr)], _context(tr + va), DiagnoseConfig())
    b, e = structure_of(*base), structure_of(*base, effect)
    out = []
    for k in range(2):
        search.fit(k, e, start=search.fit(k, b))
        mb, me = search.eval(k, b)[0]["mae_psi_deg"], search.eval(k, e)[0]["mae_psi_deg"]
        out.append((mb, me, (mb - me) / mb, search.fit(k, e).values[effect]))
    return out


@pytest.mark.long     # CI cut: the hidden-effect cases, the clean and default ship, a pull-out (make test)
@pytest.mark.parametrize("design", [CURRENT, FAST], ids=["14deg_s", "50deg_s"])
def test_tank_dead_time_oracle_is_below_the_bar(design):
    """The oracle evidence behind the dead-time xfails: the truth's structure (own cubic damping + the
    dead time) fitted on the same runs sees the dead time (0.6 s within 25 % in both folds) but is not
    worth 30 % held-out in both folds, on the current rudder nor a 50 deg/s one."""
    folds = _oracle(*_design_runs(design, rudder_delay=0.6), (OWN,), "rudder_delay")
    for _, _, _, values in folds:
        assert abs(values["delay_s"] - 0.6) <= 0.25 * 0.6, folds
    gains = [g for _, _, g, _ in folds]
    assert min(gains) < 0.30 <= max(gains), folds


@pytest.mark.long     # CI cut: the hidden-effect cases, the clean and default ship, a pull-out (make test)
@pytest.mark.xfail(strict=True, reason="measured: the oracle (own cubic damping + dead time, fitted) gains "
                   "16 % / 50 % held-out with a 50 deg/s rudder; no exchangeable zigzag design tried clears "
                   "30 % in both folds (module docstring's table)")
def test_tank_dead_time_is_found_with_a_fast_rudder():
    rep = diagnose(*_design_runs(FAST, rudder_delay=0.6), cfg=SELECTION_ONLY).report
    finding = next(f for f in rep["findings"] if f["effect"] == "rudder_delay")
    assert "rudder_delay" in rep["extended"]["effects"], _summary(rep)
    assert finding["significant"], finding["evidence"]
    assert min(finding["validation_gain_in_extended_folds"]) >= 0.30, _summary(rep)
    est = rep["extended"]["effect_estimates"]["rudder_delay"]["estimate"]["delay_s"]
    assert abs(est - 0.6) <= 0.25 * 0.6, est


#: a noise seed of the tank at which the 10 deg pull-out design's dead time is seen but not named
#: (measured 2026-11-26 at four seeds: named at the default seed and at 12, not at 11 and 13, where its
#: held-out cut, 0.098 / 0.092 deg, is under the 0.1 deg heading floor; docstring).  With
#: hull_nonlinearity tried by the selection it was named at 13 too (effects.TRIAL says why that effect
#: is not tried: test_tank_dead_time_is_found_with_a_10_deg_pull_out is a strict xfail again)
NOT_NAMED_SEED = 13


@pytest.mark.slow
@pytest.mark.parametrize("seed", [TankConfig().seed, pytest.param(NOT_NAMED_SEED, marks=pytest.mark.long)],
                         ids=["seed_default", "seed_13"])     # long: the second seed (make test-long)
def test_tank_dead_time_is_seen_on_a_pull_out(seed):
    """On the pull-out design the 0.6 s dead time is worth >= 30 % held-out in both folds when it is
    added alone to the linear baseline, and its estimate is within 25 %: what the zigzag designs never
    showed (module docstring).  Asserted at a seed where it is named and at one where it is not."""
    rep = _design_diagnosis("PULL_OUT", rudder_delay=0.6, seed=seed)
    finding = next(f for f in rep["findings"] if f["effect"] == "rudder_delay")
    assert min(finding["validation_gain_folds"]) >= 0.30, _summary(rep)
    assert abs(finding["estimate"]["delay_s"] - 0.6) <= 0.25 * 0.6, finding["estimate"]
    sig = {f["effect"] for f in rep["findings"] if f["significant"]}
    assert sig <= {"rudder_delay", *HULL_NL}, _summary(rep)


@pytest.mark.slow
@pytest.mark.long     # CI cut: the hidden-effect cases, the clean and default ship, a pull-out (make test)
@pytest.mark.xfail(strict=True, reason="on the 10 deg pull-out design at this seed the dead time's held-out "
                   "cut, 0.092 deg, is under the 0.1 deg heading floor (twice the 0.05 deg heading noise) "
                   "while single hull effects carry the ship's nonlinearity; named with hull_nonlinearity "
                   "tried, which is not (pipeline.diagnose.effects.TRIAL)")
def test_tank_dead_time_is_found_with_a_10_deg_pull_out():
    """The 0.6 s dead time on the 10 deg pull-out design at the seed where, with the hull's
    nonlinearity carried by single hull effects, its held-out cut (0.092 deg) stays under the 0.1 deg
    heading floor; with the Abkowitz-type set tried in one step (hull_nonlinearity) the ship's own
    nonlinearity is carried whole and the dead time is named on top of it."""
    rep = _design_diagnosis("PULL_OUT", rudder_delay=0.6, seed=NOT_NAMED_SEED)
    _found_on_top_of_the_ship(rep, "rudder_delay")


@pytest.mark.slow
@pytest.mark.parametrize("seed", [TankConfig().seed, pytest.param(12, marks=pytest.mark.long)],
                         ids=["seed_default", "seed_12"])     # long: the second seed (make test-long)
def test_tank_dead_time_is_found_with_a_pull_out(seed):
    """The dead time on the virtual KCS, found where the manoeuvre lets it matter: the
    20 deg pull-out design (PULL_OUT_20), 0.6 s injected.  By the criteria of the injected effects: in
    the extended model beside nothing but the ship's own hull terms, significant, worth >= 30 % in
    both folds inside it, nothing else significant; its estimate within 25 %.  Seed 12 is the seed at
    which the 10 deg design's no-harm test refused it before the start's uncertainty was carried
    (select.py, Search._start_sd).  Measured 2026-11-26 at eight seeds (default, 11-13, 21-24, the
    last four drawn after the design was chosen): named at all eight, per-fold worth +39 % to +71 %,
    estimate 0.47-0.54 s; without the dead time (default, 12, 21, 22) it is not named at any."""
    rep = _design_diagnosis("PULL_OUT_20", rudder_delay=0.6, seed=seed)
    finding = _found_on_top_of_the_ship(rep, "rudder_delay")
    assert abs(finding["estimate"]["delay_s"] - 0.6) <= 0.25 * 0.6, finding["estimate"]


@pytest.mark.slow
def test_tank_clean_pull_out_has_no_dead_time():
    """The same design without a dead time: no rudder_delay, only the ship's own hull terms."""
    rep = _design_diagnosis("PULL_OUT_20")
    assert rep["extended"]["effects"] and set(rep["extended"]["effects"]) <= set(HULL_NL), _summary(rep)
    sig = {f["effect"] for f in rep["findings"] if f["significant"]}
    assert sig <= set(HULL_NL), _summary(rep)


@pytest.mark.slow
def test_tank_speed_loss_is_found_with_a_pull_out():
    """Speed free, the pull-out design: the KCS loses 23 % of its speed in the 10 deg turn, and speed
    dependence is found on top of the ship's own hull nonlinearity by the criteria of the injected
    effects (in the extended model beside nothing but hull terms, significant, worth >= 30 % in both
    folds).  Estimates: the speed loss the diagnosis reports is within 25 % of the truth's (its
    noise-free surge speed); the exponent has no truth to match (the tank is MMG at constant rps, not
    the power form), but physics bounds it: hull forces scale as u (n = 1 for the dimensional
    derivatives) while the slipstream holds the rudder's inflow up (n near 0 for the rudder terms),
    so a blend lies in (0, 1].  Speed held, the same design: speed dependence is not tried and only
    hull terms are named."""
    rep = _design_diagnosis("PULL_OUT", hold_speed=False)
    kind = "speed_loss"
    finding = _found_on_top_of_the_ship(rep, kind)
    clean = dc.replace(TankConfig(), hold_speed=False, noise=False)
    u = np.concatenate([tank.simulate(m, clean, coeffs=_symmetric()).col("u") for m in PULL_OUT["train"]])
    truth = 1.0 - u.min() / u[0]
    est = finding["estimate"]
    assert est["max_speed_loss"] == pytest.approx(truth, rel=0.25), (est, truth)
    assert 0.0 < rep["extended"]["effect_estimates"][kind]["estimate"]["speed_exponent"] <= 1.0, _summary(rep)
    held = _design_diagnosis("PULL_OUT")
    assert set(held["extended"]["effects"]) <= set(HULL_NL) and held["extended"]["effects"], _summary(held)
    sl = next(f for f in held["findings"] if f["effect"] == kind)
    assert sl["validation_gain"] is None and sl["evidence"].startswith("Not tried"), sl


@pytest.mark.long     # CI cut: the hidden-effect cases, the clean and default ship, a pull-out (make test)
@pytest.mark.xfail(strict=True, reason="measured: at constant rps the KCS's rudder inflow hardly drops "
                   "with speed; speed dependence gains -5 % / -1 % held-out on top of its cubic damping "
                   "(2026-11-24, boxed start: -7 % / -3 % alone); the "
                   "oracle reaches 7 % / 7 % on 20/20 + 10/10, 23 % / 21 % on 35/35 + 20/20 (docstring)")
def test_tank_speed_loss_is_found():
    rep = _diagnosis(hold_speed=False)
    assert "speed_loss" in rep["extended"]["effects"], _summary(rep)


@pytest.mark.slow
def test_tank_speed_free_is_tried_not_imagined():
    """Speed free: the KCS slows in the zigzags, speed dependence is tried (the loss is measured), and
    the ship's own damping stays the cause; with the speed held it is not even tried."""
    rep = _diagnosis(hold_speed=False)
    sl = next(f for f in rep["findings"] if f["effect"] == "speed_loss")
    assert sl["validation_gain"] is not None
    assert 0.05 <= sl["estimate"]["max_speed_loss"] <= 0.35, sl["estimate"]
    assert rep["cause"] in HULL_NL, _summary(rep)
    # speed held: the loss is below the effect's applicability floor, so it is not tried, and says why
    held = next(f for f in _diagnosis()["findings"] if f["effect"] == "speed_loss")
    assert held["validation_gain"] is None and held["estimate"] == {}, held
    assert held["evidence"].startswith("Not tried: the speed falls by only"), held


@pytest.mark.slow
@pytest.mark.parametrize("eps", [0.5, pytest.param(1.0, marks=pytest.mark.long)])   # long: the second size
def test_tank_heading_misalignment_is_found_on_top_of_the_ship(eps):
    """A sensor effect injected into the tank (TankConfig.heading_misalignment: the logged heading reads
    eps more, u and v read through it, the KCS's own hull untouched) is found on top of the ship's own
    hull nonlinearity, by the criteria of the injected effects above: in the extended model beside
    nothing but the hull's terms, significant, worth >= 30 % in both folds, within 25 %.

    Measured 2026-11-25: cubic yaw damping + misalignment 0.50 / 1.00 deg, drop-one worth +65 % / +69 %
    (per fold +70 / +59 %, +73 / +62 %).  On the six-run design with 35 deg circles (the virtual
    dataset's, read through 1 deg) it is not found: sway damping is named (+33 %), the misalignment
    fitted 0.62 deg predicts the held-out runs 19 % worse, and the honest gain is +0.5 % [-4 %, +4 %]
    (flagged), the virtual KCS's circles again (README, "turning circles are in the design")."""
    rep = _diagnosis(heading_misalignment=eps)
    finding = _found_on_top_of_the_ship(rep, "heading_misalignment")
    assert finding["estimate"]["misalignment_deg"] == pytest.approx(eps, rel=0.25), finding["estimate"]
