"""Hidden-effect cases for the diagnosis (docs/diagnosis.md).

Linear truth model (pipeline.diagnose.truth): >= 20 cases drawn at random (seeded from
DiagnoseConfig.seed): each effect at a realistic magnitude (offset 1-3 deg, dead time 0.3-1 s,
cubic damping cutting the 20/20 yaw-rate amplitude by 15-35 %, speed loss 8-25 %) plus clean cases.
Truth parameters: the paper's Table 4 with the hull block and rudder block each scaled by a random
factor in [0.85, 1.15].  Train on 20/20 starboard + 10/10 port, validate on 20/20 port + 10/10
starboard (both sides, two amplitudes).  "Clean" = exactly linear plus white measurement noise.

The virtual tank's cases (effects injected into the MMG KCS, found on top of the ship's own cubic
damping) are in tests/test_diagnose_tank.py.
"""

from __future__ import annotations

import dataclasses as dc
from types import SimpleNamespace

import numpy as np
import pytest
from selection_only import SELECTION_ONLY  # the setting, and its reason, of selection-only tests

from pipeline.config import DiagnoseConfig
from pipeline.diagnose import TruthConfig, diagnose, zigzag_truth
from pipeline.diagnose.truth import damping_for_cut, speed_loss_for
from pipeline.model import PAPER_TABLE4

N_CASES = 20
KINDS = ("none", "rudder_offset", "rudder_delay", "nonlinear_yaw_damping", "speed_loss")


def _draw_cases():
    rng = np.random.default_rng(DiagnoseConfig().seed)
    cases = []
    for i in range(N_CASES):
        kind = KINDS[i % len(KINDS)]
        fa, fb = rng.uniform(0.85, 1.15, 2)
        mag = {
            "none": 0.0,
            "rudder_offset": rng.uniform(1.0, 3.0) * rng.choice([-1.0, 1.0]),
            "rudder_delay": rng.uniform(0.3, 1.0),
            "nonlinear_yaw_damping": rng.uniform(0.15, 0.35),
            "speed_loss": rng.uniform(0.08, 0.25),
        }[kind]
        cases.append((i, kind, float(mag), float(fa), float(fb), int(rng.integers(1, 10**6))))
    return cases


CASES = _draw_cases()


def _truth_runs(cfg: TruthConfig):
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
    runs = [
        zigzag_truth(a, a, side, 80.0, dc.replace(cfg, seed=cfg.seed + j)) for j, (a, side) in enumerate(legs)
    ]
    return runs[:2], runs[2:]


def _true_estimate(kind, mag, cfg):
    """(truth config with the effect, the injected magnitude in the estimate's terms)."""
    if kind == "rudder_offset":
        return dc.replace(cfg, rudder_offset=mag), ("offset_deg", mag)
    if kind == "rudder_delay":
        return dc.replace(cfg, rudder_delay=mag), ("delay_s", mag)
    if kind == "nonlinear_yaw_damping":
        n = damping_for_cut(mag, cfg)
        return dc.replace(cfg, n_rrr=n), ("n_rrr_s_per_deg2", n)
    if kind == "speed_loss":
        k = speed_loss_for(mag, cfg)
        return dc.replace(cfg, speed_loss_k=k), ("coefficient_loss", mag)
    return cfg, None


def _oracle_gain(kind, cfg: TruthConfig, val_runs, base_mae: float, t_ship: float) -> tuple[float, float]:
    """Held-out gain (relative, and absolute in deg) of the truth's own structure at its TRUE parameters
    over the fitted baseline, each held-out run started by the diagnosis's own rule (the approach's
    estimate, boxed by its uncertainty: DiagnoseConfig.x0_window_T / x0_box_sigma, ``t_ship`` s the
    diagnosis's time scale), so the oracle and the baseline are judged alike.

    When even the truth cannot beat the linear fit by 30 % on the held-out runs (a short dead time on
    a sluggish ship is absorbed by the linear time constants, and the baseline sits at the noise
    floor), no diagnosis can honestly show that gain.  Measured for case 07 (0.32 s dead time):
    baseline 0.074 deg, the truth model itself 0.087 deg.
    """
    from pipeline.diagnose.effects import Terms
    from pipeline.diagnose.fit import evaluate, series_from_run, with_initial_states

    terms, ratio = Terms(), False
    if kind == "rudder_offset":
        terms.offset_deg = cfg.rudder_offset
    elif kind == "rudder_delay":
        terms.delay_s = cfg.rudder_delay
    elif kind == "nonlinear_yaw_damping":
        terms.feat_code, terms.feat_eq, terms.feat_coef = [0], [1], [cfg.n_rrr]
    elif kind == "speed_loss":
        terms.speed_exponent, ratio = 1.0, True
    d = DiagnoseConfig()
    series = [series_from_run(r) for r in val_runs]
    series = with_initial_states(series, d.x0_window_T * t_ship if d.x0_window_T > 0 else None, None,
                                 d.x0_box_sigma)
    oracle = SimpleNamespace(theta=np.array(cfg.theta), terms=terms, u_ref=cfg.u0 if ratio else None,
                             plain=False)
    mae = evaluate(oracle, series)[0]["mae_psi_deg"]
    return (base_mae - mae) / base_mae, base_mae - mae


