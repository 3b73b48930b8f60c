"""Hidden-effect cases for the diagnosis (SPEC section 7).

Linear truth model (pipeline.diagnose.truth): >= 20 cases drawn at random (seeded from
DiagnoseConfig.seed): each effect at a realistic magnitude (offset 1-3 deg, dead time 0.3-1 s,
cubic damping cutting the 20/20 yaw-rate amplitude by 15-35 %, speed loss 8-25 %) plus clean cases.
Truth parameters: the paper's Table 4 with the hull block and rudder block each scaled by a random
factor in [0.85, 1.15].  Train on 20/20 starboard + 10/10 port, validate on 20/20 port + 10/10
starboard (both sides, two amplitudes).  "Clean" = exactly linear plus white measurement noise.

Virtual tank (pipeline.tank, an MMG KCS): the ship has nonlinear damping and speed loss of its own,
so a clean tank is not "none"; the injected effect must be found on top of it (checked for a rudder
offset with speed held, where the KCS's own effects are smallest), and a clean tank must not show
an offset or a dead time.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest

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


def _oracle_gain(kind, cfg: TruthConfig, val_runs, base_mae: float) -> float:
    """Held-out gain of the truth's own structure at its TRUE parameters over the fitted baseline.

    When even the truth cannot beat the linear fit by 30 % on the held-out runs (a short dead time on
    a sluggish ship is absorbed by the linear time constants, and the baseline sits at the noise
    floor), no diagnosis can honestly show that gain.  Measured for case 07 (0.32 s dead time):
    baseline 0.074 deg, the truth model itself 0.087 deg.
    """
    from pipeline.diagnose.extended import NULL
    from pipeline.diagnose.fit import FitResult, evaluate, series_from_run

    extra = dict(NULL)
    u_ref = None
    if kind == "rudder_offset":
        extra["offset_deg"] = cfg.rudder_offset
    elif kind == "rudder_delay":
        extra["delay_s"] = cfg.rudder_delay
    elif kind == "nonlinear_yaw_damping":
        extra["n_rrr_s_per_deg2"] = cfg.n_rrr
    elif kind == "speed_loss":
        extra["speed_exponent"], u_ref = 1.0, cfg.u0
    oracle = FitResult((), np.array(cfg.theta), extra, {}, np.zeros((0, 0)), [], 0.0, 0.0, u_ref)
    mae = evaluate(oracle, [series_from_run(r) for r in val_runs])[0]["mae_psi_deg"]
    return (base_mae - mae) / base_mae


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=[f"{c[0]:02d}-{c[1]}" for c in CASES])
def test_hidden_effect_is_found(case):
    i, kind, mag, fa, fb, seed = case
    theta = np.array(list(PAPER_TABLE4.values()))
    theta[:4] *= fa
    theta[4:] *= fb
    cfg, truth = _true_estimate(kind, mag, TruthConfig(theta=tuple(theta), seed=seed))
    train, val = _truth_runs(cfg)
    rep = diagnose(train, val).report
    summary = {f["effect"]: (f["significant"], f["validation_gain"], f["z"]) for f in rep["findings"]}
    if kind == "none":
        assert rep["cause"] == "none", summary
        assert rep["extended"]["effects"] == []
        return
    finding = next(f for f in rep["findings"] if f["effect"] == kind)
    name, value = truth
    if _oracle_gain(kind, cfg, val, rep["baseline"]["validation"]["mae_psi_deg"]) < 0.30:
        # not demonstrable on held-out data by any model: no false cause, and the fit still sees it
        assert rep["cause"] in (kind, "none"), summary
        assert set(rep["extended"]["effects"]) <= {kind}, summary
        assert abs(finding["estimate"][name] - value) <= 0.25 * abs(value), (name, finding["estimate"], value)
        return
    assert rep["cause"] == kind, summary
    assert finding["significant"]
    assert finding["validation_gain"] >= 0.30, summary
    est = finding["estimate"][name]
    assert abs(est - value) <= 0.25 * abs(value), (name, est, value)
    assert finding["uncertainty"][list(finding["estimate"])[0]] > 0


# ---------------------------------------------------------------- the virtual tank

tank = pytest.importorskip("pipeline.tank")

# Tank design: train on 20/20 starboard + port, validate on 10/10 starboard + port.  Training on one
# side per amplitude (as for the truth model) confounds side with amplitude on this nonlinear ship, and
# the offset then absorbs the amplitude dependence (measured: 2 deg injected, 1.02 estimated, -53 %
# held-out).  Both sides at one amplitude separate an asymmetry from a nonlinearity.
TANK_LEGS = [(20, "starboard"), (20, "port"), (10, "starboard"), (10, "port")]


@pytest.fixture(scope="module")
def tank_runs():
    from pipeline.config import TankConfig

    cache = {}

    def make(symmetric: bool = False, **kw):
        key = (symmetric, *sorted(kw.items()))
        if key not in cache:
            cfg = dc.replace(TankConfig(), **{"hold_speed": True, **kw})
            base = tank.KCSCoefficients()
            # the KCS's one asymmetry is the propeller's flow straightening gamma_R (port != starboard)
            coeffs = dc.replace(base, gamma_minus=base.gamma_plus) if symmetric else None
            runs = [tank.simulate(tank.zigzag(a, a, side, duration=80.0), cfg, coeffs=coeffs)
                    for a, side in TANK_LEGS]
            cache[key] = (runs[:2], runs[2:])
        return cache[key]

    return make


@pytest.mark.slow
def test_tank_offset_found_on_top_of_the_ship(tank_runs):
    """The KCS has its own asymmetry (propeller) and cubic damping: the injected offset must come out as
    the cause with a real held-out gain, and its size is the increment of the offset fitted jointly with
    cubic damping over the same fit on the uninjected tank (same seeds), within 25 %."""
    from pipeline.diagnose.fit import fit_model, series_from_run

    train, val = tank_runs(rudder_offset=2.0)
    rep = diagnose(train, val).report
    off = next(f for f in rep["findings"] if f["effect"] == "rudder_offset")
    assert rep["cause"] == "rudder_offset", off["evidence"]
    # against a STABLE baseline (the fit keeps the stable optimum, see fit_baseline): held-out error
    # bounded; the offset's gain on it is real but smaller than against the unstable baseline of the
    # single-start fit (57 deg held-out, which any extension "improved" by > 30 %)
    assert rep["folds"][0]["baseline"]["stable"], rep["baseline"]["parameters"]
    assert rep["baseline"]["validation"]["mae_psi_deg"] < 15.0, rep["baseline"]["validation"]
    assert off["significant"] and off["validation_gain"] >= 0.10, off["evidence"]
    effects = ("rudder_offset", "nonlinear_yaw_damping")
    clean_train, _ = tank_runs()
    inj = fit_model([series_from_run(r) for r in train], effects, max_nfev=200)
    ref = fit_model([series_from_run(r) for r in clean_train], effects, max_nfev=200)
    increment = inj.extra["offset_deg"] - ref.extra["offset_deg"]
    assert abs(increment - 2.0) <= 0.25 * 2.0, (inj.extra, ref.extra)


@pytest.mark.slow
def test_clean_tank_shows_no_offset_or_delay(tank_runs):
    """A port/starboard-symmetric KCS: no offset, no dead time.  (The default KCS, whose propeller makes
    gamma_R differ port and starboard, legitimately shows an offset of about -1 deg: measured -0.99 deg,
    significant on 80 s runs; that is the ship's own asymmetry, SPEC's "propeller asymmetry".)"""
    train, val = tank_runs(symmetric=True)
    rep = diagnose(train, val).report
    sig = {f["effect"] for f in rep["findings"] if f["significant"]}
    assert not sig & {"rudder_offset", "rudder_delay"}, rep["findings"]
    # speed held: speed dependence is not even tried
    sl = next(f for f in rep["findings"] if f["effect"] == "speed_loss")
    assert sl["validation_gain"] is None and sl["estimate"]["max_speed_loss"] < 0.03, sl


@pytest.mark.slow
def test_free_tank_speed_loss_is_measured_not_imagined(tank_runs):
    """Speed free: the KCS loses 8-35 % of its speed in a 20/20 and speed dependence is tried; with the
    speed held it is not (above).  (Measured: on this ship the linear model's misfit is dominated by
    its nonlinearity, so speed dependence alone does not pass held-out validation; not asserted.)"""
    train, val = tank_runs(hold_speed=False)
    rep = diagnose(train, val).report
    sl = next(f for f in rep["findings"] if f["effect"] == "speed_loss")
    assert sl["validation_gain"] is not None
    assert 0.08 <= sl["estimate"]["max_speed_loss"] <= 0.35, sl["estimate"]
    delay = next(f for f in rep["findings"] if f["effect"] == "rudder_delay")
    assert not delay["significant"], delay


@pytest.mark.slow
def test_tank_dead_time_is_measured_on_top_of_the_ship(tank_runs):
    """A 0.6 s dead time on the KCS: the dead time fitted jointly with cubic damping on the training runs,
    minus the same fit on the uninjected tank (same seeds), is within 25 % of 0.6 s.  (Measured: the
    extension does not pass held-out validation on this ship, -46 %, so detection is not asserted; the
    linear model's misfit of the MMG ship, 5-7 deg, dominates a 0.6 s lag.)"""
    from pipeline.diagnose.fit import fit_model, series_from_run

    effects = ("rudder_delay", "nonlinear_yaw_damping")
    train, _ = tank_runs(rudder_delay=0.6)
    clean_train, _ = tank_runs()
    inj = fit_model([series_from_run(r) for r in train], effects, max_nfev=200)
    ref = fit_model([series_from_run(r) for r in clean_train], effects, max_nfev=200)
    increment = inj.extra["delay_s"] - ref.extra["delay_s"]
    assert abs(increment - 0.6) <= 0.25 * 0.6, (inj.extra, ref.extra)
    assert inj.std["delay_s"] > 0