#: None today.  Case 12 (a 0.35 s dead time) gives "none", which is right on this design: the truth's
#: own structure at its true parameters cuts the baseline's held-out 0.107 deg by 0.062 deg, below
#: the 0.1 deg heading floor (measured 2026-11-24, CASE12_DESIGN comment).
KNOWN_WRONG: dict[int, str] = {}


#: cases in make test: the first draw of every kind (CASES cycles through KINDS); the other draws
#: are marked long (make test-long), which keeps make test within its 10 minutes on 2 cores
CI_DRAWS = len(KINDS)


@pytest.mark.slow
@pytest.mark.parametrize("case", [
    pytest.param(c, id=f"{c[0]:02d}-{c[1]}",
                 marks=([pytest.mark.xfail(strict=True, reason="measured: " + KNOWN_WRONG[c[0]])]
                        if c[0] in KNOWN_WRONG else []) + ([] if c[0] < CI_DRAWS else [pytest.mark.long]))
    for c in CASES])
def test_hidden_effect_is_found(case):
    i, kind, mag, fa, fb, seed = case
    theta = np.array(list(PAPER_TABLE4.values()))
    theta[:4] *= fa
    theta[4:] *= fb
    cfg, truth = _true_estimate(kind, mag, TruthConfig(theta=tuple(theta), seed=seed))
    train, val = _truth_runs(cfg)
    rep = diagnose(train, val, cfg=SELECTION_ONLY).report
    summary = {f["effect"]: (f["significant"], f["validation_gain"], f["z"]) for f in rep["findings"]}
    if kind == "none":
        assert rep["cause"] == "none", summary
        assert rep["extended"]["effects"] == []
        return
    finding = next(f for f in rep["findings"] if f["effect"] == kind)
    name, value = truth
    rel, cut = _oracle_gain(kind, cfg, val, rep["baseline"]["validation"]["mae_psi_deg"],
                            rep["settings"]["time_scale_s"])
    floor = max(2 * rep["settings"]["heading_noise_deg"], rep["settings"]["min_abs_gain_deg"])
    if rel < 0.30 or cut < floor:
        # not demonstrable on held-out data by any model: no false cause, and the fit still sees it.
        # A held-out gain must also be above the heading noise level in absolute terms
        # (case 12: a 0.35 s dead time, oracle cut 0.035 deg of a 0.080 deg baseline, below 0.1 deg)
        assert rep["cause"] in (kind, "none"), summary
        assert set(rep["extended"]["effects"]) <= {kind}, summary
        if name in finding["estimate"]:
            est = finding["estimate"][name]
            assert abs(est - value) <= 0.25 * abs(value), (name, finding["estimate"], value)
        return
    assert rep["cause"] == kind, summary
    assert finding["significant"]
    assert finding["validation_gain"] >= 0.30, summary
    if kind == "nonlinear_yaw_damping" and finding["form"] == "abs":
        # the fit chose the r|r| form on its training cost: the form does not match the r^3 truth, so
        # (estimates are judged within 25 % only where the form matches) only its sense is checked
        assert finding["estimate"]["n_rr_per_deg"] < 0
        return
    est = finding["estimate"][name]
    assert abs(est - value) <= 0.25 * abs(value), (name, est, value)
    assert finding["uncertainty"][list(finding["estimate"])[0]] > 0


#: Case 12 again, on a design meant to make a 0.35 s dead time material.  Physics:
#: the truth's time scale is T = 4.1 s and its zigzags have a period of ~30 s whatever their size (the
#: heading trigger scales with the rudder), so the dead time's phase lag at the zigzag frequency is
#: omega tau = 4 deg on either design and the linear time constants absorb most of it; what is left is
#: the yaw acceleration tau d(delta)/dt at each reversal, larger the larger the swing and the faster
#: the rudder.  Oracle (the truth's structure at its true parameters, held-out MAE psi, each run
#: started by the diagnosis's own rule) against the fitted baseline.  Measured 2026-11-24 once the
#: fit kept the coupling to its ship sign (a21 <= 0, fit.Layout.bounds; before it the baseline took
#: a21 > 0 and absorbed most of the dead time):
#:   20/20 + 10/10 at 14 deg/s (the standard design): 0.107 -> cut 0.062 deg (58 %), under the
#:     0.1 deg heading floor, and the diagnosis names none, which is right (test_hidden_effect_is_found);
#:   30/30 + 15/15 at 30 deg/s (this design): 0.155 -> cut 0.110 deg (71 %); the diagnosis names
#:     rudder_delay alone, 0.351 s against 0.35 s, fold gains 0.71 / 0.72.
#: Before the sign bound (same day, boxed held-out start) the same two designs gave 0.080 -> 0.035 and
#: 0.120 -> 0.075 deg and none on every design tried (35/35 + 20/20, 60 deg/s, 35/10 + 20/10, three
#: legs a side: cuts 0.071 to 0.092 deg); those were not re-measured with the bound.
CASE12_DESIGN = {
    "legs": ((30, "starboard"), (15, "port"), (30, "port"), (15, "starboard")),
    "rudder_rate": 30.0,  # deg/s
}


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "measured with the best linear model as the baseline (DiagnoseConfig.best_linear_baseline, the "
    "unconstrained fit): it absorbs most of the 0.35 s dead time, and the truth's own structure cuts its "
    "held-out error by 62 % but only 0.075 deg, under the 0.1 deg heading floor, so this design no "
    "longer shows the dead time (docs/diagnosis.md, Known limits)"))
def test_short_dead_time_is_found_where_the_design_shows_it():
    i, kind, mag, fa, fb, seed = CASES[12]
    assert kind == "rudder_delay"
    theta = np.array(list(PAPER_TABLE4.values()))
    theta[:4] *= fa
    theta[4:] *= fb
    rate = CASE12_DESIGN["rudder_rate"]
    cfg = TruthConfig(theta=tuple(theta), seed=seed, rudder_delay=mag, rudder_rate=rate)
    runs = [
        zigzag_truth(a, a, side, 80.0, dc.replace(cfg, seed=cfg.seed + j))
        for j, (a, side) in enumerate(CASE12_DESIGN["legs"])
    ]
    rep = diagnose(runs[:2], runs[2:], cfg=SELECTION_ONLY).report
    summary = {f["effect"]: (f["significant"], f["validation_gain_folds"]) for f in rep["findings"]}
    # the design is material: the truth's own structure at its true parameters clears both bars
    rel, cut = _oracle_gain(kind, cfg, runs[2:], rep["baseline"]["validation"]["mae_psi_deg"],
                            rep["settings"]["time_scale_s"])
    floor = max(2 * rep["settings"]["heading_noise_deg"], rep["settings"]["min_abs_gain_deg"])
    assert rel >= 0.30 and cut >= floor, (rel, cut, floor)
    # and the diagnosis finds it: the cause, alone in the extended model, >= 30 % in both folds
    assert rep["cause"] == kind, summary
    assert rep["extended"]["effects"] == [kind], summary
    finding = next(f for f in rep["findings"] if f["effect"] == kind)
    assert finding["significant"], finding["evidence"]
    assert len(finding["validation_gain_in_extended_folds"]) == 2, summary
    assert min(finding["validation_gain_in_extended_folds"]) >= 0.30, summary
    est = rep["extended"]["effect_estimates"][kind]["estimate"]["delay_s"]
    assert abs(est - mag) <= 0.25 * mag, (est, mag)
    assert rep["extended"]["effect_estimates"][kind]["uncertainty"]["delay_s"] > 0
