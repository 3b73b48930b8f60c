"""Does the diagnosis generalise? Cases judged against truths NOT written in its own formulas.

The truths (tests/truths/, no import of pipeline.model or pipeline.diagnose):

- :mod:`truths.swayyaw`: a continuous-time sway-yaw ship integrated by RK4 at 0.01 s (one case at
  0.0025 s), logged at 0.08 s, with a rate-limited servo, zigzag logic on the measured heading, two
  ships that are not the paper's (fast and strongly stable; slow and nearly course-unstable) and
  effects in forms of their own (servo lag, r|r|, tanh stall, |.| cross terms, ...), AR(1) sensor
  noise and rudder encoder quantisation.  32 seeded cases (:func:`truths.cases.draw_cases`, seed
  ``DiagnoseConfig().seed + 2``), each trained on 20/20 S + 10/10 P, validated on 20/20 P + 10/10 S
  and, when the diagnosis API takes ``test``, reported on 15/15 S + 15/15 P.  What counts as right
  is stated in :mod:`truths.cases` (clean -> "none"; an injected effect -> its name, significant,
  held-out gain >= 30 %, estimate within 25 % where the form matches).
- :mod:`truths.kvlcc2`: another ship and tank: the KVLCC2 MMG model (Yasukawa & Yoshimura 2015) at
  full scale written as MARIN SIMMAN .dat files, read with ``--scale 45.7``.  Side-swap folds (train
  starboard 20/20 + 10/10, validate port; and the reverse): each must name a cause and cut the
  held-out heading MAE by >= 50 %.
- :mod:`truths.mariner`: a third ship and another model family: the Mariner's Abkowitz model
  (Chislett & Stroem-Tejsen 1965) at full scale, only just course-stable when linear, forces made
  non-dimensional by the instantaneous speed, a hull moment Y_0, N_0 worth a 1.1 deg rudder offset,
  the measured rudder logged; MARIN .dat read with ``--scale 40``; the same side-swap folds.  Its
  linear form must give "none", its linear form with Y_0, N_0 the offset within 25 %, the published
  model a cause and a >= 50 % held-out cut with the offset among the effects.
- :mod:`truths.tanker`: a fourth ship and model family, added after the method and run as found: the
  Van Berlekom & Goddard (1972) 190 000 dwt tanker at full scale (|v| v and |v| r hull terms, the
  rudder force on the propeller slipstream with a rudder-drift interaction, the propeller's
  constant side force and moment, a surge equation), course-unstable when linear; MARIN .dat read
  with ``--scale 50``; the same side-swap folds.  Linear -> none (and the baseline recovers its
  parameters within 10 %), linear with the propeller's constants -> the offset alone within 25 %,
  the published model a cause and a >= 50 % held-out cut with the offset among the effects.
- :mod:`truths.container`: a fifth ship and model family, with a degree of freedom the diagnosis has
  not: the Son & Nomoto (1982) container ship, sway-yaw-ROLL coupled (GM 0.3 m: 5-9 deg of heel in
  these zigzags, a lightly damped roll mode of 28 s period in the zigzag's band), cubic hull terms of
  every kind, the rudder on the slipstream, a surge equation, port/starboard symmetric; MARIN .dat read
  with ``--scale 35``; the same side-swap folds.  Linearised with its roll mode -> none (the roll is
  no effect of the catalogue and must not be named as one), the published model a cause, a >= 50 %
  held-out cut, and no rudder, servo or sensor effect (it has none).
- :mod:`truths.crossflow`: a sixth model family, logged as another tank's logger would: Clarke et al.'s
  (1983) regression derivatives, twin rudders with flow straightening, and Hoerner's cross-flow drag
  integrated over the length (no candidate's formula); two hulls (a ferry, a full-form bulker close to
  course instability); canonical CSV at MODEL scale, 20 Hz, AR(1) heading and rate noise, the rudder
  quantised; the same side-swap folds.  Linear -> none; with the cross-flow drag a cause, a >= 50 %
  held-out cut and only hull kinds; with a process disturbance a cause among the hull kinds wherever
  the truth's own equations (the oracle) cut the held-out error by >= 30 %.
- Scale invariance: the same KVLCC2 runs (a) Froude-scaled to model scale and read without
  ``--scale``, (b) read at full scale without ``--scale`` (a 320 m "model"; logged step scaled by
  sqrt(45.7) so that the runs have the same number of samples): the cause must be the one found
  with ``--scale 45.7``.

Every raw file goes through ``ingest`` (canonical CSV or MARIN .dat), as a user's data would.
Marker ``generalise`` selects these tests (``pytest -m generalise``); ``python
tests/truths/run_cases.py`` prints the table of every case.
"""

from __future__ import annotations

import dataclasses as dc
import inspect
import math
import os
import time
from pathlib import Path

import numpy as np
import pytest
from selection_only import SELECTION_ONLY  # the setting, and its reason, of selection-only tests
from truths import cases as tc
from truths import container as ct
from truths import crossflow as cf
from truths import kvlcc2 as kv
from truths import mariner as mr
from truths import swayyaw as sy
from truths import tanker as tk
from truths.files import froude_to_model, marin_test_name, write_csv, write_marin

from pipeline.config import DiagnoseConfig, IngestConfig
from pipeline.ingest import ingest_file

pytestmark = [pytest.mark.generalise, pytest.mark.slow]

SEED = DiagnoseConfig().seed + 2
CASES = tc.draw_cases(SEED)
SCALE = 45.7
KV_DURATION = 800.0       # s full scale (118 s at 1:45.7): 2-3 zigzag periods of the 20/20
KV_LEGS = ((20, "starboard"), (10, "starboard"), (20, "port"), (10, "port"))
KV_MIN_GAIN = 0.50        # docs/diagnosis.md: each side-swap fold cuts the held-out heading MAE by half


# ------------------------------------------------------------------------------------------ runner
def load(path: Path, scale: float | None = None, dt: float | None = None, model_scale: float | None = None):
    """A raw file through ingest, as ``diagnose --train FILE`` reads it (run id = file stem).

    ``model_scale``: model-scale files of a known ship, as a dataset.toml's ``[data] model_scale``."""
    cfg = IngestConfig() if dt is None else dc.replace(IngestConfig(), dt=dt)
    kw = {} if model_scale is None else {"model_scale": model_scale}
    run = ingest_file(path, scale=scale, config=cfg, **kw)
    run.meta["run_id"] = path.stem
    return run


def diagnose_report(train, validate, test=None, cfg=None) -> dict:
    """diagnosis.json of pipeline.diagnose.diagnose; ``test`` runs passed when the API takes them."""
    from pipeline.diagnose import diagnose

    kw = {} if cfg is None else {"cfg": cfg}
    if test and "test" in inspect.signature(diagnose).parameters:
        kw["test"] = test
    out = diagnose(train, validate, **kw)
    return out.report if hasattr(out, "report") else out


def run_case(case: tc.Case, folder: Path) -> tuple[dict, float]:
    """(diagnosis report, CPU seconds of the diagnosis) of one sway-yaw case, without the reference fit
    (the truth table judges the selection, its findings and the test runs' gain, which it does not
    change: tests/selection_only.py)."""
    paths = tc.write_runs(case, folder)
    runs = {k: [load(p) for p in v] for k, v in paths.items()}
    t0 = time.process_time()
    rep = diagnose_report(runs["train"], runs["validate"], runs["test"],
                          cfg=DiagnoseConfig(reference_fit=False))
    return rep, time.process_time() - t0


def write_kvlcc2(folder: Path, seed: int, disturbance_deg: float = 0.0, misalignment_deg: float = 0.0,
                 rate_bias_deg_s: float = 0.0) -> dict[tuple[int, str], Path]:
    """The four KVLCC2 zigzags as full-scale MARIN .dat files (and their model-scale twins, without
    the sensor faults: ``misalignment_deg`` and ``rate_bias_deg_s``, at MODEL scale, as in
    :func:`write_ship`)."""
    folder.mkdir(parents=True, exist_ok=True)
    ship = kv.KVLCC2()
    out = {}
    for j, (a, side) in enumerate(KV_LEGS):
        f = kv.simulate_zigzag(ship, a, a, side, duration=KV_DURATION, seed=seed + j,
                               disturbance_deg=disturbance_deg)
        name = f"kvlcc2_zz{a}_{side[0].upper()}"
        out[(a, side)] = write_marin(f, folder / f"{name}.dat", marin_test_name("KVLCC2", a, a),
                                     heading_misalignment_deg=misalignment_deg,
                                     rate_bias_deg_s=rate_bias_deg_s / math.sqrt(SCALE))
        out[(a, side, "model")] = write_marin(froude_to_model(f, SCALE), folder / f"{name}_model.dat",
                                              marin_test_name("KVLCC2", a, a))
    return out


def kvlcc2_fold(files: dict, fold: int, how: str = "full", nested_gain: bool = True) -> dict:
    """Side-swap fold 1 (train starboard, validate port) or 2 (the reverse).

    how: "full" (full-scale files, --scale 45.7), "model" (model-scale twins, no --scale; the
    ship's model scale given as a dataset.toml's ``[data] model_scale`` gives it, since the file
    names the KVLCC2, whose 320 m Lpp at scale 1 is no tank model),
    "unscaled" (full-scale files read as if model scale, step 0.08 sqrt(45.7) s).
    nested_gain: False where only the selection is asserted (DiagnoseConfig.nested_gain)."""
    sides = ("starboard", "port") if fold == 1 else ("port", "starboard")

    def get(side):
        res = []
        for a in (20, 10):
            if how == "full":
                res.append(load(files[(a, side)], scale=SCALE))
            elif how == "model":
                res.append(load(files[(a, side, "model")], model_scale=SCALE))
            else:
                res.append(load(files[(a, side)], dt=0.08 * math.sqrt(SCALE)))
        return res

    return diagnose_report(get(sides[0]), get(sides[1]), cfg=fold_config(nested_gain))


def fold_config(nested_gain: bool) -> DiagnoseConfig:
    """The diagnosis setting of a side-swap fold: the defaults where its honest gain is asserted, else
    the selection-only setting (tests/selection_only.py: neither the nested gain nor the reference fit
    changes the selection and findings these folds assert)."""
    return DiagnoseConfig() if nested_gain else SELECTION_ONLY


# ------------------------------------------------------------------------------ truths hold up
def test_truth_signs_and_nomoto():
    """The truths keep docs/contract.md#run-data's signs; each ship's coefficients give back its Nomoto
    indices."""
    for ship in sy.SHIPS.values():
        back = sy.coefficients_to_nomoto(ship.coefficients)
        for k in ("K", "T1", "T2", "T3"):
            assert back[k] == pytest.approx(getattr(ship, k), rel=1e-9), (ship.name, k)
        f = sy.simulate(sy.Truth(ship=ship), sy.Zigzag(10, 1e9, "starboard", 20.0), seed=0, noise=False)
        assert f["r"].iloc[-1] > 0 and f["v"].iloc[-1] < 0    # starboard rudder: r > 0, drift outward
        assert f["psi"].iloc[-1] > 0 and f["y0"].iloc[-1] > 0  # heading and track to starboard
    s = kv.check_signs()
    assert s["r_deg_s"] > 0 and s["v_m_s"] < 0


def test_truth_effects_are_what_they_say():
    """Servo lag and dead time act as stated; AR(1) noise has the stated correlation; quantisation."""
    base = sy.Truth(ship=sy.FAST)
    zz = sy.Zigzag(20, 20, "starboard", 12.0)
    f = sy.simulate(base.with_effects(delay_s=0.5), zz, seed=0, noise=False).attrs["true"]
    t, d, de = f["time"].to_numpy(), f["delta"].to_numpy(), f["delta_eff"].to_numpy()
    assert np.allclose(de[t > 1.0], np.interp(t[t > 1.0] - 0.5, t, d), atol=1.0)  # 0.08 s grid
    g = sy.simulate(base.with_effects(lag_s=0.8), zz, seed=0, noise=False).attrs["true"]
    d = g["delta"].to_numpy()
    lagged = np.zeros_like(d)  # the logged rudder through tau y' = x - y, exact for a held input
    a = math.exp(-0.08 / 0.8)
    for k in range(1, d.size):
        lagged[k] = a * lagged[k - 1] + (1 - a) * 0.5 * (d[k] + d[k - 1])
    assert np.max(np.abs(g["delta_eff"].to_numpy() - lagged)) < 0.3
    assert np.max(np.abs(g["delta_eff"].to_numpy() - d)) > 10.0    # and it is a real lag
    sen = sy.Sensors(ar1_phi=0.95, noise_psi=0.1)
    h = sy.simulate(sy.Truth(ship=sy.FAST, sensors=sen), sy.Zigzag(10, 10, "port", 400.0), seed=3)
    e = h["psi"].to_numpy() - h.attrs["true"]["psi"].to_numpy()
    rho = np.corrcoef(e[1:], e[:-1])[0, 1]
    assert abs(rho - 0.95) < 0.03 and abs(e.std() - 0.1) < 0.03
    q = sy.simulate(sy.Truth(ship=sy.FAST, sensors=sy.Sensors(noise_delta=0.0, quant_delta=0.1)), zz, seed=1)
    assert np.allclose(q["delta"] * 10, np.round(q["delta"] * 10), atol=1e-9)


def test_marin_file_round_trip(tmp_path):
    """A KVLCC2 run written as MARIN .dat and ingested with --scale is the model-scale truth."""
    f = kv.simulate_zigzag(kv.KVLCC2(), 20, 20, "port", duration=300.0, seed=1)
    p = write_marin(f, tmp_path / "zz.dat", marin_test_name("KVLCC2", 20, 20))
    lines = p.read_text().splitlines()
    assert lines[1] == "Zig-zag manoeuvring for KVLCC2 : 20 / -20" and lines[2] == ""
    assert len(lines[3].split("\t")) == 11 and lines[-1] == ""
    run = load(p, scale=SCALE)
    assert run.meta["first_side"] == "port" and run.meta["rudder_deg"] == 20
    m = froude_to_model(f, SCALE)
    t = run.frame["time"].to_numpy()
    sel = (t > 5) & (t < t[-1] - 5)
    for col, tol in (("psi", 0.15), ("r", 0.1), ("delta", 0.25), ("u", 0.01), ("v", 0.01)):
        ref = np.interp(t, m["time"], m[col])
        assert np.max(np.abs(run.frame[col].to_numpy() - ref)[sel]) < tol, col


def test_kvlcc2_zigzags_against_published():
    """Free-running check of the MMG KVLCC2 against SIMMAN 2008 (MARIN) figures.

    Published first overshoots: 10/10 about 8 deg, 20/20 about 13 deg.  A wrong sign or unit in the
    MMG model moves them by far more than the band here (3-12 and 8-20 deg), which allows for the
    difference between an MMG prediction and a tank (Yasukawa & Yoshimura's own comparison shows a
    few degrees either way) and for the side: the single propeller makes them side-dependent.
    Measured (run_cases.py prints them): 10/10 5.1 S / 7.2 P, 20/20 10.6 S / 13.9 P deg.
    """
    s = kv.KVLCC2()
    for a, lo, hi in ((10, 3.0, 12.0), (20, 8.0, 20.0)):
        for side in ("starboard", "port"):
            m = kv.zigzag_metrics(kv.simulate_zigzag(s, a, a, side, duration=400.0, noise=False), a)
            assert lo < m["overshoots_deg"][0] < hi, (a, side, m)
    # 20/20 of a full form loses a quarter to a third of its speed (docs/diagnosis.md; HSVA runs 30 %)
    m = kv.zigzag_metrics(kv.simulate_zigzag(s, 20, 20, "starboard", duration=400.0, noise=False), 20)
    assert 0.6 < m["lowest_speed_ratio"] < 0.8


# ---------------------------------------------------------------------------- the 32 cases
#: Cases the method gets wrong today (tests/truths/run_cases.py), strict xfails with the measured
#: reason, so a fix shows up as XPASS.  None since 2026-11-24 (32 of 32): cases 12 and 13, servo lags
#: of 0.93 and 0.78 s, were found but estimated 0.26 / 0.27 s while the output-error fit could turn the
#: coupling a21 positive (+9.9 against the truth's -15.9) and absorb the lag; with a12, a21 <= 0
#: (fit.Layout.bounds) they are estimated 0.934 and 0.752 s (tests/test_diagnose_signs.py).
KNOWN_WRONG: dict[str, str] = {}
#: make test runs a CI-sized cut (a clean case per sensor kind and one case of each effect family
#: the method finds today, both ships); `make generalise` (TANKTEST_GENERALISE=full) runs all 32.
CI_CASES = ("00", "03", "04", "08", "10", "12", "16", "25", "27", "31")
FULL = os.environ.get("TANKTEST_GENERALISE") == "full"
#: the cases of this file `make test` leaves to `make test-long` (tests/conftest.py marks them long):
#: make test keeps one case of each family (clean, offset, yaw damping; the MARIN KVLCC2 fold 1; the
#: Mariner clean and side swap; the tanker's linear side swap; the container's linear; the cross-flow
#: ferry), so every truth family is still exercised; these are the further draws, folds and variants.
LONG_TESTS = frozenset({
    "test_case[03-slow-none]", "test_case[04-fast-none]", "test_case[10-fast-rudder_delay]",
    "test_case[12-fast-rudder_lag]", "test_case[25-fast-rudder_asymmetry]", "test_case[27-fast-speed_loss]",
    "test_case[31-slow-rudder_offset+nonlinear_yaw_damping]",
    "test_case_fresh_draw[fresh777-31-slow-rudder_offset+nonlinear_yaw_damping]",
    "test_kvlcc2_marin_side_swap_with_a_process_disturbance[seed1300-fold1]",
    "test_kvlcc2_rate_gyro_bias_beside_a_misalignment[1300-False-1]",
    "test_kvlcc2_false_misalignment_is_refused_by_the_approach[1]",
    "test_kvlcc2_same_cause_model_scale_file",
    "test_mariner_linear_is_none[2]", "test_mariner_hull_constants_are_an_offset[1]",
    "test_mariner_hull_constants_are_an_offset[2]",
    "test_mariner_process_disturbance_is_not_an_effect[1-linear-seed1350]",
    "test_mariner_process_disturbance_is_not_an_effect[1-offset-seed1350]",
    "test_mariner_process_disturbance_is_not_an_effect[2-linear-seed1350]",
    "test_mariner_process_disturbance_is_not_an_effect[2-offset-seed1350]",
    "test_mariner_disturbance_short_horizons_tell",
    "test_tanker_side_swap[1-full-seed1300]", "test_tanker_side_swap[2-linear-seed1300]",
    "test_tanker_side_swap[2-full-seed1300]", "test_tanker_process_disturbance[linear-seed1300-fold1]",
    "test_tanker_heading_misalignment[linear-0.3deg-fold1]", "test_tanker_rate_gyro_bias[linear-1]",
    "test_tanker_with_turning_circles[linear-1300]", "test_a_step_that_hinges_on_one_training_run_is_found",
    "test_container_side_swap[full-seed1300-dist0-fold1]",
    "test_crossflow_side_swap[ferry-linear-seed1300-fold1]",
    "test_crossflow_disturbed_side_swap[bulker-crossflow-seed2000-fold1]",
})


def known_wrong(values: tuple, known: dict, key, test_id: str, measured: str = ""):
    """``pytest.param(*values)``, a strict xfail with its measured reason when ``key`` is in ``known``
    (the measurement date in ``measured``)."""
    why = known.get(key)
    marks = [pytest.mark.xfail(strict=True, reason=f"measured{' ' + measured if measured else ''}: {why}")]
    return pytest.param(*values, id=test_id, marks=marks if why else [])


def _case_param(c):
    return known_wrong((c,), KNOWN_WRONG, c.cid, f"{c.cid}-{c.ship}-{c.expected}")


@pytest.mark.parametrize("case", [_case_param(c) for c in CASES if FULL or c.cid in CI_CASES])
def test_case(case, tmp_path):
    rep, _ = run_case(case, tmp_path)
    ok, why, fig = tc.judge(case, rep, tc.noise_mae_psi(case))
    assert ok, f"{case.truth}: " + "; ".join(why) + f" | got {fig}"


#: A fresh draw of the 32 cases (new magnitudes, noise seeds) that no choice of the method has seen:
#: the data that reports, not the data that chose (make generalise; make test runs its case 31).
#: Seeds 1013, 2026 and 4242 gave 32 of 32 on 2026-11-24; seed 777 gave 29 and is the one kept
#: here.  Its case 31 (offset -1.26 deg + r^3 on the slow ship) then lost the offset in the backward
#: pass (without it 469.5 deg held-out against 0.23, block t 1.02 by the divergence itself): the
#: backward pass no longer removes an effect without which the model runs away
#: (pipeline.diagnose.select), and the case is right.
FRESH_SEED = 777
#: Cases 15 and 17 (r|r| / r^3 shares 0.42 / 0.41, slow ship) were strict xfails until the output-
#: error polish fitted each training run's start (pipeline.diagnose.fit._fit_from, 2026-11-24): the
#: fitted linear yaw damping had taken up part of the nonlinearity, whose term then changed the peak
#: yaw rate by 4.7 %, under the 5 % floor.  Now right, estimates -0.002628 against -0.002623 (r|r|)
#: and -0.000657 against -0.000633 (r^3).
FRESH_KNOWN_WRONG: dict = {}


def _fresh_param(c):
    return known_wrong((c,), FRESH_KNOWN_WRONG, c.cid, f"fresh{FRESH_SEED}-{c.cid}-{c.ship}-{c.expected}",
                       "2026-11-24")


#: make test runs the fresh draw's case 31 only (what the backward pass's run-away rule mended)
@pytest.mark.parametrize("case", [_fresh_param(c) for c in tc.draw_cases(FRESH_SEED)
                                  if FULL or c.cid == "31"])
def test_case_fresh_draw(case, tmp_path):
    """The truth table's rules on a draw no choice has seen (FRESH_SEED)."""
    rep, _ = run_case(case, tmp_path)
    ok, why, fig = tc.judge(case, rep, tc.noise_mae_psi(case))
    assert ok, f"{case.truth}: " + "; ".join(why) + f" | got {fig}"


def _fake_report(base_deg, cause="none", effects=(), noise_deg=0.02, gain=0.0):
    return {"cause": cause, "extended": {"effects": list(effects)}, "findings": [],
            "gain": {"mae_psi_relative_reduction": gain},
            "baseline": {"validation": {"mae_psi_deg": base_deg}},
            "settings": {"heading_noise_deg": noise_deg, "min_abs_gain_deg": 0.1}}


def test_immaterial_effect_rule_known_answers():
    """cases.demonstrable: room = baseline - the truth's own (noise) MAE against the diagnosis's floor
    max(2 noise, 0.1 deg) and MIN_GAIN; and judge's consequences, on hand-made reports."""
    shown, words = tc.demonstrable(_fake_report(0.12), 0.04)       # room 0.08 < 0.1
    assert not shown and "0.080 deg" in words
    assert tc.demonstrable(_fake_report(0.28), 0.04)[0]              # room 0.24, 86 %
    assert not tc.demonstrable(_fake_report(0.28, noise_deg=0.15), 0.04)[0]   # floor 0.30
    assert not tc.demonstrable(_fake_report(1.0), 0.75)[0]           # 0.25 deg but 25 % < MIN_GAIN
    vv = next(c for c in CASES if c.cid == "18")
    # immaterial: "none" is right, a rudder-side name is not, an accepted name is
    assert tc.judge(vv, _fake_report(0.12), 0.04)[0]
    assert not tc.judge(vv, _fake_report(0.12, "rudder_offset", ["rudder_offset"]), 0.04)[0]
    named = _fake_report(0.12, "nonlinear_sway_damping", ["nonlinear_sway_damping"])
    assert not tc.judge(vv, named, 0.04)[0]          # a name without its findings row
    named["findings"] = [{"effect": "nonlinear_sway_damping", "significant": True, "estimate": {}}]
    assert tc.judge(vv, named, 0.04)[0]
    # material: "none" is a miss
    assert not tc.judge(vv, _fake_report(0.50), 0.04)[0]
    # without the noise figure the old rule: "none" is a miss
    assert not tc.judge(vv, _fake_report(0.12))[0]
    # a clean case never relaxes
    clean = next(c for c in CASES if c.cid == "00")
    assert not tc.judge(clean, _fake_report(0.05, "rudder_offset", ["rudder_offset"]), 0.04)[0]


def test_noise_mae_is_the_logged_noise():
    """noise_mae_psi of a clean white-noise case is the MAE of its heading noise: sigma sqrt(2/pi)."""
    c = next(c for c in CASES if c.cid == "00")
    sigma = sy.Sensors(**c.sensors).noise_psi
    assert tc.noise_mae_psi(c) == pytest.approx(sigma * math.sqrt(2.0 / math.pi), rel=0.15)


@pytest.mark.xfail(strict=True, reason="measured 2026-11-24: v|v| share 0.70 (fast ship, case 18) gives "
                   "none.  It is immaterial in heading: the baseline's held-out heading MAE is 0.12 deg "
                   "against the truth's own 0.04 deg (its noise), 0.08 deg of room under the 0.1 deg floor, "
                   "so test_case judges 'none' right (cases.demonstrable).  The effect lives in the sway "
                   "(the candidate of the truth's form, fitted, recovers y_vv -5.08 / n_vv -27.0 against "
                   "-5.04 / -26.7; peak v 0.42 -> 0.29 m/s, baseline against the fit), and the "
                   "diagnosis judges the heading only")
def test_sway_only_effect_is_named(tmp_path):
    """What a sway-channel judge would have to do: name the hull's nonlinearity of case 18, whose
    whole signature is in the sway."""
    case = next(c for c in CASES if c.cid == "18")
    rep, _ = run_case(case, tmp_path)
    assert rep["cause"] in tc.HULL_NL, (rep["cause"], rep["extended"]["effects"])


# ------------------------------------------------------------------ another ship and tank: KVLCC2
@pytest.fixture(scope="module")
def kv_files(tmp_path_factory):
    return write_kvlcc2(tmp_path_factory.mktemp("kvlcc2"), seed=SEED * 100)



def assert_names_a_cause_and_halves(rep: dict) -> None:
    """The side-swap bar (``KV_MIN_GAIN``) on one fold's report: a cause named, and the extended model
    cutting the held-out heading MAE of the fold by at least KV_MIN_GAIN."""
    base = rep["baseline"]["validation"]["mae_psi_deg"]
    ext = rep["extended"]["validation"]["mae_psi_deg"]
    assert rep["cause"] != "none", (rep["cause"], base, ext)
    assert 1.0 - ext / base >= KV_MIN_GAIN, (rep["cause"], base, ext, rep["extended"]["effects"])

_KV: dict = {}


def _kv_report(files, fold: int, honest: bool | None = None) -> dict:
    """The diagnosis of one side-swap fold, made once per process, fold and setting (a module fixture
    of both folds was made again by each xdist worker that ran one of its tests: 100 s each).  The
    honest gain (``honest``; by default in fold 1 only: the nested leave-one-run-out holds out each of
    the same 4 runs in either fold, measured 2026-11-24: 0.695 [0.55, 0.79] in both) is three
    quarters of a fold's time; without it the fold is selection-only (:func:`fold_config`)."""
    honest = fold == 1 if honest is None else honest
    key = (str(files[(20, "starboard")]), fold, honest)
    if key not in _KV:
        _KV[key] = kvlcc2_fold(files, fold, nested_gain=honest)
    return _KV[key]


#: measured with the best linear model as the baseline (DiagnoseConfig.best_linear_baseline): the bar
#: was set against the bounded fit, which sits on its bound a21 = 0 (docs/diagnosis.md, "The baseline")
KV_BEST_LINEAR = ("measured against the best linear model (the unconstrained fit): fold 1 names rudder "
                  "offset + nonlinear sway damping, its validation runs 2.73 -> 2.28 deg (-16 %) below the "
                  "halving bar (2.78 with the nested gain's settings), honest "
                  "gain +9 % [-4 %, 20 %] (4.66 -> 4.24 deg); against the bounded fit +59 % [44 %, 70 %] "
                  "(docs/diagnosis.md, Known limits)")


#: all make test-long's (make test keeps the measured KVLCC2 files' other checks below): fold 1's
#: selection only ("1-selection": the side-swap bar on the fold's own held-out runs, a strict xfail on
#: the measured reason, the fold's selection being the same with or without the nested gain:
#: tests/selection_only.py; about a minute), the fold with its honest gain ("1", the nested
#: leave-one-run-out: 3.5 min of 2 cores) and the mirror fold
@pytest.mark.parametrize("fold,honest", [
    pytest.param(1, False, marks=[pytest.mark.xfail(strict=True, reason=KV_BEST_LINEAR), pytest.mark.long],
                 id="1-selection"),
    pytest.param(1, True, marks=[pytest.mark.xfail(strict=True, reason=KV_BEST_LINEAR), pytest.mark.long],
                 id="1"),
    pytest.param(2, False, marks=pytest.mark.long, id="2"),            # long: the mirror fold
])
def test_kvlcc2_marin_side_swap(kv_files, fold, honest):
    """Each side-swap fold names a cause, and the extended model cuts the held-out
    heading MAE of that fold (the runs of the other side, never trained on) by at least half.

    And the honest gain (item 4: nested leave-one-run-out, each of the 4 runs held out, the effects
    chosen again on the other 3, every one of them validated once; fold 1, whose 4 runs are fold 2's)
    cuts it by at least half too.
    Measured 2026-11-24 with each training run's start fitted (pipeline.diagnose.fit._fit_from):
    0.571 [0.39, 0.69], held-out 14.06 -> 2.18 deg in fold 1 (sway damping + asymmetry); before it,
    with the coupling sign bound: 0.695 [0.55, 0.79] in both folds, held-out
    13.98 -> 2.30 and 7.23 -> 1.52 deg (sway damping + asymmetry); the inner causes differ by held-out
    run (asymmetry 0.27 and 0.91, sway damping 0.64, offset 0.77).  Before the bound 0.626; it was
    0.41 (a strict xfail) while the inner selections validated on one run (core._inner_folds)."""
    rep = _kv_report(kv_files, fold, honest)
    assert_names_a_cause_and_halves(rep)
    if honest:
        gain = rep["gain"]["mae_psi_relative_reduction"]
        assert gain is not None and gain >= KV_MIN_GAIN, rep["gain"]


#: the KVLCC2 folds with the Mariner tests' process disturbance (MR_DISTURBANCE_DEG's reasoning), the
#: noise seeds of make test's folds; make generalise adds three more (and make test runs fold 1 of the
#: first only: CI time, 2026-11-25)
KV_DIST_SEEDS = (SEED * 100, *((700, 2000, 3000) if FULL else ()))
#: (seed, fold) below the 50 % bar with the disturbance (strict xfails): none since the coupling sign
#: bound (fit.Layout.bounds); before it (3000, 1) cut 49 % (offset + cross terms, 10.94 -> 5.57 deg)
#: Since the best linear model is the reported baseline (00d5cdf, 2026-11-27; make generalise bisected
#: on seed 700 fold 1) the bar is judged against the unconstrained fit, which holds these folds'
#: held-out side at 2.6-3.1 deg where the bounded fit, on its bound a21 = 0, held them at 7.5-14 deg.
#: Measured 2026-11-29 beside each: the reference structure (TK_ORACLE's) fitted on the same two runs
#: (_side_swap_oracle; test_kvlcc2_disturbed_side_swap_oracle): in three of the five folds it does not
#: halve the best linear model's error either.
KV_DIST_KNOWN_WRONG: dict[tuple[int, int], str] = {
    (SEED * 100, 1): "2026-11-27, failing on main since before the gate beats_best_linear (at 2a39f04 "
                     "too; cause not found): offset + sway damping named, held-out 2.62 -> 3.01 deg (worse "
                     "than the baseline), bar 50 %",
    (SEED * 100, 2): "2026-11-29: offset + sway damping named, held-out 3.07 -> 2.51 deg (18 %) against "
                     "the best linear model; the reference structure 1.87 (39 %), without its asymmetry "
                     "1.31 (57 %): within the catalogue's reach, missed",
    (700, 1): "2026-11-29: sway damping + rudder asymmetry named, held-out 2.61 -> 3.18 deg, worse than "
              "the best linear model; the reference structure 2.61 deg, no better: half the best linear "
              "model's error is beyond the catalogue on this fold",
    (700, 2): "2026-11-29: sway damping + rudder asymmetry named, held-out 3.12 -> 2.55 deg (18 %); the "
              "reference structure 2.12 (32 %), without its asymmetry 2.03 (35 %): the bar is beyond it too",
    (2000, 2): "2026-11-29: offset + cross terms named, held-out 2.93 -> 1.73 deg (41 %); the reference "
               "structure 1.43 (51 %), without its asymmetry 1.52 (48 %)",
    (3000, 1): "2026-11-29: sway damping + cross terms + rudder asymmetry named, held-out 2.76 -> 3.12 deg "
               "(-13 %); the reference structure 4.96 deg, worse than the best linear model",
}


def _kv_dist_param(seed, fold):
    return known_wrong((seed, fold), KV_DIST_KNOWN_WRONG, (seed, fold), f"seed{seed}-fold{fold}")


@pytest.mark.parametrize("seed,fold", [_kv_dist_param(s, f) for s in KV_DIST_SEEDS for f in (1, 2)
                                       if FULL or f == 1])
def test_kvlcc2_marin_side_swap_with_a_process_disturbance(tmp_path, seed, fold):
    """The side-swap bar on runs that carry what measured runs carry and no model has: a random external
    yaw moment in every run (0.5 deg of rudder, 30 s; truths.kvlcc2.simulate_zigzag).  Each side-swap
    fold must still name a cause and cut the held-out heading MAE by at least half.

    Measured 2026-11-24 (selection only): seed 1300 offset + yaw damping, 11.70 -> 2.98 and 7.20 -> 2.32
    deg (75 % / 68 %; without the disturbance yaw damping + asymmetry, 89 % / 64 %; at 1 deg, 63 % / 54 %);
    seed 700 cross terms + asymmetry, 79 % / 71 %; seed 2000 yaw damping + asymmetry, 89 % / 53 %; seed
    3000 offset + cross terms, 49 % / 62 % (KV_DIST_KNOWN_WRONG).  The verdict moves between the hull's
    nonlinearity (yaw damping, cross terms) and its propeller's side dependence (offset, asymmetry), both
    of which the truth has."""
    files = write_kvlcc2(tmp_path, seed=seed, disturbance_deg=MR_DISTURBANCE_DEG)
    rep = kvlcc2_fold(files, fold, nested_gain=False)
    assert_names_a_cause_and_halves(rep)
    assert not set(rep["extended"]["effects"]) & {"rudder_delay", "rudder_lag"}, rep["extended"]["effects"]


#: two sensor faults at once in the KVLCC2 stand-in's files: the heading reference 1 deg off the
#: centreline (TK_MISALIGN_DEG's careless set-up) and a rate gyro biased by TK_RATE_BIAS_DEG_S
KV_SENSOR_FAULTS = {"misalignment_deg": 1.0, "rate_bias_deg_s": 0.1}


#: (noise seed, with the process disturbance of MR_DISTURBANCE_DEG) of the sensor-fault folds: make
#: test the first's fold 1; make generalise both folds of all
KV_FAULT_RUNS = ((SEED * 100, False), *(((700, True), (2000, True), (3000, True)) if FULL else ()))


#: (noise seed, disturbed, fold) below the side-swap bar (strict xfails), measured 2026-11-29 against the
#: best linear model (the reported baseline since 00d5cdf; KV_DIST_KNOWN_WRONG); the same seeds'
#: disturbed files without the sensor faults are within the catalogue's reach on none of seed 700's
#: folds and seed 3000's fold 1 (the reference structure fitted on the same runs: 0 %, 35 %, -78 %)
KV_FAULT_KNOWN_WRONG: dict[tuple[int, bool, int], str] = {
    (700, True, 1): "2026-11-29: cross terms named, held-out 6.17 -> 3.32 deg (46 %) against the best "
                    "linear model (the unconstrained fit; the bounded one presses on a21 = 0)",
    (700, True, 2): "2026-11-29: cross terms named, held-out 6.96 -> 4.51 deg (35 %) against the best "
                    "linear model",
    (2000, True, 1): "2026-11-29: cross terms named, held-out 5.40 -> 2.97 deg (45 %) against the best "
                     "linear model",
    (3000, True, 1): "2026-11-29: sway damping named, held-out 5.45 -> 3.45 deg (37 %) against the best "
                     "linear model",
    (3000, True, 2): "2026-11-29: sway damping named, held-out 5.46 -> 3.37 deg (38 %) against the best "
                     "linear model",
}


def _kv_fault_param(seed, disturbed, fold):
    return known_wrong((seed, disturbed, fold), KV_FAULT_KNOWN_WRONG, (seed, disturbed, fold),
                       f"{seed}-{disturbed}-{fold}")


@pytest.mark.parametrize("seed,disturbed,fold", [_kv_fault_param(s, d, k) for s, d in KV_FAULT_RUNS
                                                 for k in (1, 2) if FULL or k == 1])
def test_kvlcc2_rate_gyro_bias_beside_a_misalignment(tmp_path, seed, disturbed, fold):
    """The side-swap bar with two sensor faults a new tank's files may carry together
    (KV_SENSOR_FAULTS): the rate bias is read against the heading without a model and corrected
    before any fit (pipeline.diagnose.datacheck.rate_bias), said in the summary, and the side-swap
    fold names a cause and cuts the held-out heading MAE by half, with no misalignment named but
    the files' own.

    Measured 2026-11-25 (seed 1300, selection only): before the correction heading_misalignment was
    named as the cause at -5.3 / -3.4 deg (the files' is +1 deg), beside sway damping and cross terms
    (87 % / 75 %): the fit bought the r channel's constant with a sway-reading bias of 0.11 / 0.07
    m/s.  The bias alone was harmless (sway damping + asymmetry, as on clean files), and so was the
    misalignment alone (sway damping, 77 % / 65 %; the misalignment not named, fitted 0.02 / -0.11
    deg: this hull's own straight-running drift stands in for it).  With the correction: bias read
    0.101, 0.102, 0.099, 0.100 deg/s, then what the misaligned files give, 14.07 -> 3.27 and 7.23 ->
    2.57 deg.  With the disturbance (make generalise): seed 700 sway damping + cross terms +
    asymmetry, 86 % / 56 %; seeds 2000 and 3000 (measured without the bias, which the correction
    removes) sway damping, 74 % / 60 % and 73 % / 55 %."""
    files = write_kvlcc2(tmp_path, seed=seed, disturbance_deg=MR_DISTURBANCE_DEG if disturbed else 0.0,
                         **KV_SENSOR_FAULTS)
    rep = kvlcc2_fold(files, fold, nested_gain=False)
    rates = rep["data_checks"]["rate_bias"]
    assert len(rates["per_run"]) == 4 and all(x["corrected"] for x in rates["per_run"].values()), rates
    for x in rates["per_run"].values():
        assert x["bias_deg_s"] == pytest.approx(KV_SENSOR_FAULTS["rate_bias_deg_s"], abs=0.005), rates
    assert rates["warning"] and rates["warning"] in rep["summary"]
    assert_names_a_cause_and_halves(rep)
    if "heading_misalignment" in rep["extended"]["effects"]:
        est = next(f for f in rep["findings"] if f["effect"] == "heading_misalignment")["estimate"]
        assert est["misalignment_deg"] == pytest.approx(KV_SENSOR_FAULTS["misalignment_deg"], rel=tc.EST_TOL)


@pytest.mark.parametrize("fold", [1, 2] if FULL else [1])
def test_kvlcc2_false_misalignment_is_refused_by_the_approach(tmp_path, monkeypatch, fold):
    """The second guard against the same false finding: with the rate-gyro correction bypassed (a
    bias the check could not read), the misalignment that would make the ship itself drift several
    degrees on its straight approaches is not material (heading_misalignment.MAX_OWN_DRIFT_DEG).

    Measured 2026-11-25 (seed 1300, KV_SENSOR_FAULTS, the bias left in): before the rule
    heading_misalignment was the cause at -5.29 / -3.40 deg (87 % / 75 %), implying some 5.7 / 3.8
    deg of the ship's own drift on approaches that read about -0.4 deg (20/20 S: v -0.0078 m/s at
    1.18 m/s); with it sway damping alone, 14.75 ->
    3.25 and 7.46 -> 2.32 deg, the misalignment fitted -0.11 / -0.36 deg and not named."""
    import pipeline.diagnose.core as core

    monkeypatch.setattr(core, "correct_rate_bias", lambda series, check: list(series))
    files = write_kvlcc2(tmp_path, seed=SEED * 100, **KV_SENSOR_FAULTS)
    rep = kvlcc2_fold(files, fold, nested_gain=False)
    assert all(x["corrected"] for x in rep["data_checks"]["rate_bias"]["per_run"].values())
    mis = next(f for f in rep["findings"] if f["effect"] == "heading_misalignment")
    eps = mis["estimate"]["misalignment_deg"]
    assert abs(eps) < 2 * KV_SENSOR_FAULTS["misalignment_deg"], mis["estimate"]
    if "heading_misalignment" in rep["extended"]["effects"]:
        # named, it is the files' own misalignment, not the false one the bias would buy
        assert eps == pytest.approx(KV_SENSOR_FAULTS["misalignment_deg"], rel=tc.EST_TOL), mis["estimate"]
    assert_names_a_cause_and_halves(rep)


def test_kvlcc2_same_cause_model_scale_file(kv_files):
    """Model-scale files (no --scale) and full-scale files with --scale 45.7: the same cause."""
    # the cause only: the model-scale run without the nested honest gain (it does not change the cause)
    assert kvlcc2_fold(kv_files, 1, "model", nested_gain=False)["cause"] == _kv_report(kv_files, 1)["cause"]


def test_kvlcc2_full_scale_files_without_scale_are_refused(kv_files):
    """Full-scale files read without --scale would be a 320 m "model": ingest refuses
    them in one line (the verdict can no longer silently change with a forgotten --scale)."""
    from pipeline.errors import InputError

    with pytest.raises(InputError, match="scale"):
        load(kv_files[(20, "starboard")], dt=0.08 * math.sqrt(SCALE))


# ------------------------------------------------------------ a third ship and model family: Mariner
MR_SCALE = 40.0           # a 4.0 m tank model of the 160.93 m Mariner
MR_DURATION = 600.0       # s full scale (95 s at 1:40): 3-4 periods of the 20/20 zigzag
MR_SEED = SEED * 100 + 50   # the noise seed of make test's Mariner runs (1350)
#: other noise seeds, run by make generalise (TANKTEST_GENERALISE=full): the same ship, the same design
MR_SEEDS = (700, 2000, 3000, 4000, 5000, 6000)
#: seeds the method names wrongly (measured, each a strict xfail with its reason): none since the
#: groups of three of 2026-11-24; before them seed 2000 named rudder saturation alone (32 % / 21 %),
#: and before the replacement move seed 5000 named saturation + asymmetry for the speed loss
MR_KNOWN_WRONG: dict = {}
MR_WRONG = ("rudder_delay", "rudder_lag", "rudder_asymmetry")   # not in the truth (the measured
#           rudder is logged, so the servo is no hidden effect; the published model is port/starboard
#           symmetric but for the constant Y_0, N_0, which is an offset)


def write_ship(folder: Path, simulate, ship, label: str, duration: float, scale: float, seed: int,
               disturbance_deg: float = 0.0, misalignment_deg: float = 0.0,
               rate_bias_deg_s: float = 0.0) -> dict[tuple[int, str], Path]:
    """The four zigzags (KV_LEGS) of one full-scale truth ``ship`` (its ``simulate_zigzag`` and
    ``form``) as full-scale MARIN .dat files named after ``label`` (``disturbance_deg``: the truth's
    process disturbance, 0 for none; ``misalignment_deg``: the files' heading reference off the
    centreline; ``rate_bias_deg_s``: a rate gyro's bias at MODEL scale, written Froude-scaled;
    truths.files.write_marin)."""
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for j, (a, side) in enumerate(KV_LEGS):
        f = simulate(ship, a, a, side, duration=duration, seed=seed + j, scale=scale,
                     disturbance_deg=disturbance_deg)
        out[(a, side)] = write_marin(f, folder / f"{label.lower()}_{ship.form}_zz{a}_{side[0].upper()}.dat",
                                     marin_test_name(label, a, a), heading_misalignment_deg=misalignment_deg,
                                     rate_bias_deg_s=rate_bias_deg_s / math.sqrt(scale))
    return out


def side_swap_fold(files: dict, fold: int, scale: float, nested_gain: bool) -> dict:
    """Side-swap fold 1 (train starboard 20/20 + 10/10, validate port) or 2 (the reverse) of
    :func:`write_ship`'s files, read with ``--scale``."""
    sides = ("starboard", "port") if fold == 1 else ("port", "starboard")
    runs = [[load(files[(a, side)], scale=scale) for a in (20, 10)] for side in sides]
    return diagnose_report(runs[0], runs[1], cfg=fold_config(nested_gain))


def write_mariner(folder: Path, form: str, seed: int,
                  disturbance_deg: float = 0.0) -> dict[tuple[int, str], Path]:
    """The four Mariner zigzags of one form (:func:`write_ship`)."""
    return write_ship(folder, mr.simulate_zigzag, mr.Mariner(form=form), "Mariner", MR_DURATION, MR_SCALE,
                      seed, disturbance_deg)


_MR: dict = {}


def mariner_fold(tmp_root: Path, form: str, fold: int, nested_gain: bool = False,
                 seed: int = MR_SEED, disturbance_deg: float = 0.0) -> dict:
    """Side-swap fold 1 (train starboard 20/20 + 10/10, validate port) or 2 (the reverse) of one
    Mariner form and noise seed, made once per process (files, then the diagnosis)."""
    key = (form, seed, fold, nested_gain, disturbance_deg)
    if key not in _MR:
        files = _MR.get((form, seed, disturbance_deg))
        if files is None:
            files = _MR[(form, seed, disturbance_deg)] = write_mariner(
                tmp_root / f"{form}{seed}d{disturbance_deg:g}", form, seed=seed,
                disturbance_deg=disturbance_deg)
        _MR[key] = side_swap_fold(files, fold, MR_SCALE, nested_gain)
    return _MR[key]


@pytest.fixture(scope="module")
def mr_root(tmp_path_factory):
    return tmp_path_factory.mktemp("mariner")


def test_disturbance_is_the_stated_process():
    """truths.disturbance: unit standard deviation and lag-k autocorrelation exp(-k dt / tau) (known
    answers of the stationary Ornstein-Uhlenbeck process, within the sampling error of 200 000 samples
    of a process with 60 samples' correlation), the same draw for the same seed."""
    from truths.disturbance import ornstein_uhlenbeck

    x = ornstein_uhlenbeck(200_000, 0.5, 30.0, seed=4)
    assert abs(np.std(x) - 1.0) < 0.03 and abs(np.mean(x)) < 0.05
    for k in (1, 60):
        rho = np.corrcoef(x[:-k], x[k:])[0, 1]
        assert rho == pytest.approx(math.exp(-k * 0.5 / 30.0), abs=0.02), (k, rho)
    assert np.array_equal(x[:100], ornstein_uhlenbeck(100, 0.5, 30.0, seed=4))
    assert not np.array_equal(x[:100], ornstein_uhlenbeck(100, 0.5, 30.0, seed=5))


def test_mariner_truth_is_what_it_says():
    """contract signs (docs/contract.md#run-data) in every form; the linear Mariner is only just stable (slow
    pole 118 s); the published model loses speed in a 20/20 zigzag and overshoots far less than its linear
    part (its nonlinear sway and cross terms stabilise it); the equivalent offset balances the hull
    constants."""
    for form in ("linear", "offset", "full"):
        s = mr.check_signs(form)
        assert s["r_deg_s"] > 0 and s["v_m_s"] < 0, (form, s)
    slow = -1.0 / mr.linear_poles()[1]          # s; L/U = 20.9 s
    assert 100.0 < slow < 140.0, slow
    full = kv.zigzag_metrics(mr.simulate_zigzag(mr.Mariner(), 20, 20, noise=False), 20)
    lin = kv.zigzag_metrics(mr.simulate_zigzag(mr.Mariner(form="linear"), 20, 20, noise=False), 20)
    assert full["lowest_speed_ratio"] < 0.9 and lin["lowest_speed_ratio"] == 1.0
    assert max(full["overshoots_deg"]) < 0.5 * max(lin["overshoots_deg"]), (full, lin)
    # the offset: the linear ship with the rudder at the equivalent offset (contract sign,
    # docs/contract.md#run-data; the published rudder is its minus) and the constants' ship at zero rudder
    # have the same steady yaw rate: the yaw rates at which each ship's linear forces vanish
    d0 = mr.equivalent_offset_deg() * mr.RAD
    lin_s, off_s = mr.Mariner(form="linear"), mr.Mariner(form="offset")

    def steady_r(s, d_pub):
        a = np.array([[mr.forces(s, 0, 1, 0, 0)[k] - mr.forces(s, 0, 0, 0, 0)[k],
                       mr.forces(s, 0, 0, 1, 0)[k] - mr.forces(s, 0, 0, 0, 0)[k]] for k in (1, 2)])
        return np.linalg.solve(a, -np.array(mr.forces(s, 0, 0, 0, d_pub)[1:]))[1]

    assert steady_r(lin_s, -d0) == pytest.approx(steady_r(off_s, 0.0), rel=1e-9)
    assert 0.5 < mr.equivalent_offset_deg() < 2.0


@pytest.mark.parametrize("fold", [1, 2])
def test_mariner_linear_is_none(mr_root, fold):
    """The linear Mariner is the baseline's own family in another parameterisation (a slow pole near the
    stability margin):
    nothing may be named.  Measured 2026-11-24 (seed 1350): none, held-out 0.050 / 0.061 deg in the two
    folds (seed 700: 0.05 / 0.11)."""
    rep = mariner_fold(mr_root, "linear", fold)
    assert rep["cause"] == "none" and rep["extended"]["effects"] == [], (rep["cause"], rep["extended"])


@pytest.mark.parametrize("fold", [1, 2])
def test_mariner_hull_constants_are_an_offset(mr_root, fold):
    """The linear Mariner with its Y_0, N_0: rudder_offset alone, within 25 % (tc.EST_TOL) of the
    equivalent offset.  Measured 2026-11-24 (seed 1350): 1.112 / 1.108 deg against 1.108, held-out cut
    98 % / 99 % (seed 700: 1.12 / 1.13 deg, 95 % / 90 %)."""
    rep = mariner_fold(mr_root, "offset", fold)
    assert rep["cause"] == "rudder_offset", rep["extended"]
    assert rep["extended"]["effects"] == ["rudder_offset"], rep["extended"]
    f = next(x for x in rep["findings"] if x["effect"] == "rudder_offset")
    assert f["estimate"]["offset_deg"] == pytest.approx(mr.equivalent_offset_deg(), rel=tc.EST_TOL)


def _mr_seed_param(seed):
    return known_wrong((seed,), MR_KNOWN_WRONG, seed, f"seed{seed}", "2026-11-24")


@pytest.mark.parametrize("seed", [_mr_seed_param(s) for s in (MR_SEED, *(MR_SEEDS if FULL else ()))])
@pytest.mark.parametrize("fold", [1, pytest.param(2, marks=pytest.mark.long)])   # long: the mirror fold
def test_mariner_side_swap(mr_root, fold, seed):
    """The published Mariner, as the MARIN KVLCC2 folds: each side-swap fold names
    a cause and cuts the held-out heading MAE by at least half; every named effect is one the truth
    has (hull nonlinearity, speed dependence, the constants as an offset, the cubic rudder terms),
    and the hull's offset is among them, within 25 % of its equivalent.  Fold 1 also measures the
    honest gain (nested leave-one-run-out over the 4 runs; the same runs in fold 2), which must reach
    the truth cases' bar, 30 % (tc.MIN_GAIN); make generalise only (100 s of make test's time).

    Measured 2026-11-24 (seed 1350): offset + speed loss + cross terms in both folds, offset 1.15 /
    1.16 deg against 1.11, held-out 3.15 -> 0.35 and 5.44 -> 0.27 deg (89 % / 95 %), honest gain 0.90.
    Other seeds (make generalise): 700, 2000, 3000, 4000, 5000, 6000 the same (81-96 %, offset
    1.15-1.19 deg): 7 of 7.  Seed 5000 was wrong before the replacement move of select (offset +
    cross terms + saturation + asymmetry, full, where saturation and asymmetry stood for the speed
    loss: 80 % / 88 %), seed 2000 before the groups of three (saturation alone, 32 % / 21 %: the
    three that replace it pass only together).  Before the two changes
    to select of that day (pipeline.diagnose.select's docstring): seed 1350 named rudder saturation
    alone (-45 % force at 20 deg, the truth's cubic rudder terms give -4 %), 32 % / 23 %, since the
    offset and the cross terms hurt held-out alone and the pair fallback's pool held neither; seed 700
    named speed loss + sway damping, 61 % / 57 %, and left out the offset though it passed on top.
    """
    honest = fold == 1 and seed == MR_SEED and FULL    # make test: the KVLCC2 honest gain only
    rep = mariner_fold(mr_root, "full", fold, nested_gain=honest, seed=seed)
    assert_names_a_cause_and_halves(rep)
    assert not set(rep["extended"]["effects"]) & set(MR_WRONG), rep["extended"]["effects"]
    assert "rudder_offset" in rep["extended"]["effects"], rep["extended"]["effects"]
    f = next(x for x in rep["findings"] if x["effect"] == "rudder_offset")
    assert f["estimate"]["offset_deg"] == pytest.approx(mr.equivalent_offset_deg(), rel=tc.EST_TOL)
    if honest:
        assert rep["gain"]["mae_psi_relative_reduction"] >= tc.MIN_GAIN, rep["gain"]


#: the process disturbance of the Mariner runs below: a yaw moment worth 0.5 deg of rudder (std), with
#: a 30 s correlation time (full scale), drawn afresh in every run (truths.mariner.simulate_zigzag).
#: Sized to matter: at this level the baseline's held-out error is 2-7 deg (seeds 700-6000), tens of
#: times the 0.05 deg sensor noise, as large as what the hull constants' 1.108 deg offset causes (4.4 deg
#: without the disturbance); at 1 deg the linear Mariner's heading moves by 1.7 deg on average, 4.7
#: deg at most, in a 10/10 zigzag (measured 2026-11-24).
MR_DISTURBANCE_DEG = 0.5
#: (form, seed) named wrongly under the disturbance (strict xfails, measured 2026-11-24, both folds).
#: The linear Mariner is course-unstable (D = a11 a22 - a12 a21 < 0); a free run of the measured rudder
#: from a model that unstable drifts with the disturbance, so the output-error fit settles at the stable
#: corner of the ship-sign bounds (a21 = 0, fit.Layout.bounds), and a hull nonlinearity then takes up
#: the drift on the held-out side too.  Without the coupling bound seeds 700 and 3000 gave none and the offset
#: form's seeds 3000, 5000 and 6000 named a rudder asymmetry for the offset (the fit's a21 > 0 let the
#: asymmetry stand in; test_mariner_disturbance_short_horizons_tell): with the bound those three are
#: right.  Tried and not adopted: refusing any step whose linear part still presses a bound (it also
#: refused the KVLCC2 and published-Mariner hull nonlinearities, 15 failures of make generalise);
#: bounding the coupling only in the extended models (the baseline free): these two none, but the
#: offset missed on seed 700 and the KVLCC2 fold 1 honest gain 0.47 (make generalise, 7 failures).
#: Seed 3000 (sway_yaw_coupling + nonlinear_sway_damping, both folds) is right since the short-horizon
#: judge (pipeline.diagnose.select, "no harm from the measured state", 2026-11-24); seed 700 then named
#: the coupling instead of the sway damping, which predicts the pieces worse (0.83 -> 0.96 deg).
#: Seed 700's linear form, a strict xfail until 2026-11-29 (the cross terms named in both folds, +17 %
#: held out against a baseline at a21 = 0), gives none in both folds against the best linear model (the
#: unconstrained fit, 2.36 / 1.73 deg held out).  Against it the offset form's seeds 3000 and 6000 give
#: none: the unconstrained fit's course-unstable drift stands in for the offset.
MR_DIST_KNOWN_WRONG = {
    ("offset", 3000): "2026-11-29: none named in both folds; the best linear model (the unconstrained fit) "
                      "holds the held-out side at 4.10 / 2.71 deg (the bounded fit 18.91 / 15.27); the "
                      "truth's own structure (the linear model + the offset) fitted on the same runs: fold "
                      "1 6.97 deg, worse than the best linear model (nothing to name on held-out evidence), "
                      "fold 2 1.53 deg (-44 %), missed",
    ("offset", 6000): "2026-11-29: none named in both folds; best linear model 3.64 / 4.15 deg held out "
                      "(the bounded fit 16.55 / 16.30); the truth's own structure: fold 1 6.23 deg, worse, "
                      "fold 2 1.62 deg (-61 %), missed",
}


def _dist_param(form, seed):
    return known_wrong((form, seed), MR_DIST_KNOWN_WRONG, (form, seed), f"{form}-seed{seed}")


@pytest.mark.parametrize("form,seed", [_dist_param(f, s) for f in ("linear", "offset")
                                       for s in (MR_SEED, *(MR_SEEDS if FULL else ()))])
@pytest.mark.parametrize("fold", [1, 2])
def test_mariner_process_disturbance_is_not_an_effect(mr_root, form, fold, seed):
    """Clean data must not get effects named that are not there, with an error no candidate
    describes and that is not repeatable: a random external yaw moment in every run (wind gusts at
    sea, a tank's residual circulation), on top of the linear Mariner (truth "none") and of the
    linear Mariner with its hull constants (truth: the 1.108 deg offset).  Whatever the disturbance
    does to one run, it does something else to the next, so nothing fitted to it may pass on runs it
    was not fitted on: linear -> none, offset -> rudder_offset alone within 25 %.

    Measured 2026-11-24 at 0.5 deg with the coupling sign bound and the short-horizon judge: linear
    none in 12 of the 14 folds of the 7 seeds (10 before the judge), offset right in all 14
    (MR_DIST_KNOWN_WRONG); without the bound linear none in all 14
    and offset right in 8.  Before the bound, at 1 deg (not re-measured): linear none in all 14 (seed
    1350: baseline held-out 2.34 / 3.70 deg; the nearest, an asymmetry and an offset at +12 % / +11 %,
    failed the block t-test and their floors); offset 3 of 7 seeds right.  Not tested, measured before
    the bound: the published (full) Mariner at 0.5 deg names offset + cross terms + saturation + an
    asymmetry (seed 1350; the truth's own structure, fitted, is no better held-out: 77 % both) or sway
    damping + saturation without the offset (seed 700; the truth's structure, fitted, is worse
    held-out: 26 % against 51 %)."""
    rep = mariner_fold(mr_root, form, fold, seed=seed, disturbance_deg=MR_DISTURBANCE_DEG)
    if form == "linear":
        assert rep["cause"] == "none" and rep["extended"]["effects"] == [], (rep["cause"], rep["extended"])
        # and the error is there to be explained: the disturbance, not a noise-level misfit
        assert rep["baseline"]["validation"]["mae_psi_deg"] > 10 * rep["settings"]["heading_noise_deg"]
        return
    assert rep["extended"]["effects"] == ["rudder_offset"], rep["extended"]["effects"]
    f = next(x for x in rep["findings"] if x["effect"] == "rudder_offset")
    assert f["estimate"]["offset_deg"] == pytest.approx(mr.equivalent_offset_deg(), rel=tc.EST_TOL)


def _horizon_mae(search, k: int, structure) -> float:
    """Held-out MAE psi (deg) of fold k's fit of ``structure`` over the pieces of the diagnosis's own
    short-horizon judge (Search.short: one ship time scale, each from the measured state)."""
    return float(np.mean([m for _, maes, _ in search.short(k, structure) for m in maes]))


@pytest.mark.xfail(strict=True, reason="measured 2026-11-27: the offset is no longer named (the verdict is "
                   "none) since the gate beats_best_linear (it passed at 2a39f04, before that gate's merge)")
def test_mariner_disturbance_short_horizons_tell(mr_root, monkeypatch):
    """What told the offset from a rudder asymmetry on seed 3000, with the diagnosis's own fits (its
    forms and starts): restarted from the measured state every ship time scale, the (true) offset
    beats the asymmetry in both folds, and the diagnosis names the offset.  Before the coupling sign
    bound (fit.Layout.bounds) it named the asymmetry: over the whole held-out runs the offset was worse
    in one fold (6.92 against 2.75 deg) while one ship time scale gave 0.51 / 1.34 against
    1.56 / 1.58 (measured 2026-11-24); the linear part's a21 > 0 let the asymmetry's fit stand in."""
    import pipeline.diagnose.core as core
    from pipeline.diagnose.fit import structure_of

    seen, select = [], core.select

    def keep(search, *a, **kw):     # the diagnosis's own Search (its fits), kept for the comparison
        seen.append(search)
        return select(search, *a, **kw)

    monkeypatch.setattr(core, "select", keep)
    files = write_mariner(mr_root / "horizon3000", "offset", 3000, MR_DISTURBANCE_DEG)
    st, po = ([load(files[(a, side)], scale=MR_SCALE) for a in (20, 10)] for side in ("starboard", "port"))
    rep = diagnose_report(st, po, cfg=DiagnoseConfig(nested_gain=False))
    assert rep["extended"]["effects"] == ["rudder_offset"], rep["extended"]["effects"]
    search = seen[0]
    off, asym = structure_of("rudder_offset"), structure_of("rudder_asymmetry")
    whole = [[search.eval(k, x)[0]["mae_psi_deg"] for x in (off, asym)] for k in (0, 1)]
    short = [[_horizon_mae(search, k, x) for x in (off, asym)] for k in (0, 1)]
    assert all(o < a for o, a in short), (short, whole)


# ------------------------------------------ a fourth ship and model family: the Van Berlekom tanker
TK_SCALE = 50.0           # a 6.1 m tank model of the 304.8 m tanker
TK_DURATION = 900.0       # s full scale (127 s at 1:50): 2-3 periods of the 20/20 zigzag
TK_SEED = SEED * 100      # the noise seed of make test's tanker runs (1300)
#: other noise seeds, run by make generalise: the same ship, the same design
TK_SEEDS = (700, 2000, 3000)
#: not in the truth: the measured rudder is logged (the servo is no hidden effect), and the published
#: model is port/starboard symmetric but for the propeller's constant Y_T, N_T, which is an offset
TK_WRONG = ("rudder_delay", "rudder_lag", "rudder_asymmetry", "heading_misalignment")
#: (form, seed) named wrongly (strict xfails, both folds)
TK_KNOWN_WRONG: dict = {
    ("full", SEED * 100): "2026-11-29 (failing since before the gate beats_best_linear, 2026-11-27): cubic "
                          "yaw damping + a rudder asymmetry of -0.059 +- 0.006 / -0.046 +- 0.006 named in "
                          "the two folds (the asymmetry is not in the truth), no offset; held-out 11.85 -> "
                          "2.60 / 3.34 -> 2.32 deg (78 % / 31 %) against the best linear model",
}


def write_tanker(folder: Path, form: str, seed: int, disturbance_deg: float = 0.0,
                 misalignment_deg: float = 0.0, rate_bias_deg_s: float = 0.0) -> dict[tuple[int, str], Path]:
    """The four tanker zigzags of one form (:func:`write_ship`)."""
    return write_ship(folder, tk.simulate_zigzag, tk.Tanker(form=form), "Tanker", TK_DURATION, TK_SCALE,
                      seed, disturbance_deg, misalignment_deg, rate_bias_deg_s)


_TK: dict = {}


def tanker_fold(tmp_root: Path, form: str, fold: int, seed: int = TK_SEED, disturbance_deg: float = 0.0,
                misalignment_deg: float = 0.0, rate_bias_deg_s: float = 0.0) -> dict:
    """Side-swap fold 1 (train starboard 20/20 + 10/10, validate port) or 2 (the reverse) of one tanker
    form and noise seed, made once per process (selection only: DiagnoseConfig.nested_gain off)."""
    runs = (form, seed, disturbance_deg, misalignment_deg, rate_bias_deg_s)
    folder = tmp_root / f"{form}{seed}d{disturbance_deg:g}m{misalignment_deg:g}b{rate_bias_deg_s:g}"
    return cached_fold(_TK, runs, fold, lambda: write_tanker(folder, *runs), TK_SCALE)


def cached_fold(cache: dict, runs: tuple, fold: int, write, scale: float) -> dict:
    """The selection-only report of side-swap fold ``fold`` of the files ``write()`` makes for the key
    ``runs``, each made once per process (files, then each fold's diagnosis) in ``cache``."""
    if (*runs, fold) not in cache:
        if runs not in cache:
            cache[runs] = write()
        cache[(*runs, fold)] = side_swap_fold(cache[runs], fold, scale, nested_gain=False)
    return cache[(*runs, fold)]


@pytest.fixture(scope="module")
def tk_root(tmp_path_factory):
    return tmp_path_factory.mktemp("tanker")


def test_tanker_truth_is_what_it_says():
    """contract signs (docs/contract.md#run-data) in every form; the linearised tanker is course-unstable (one
    pole > 0, time constant 380 s, 10 L/U) with a fast stable one; the published model loses speed in a 20/20
    zigzag and overshoots less than its linear part (its |v| v, |v| r terms stabilise it); the propeller's
    constants act as a rudder offset to port (negative in docs/contract.md#run-data) that grows as the ship
    slows."""
    for form in ("linear", "offset", "full"):
        s = tk.check_signs(tk.Tanker(form=form))
        assert s["r_deg_s"] > 0 and s["v_m_s"] < 0, (form, s)
    assert tk.approach_speed() == pytest.approx(8.18, abs=0.01)      # 16 kn at 80 rpm, deep water
    slow, fast = tk.linear_poles()[::-1]
    assert 300.0 < 1.0 / slow < 500.0 and -1.0 / fast < 30.0, (slow, fast)
    full = kv.zigzag_metrics(tk.simulate_zigzag(tk.Tanker(), 20, 20, noise=False), 20)
    lin = kv.zigzag_metrics(tk.simulate_zigzag(tk.Tanker(form="linear"), 20, 20, noise=False), 20)
    assert full["lowest_speed_ratio"] < 0.7 and lin["lowest_speed_ratio"] == 1.0
    assert max(full["overshoots_deg"]) < 0.5 * max(lin["overshoots_deg"]), (full, lin)
    u0 = tk.approach_speed()
    off = [tk.equivalent_offset_deg(u=k * u0) for k in (1.0, 0.8, 0.6)]
    assert -0.6 < off[0] < -0.4 and off[0] > off[1] > off[2], off


def _tk_param(form, seed):
    return known_wrong((form, seed), TK_KNOWN_WRONG, (form, seed), f"{form}-seed{seed}")


@pytest.mark.parametrize("form,seed", [_tk_param(f, s) for f in ("linear", "offset", "full")
                                       for s in (TK_SEED, *(TK_SEEDS if FULL else ()))
                                       if FULL or f != "offset"])    # make test: CI time
@pytest.mark.parametrize("fold", [1, 2])
def test_tanker_side_swap(tk_root, form, fold, seed):
    """A ship, a tank layout and a model family no part of the method was tuned on (added after the
    method, run as found): the Van Berlekom & Goddard tanker, course-unstable when linear, full-scale
    MARIN .dat read with ``--scale 50``, the side-swap folds (``KV_MIN_GAIN``).

    - linear (the baseline's own family, course-unstable): none;
    - offset (linear + the propeller's constants): rudder_offset alone, within 25 % of its equivalent;
    - full (the published model): a cause, a held-out cut of at least half, only effects the truth
      has (hull nonlinearity of |v| v and |v| r forms, speed, the offset, the rudder-drift
      interaction), and the offset among them, between its equivalents at the approach speed and at
      the lowest speed of the runs, each widened by 25 %.

    Measured 2026-11-24, seed 1300: linear none (baseline 0.09 / 0.08 deg; 1.35 / 0.48 before each
    training run's start was fitted, pipeline.diagnose.fit._fit_from); offset -0.513 / -0.509 deg
    against -0.502, 8.91 -> 0.12 and 10.43 -> 0.12 deg (99 %); full offset + cross terms in both folds,
    12.11 -> 1.09 and 6.01 -> 1.17 deg (91 % / 80 %), offset -0.61 / -0.53 deg (equivalents -0.50 at
    8.2 m/s, -0.73 at the 20/20's lowest 4.3 m/s).  Seeds 700, 2000, 3000 (make generalise): all
    right.  Before the fitted starts the linear form's seed 2000 named two damping terms (1.72 ->
    0.59 deg: the extension corrected a biased baseline).
    """
    _check_tanker(tanker_fold(tk_root, form, fold, seed), form)


def _check_tanker(rep: dict, form: str, misalignment_deg: float = 0.0) -> None:
    """test_tanker_side_swap's judgement of one fold's report (its docstring).  With files read through a
    misaligned heading (``misalignment_deg``, above the effect's floor) the truth has that sensor effect
    too: heading_misalignment named, within 25 %, and the form judged on the rest."""
    effects = rep["extended"]["effects"]
    if misalignment_deg:
        assert "heading_misalignment" in effects, (rep["cause"], rep["extended"])
        mis = next(f for f in rep["findings"] if f["effect"] == "heading_misalignment")
        assert mis["estimate"]["misalignment_deg"] == pytest.approx(misalignment_deg, rel=tc.EST_TOL), mis
        effects = [e for e in effects if e != "heading_misalignment"]
    if form == "linear":
        cause = "heading_misalignment" if misalignment_deg else "none"
        assert effects == [] and rep["cause"] == cause, (rep["cause"], rep["extended"])
        return
    est = next((f["estimate"]["offset_deg"] for f in rep["findings"] if f["effect"] == "rudder_offset"), None)
    if form == "offset":
        assert effects == ["rudder_offset"], rep["extended"]
        assert est == pytest.approx(tk.equivalent_offset_deg(tk.Tanker(form="offset")), rel=tc.EST_TOL)
        return
    assert_names_a_cause_and_halves(rep)
    assert not set(effects) & set(TK_WRONG), effects
    assert "rudder_offset" in effects, effects
    u0 = tk.approach_speed()
    lo, hi = tk.equivalent_offset_deg(u=0.5 * u0), tk.equivalent_offset_deg(u=u0)
    assert (1 + tc.EST_TOL) * lo <= est <= (1 - tc.EST_TOL) * hi, (est, lo, hi)


def test_tanker_linear_baseline_recovers_the_course_unstable_truth(tk_root):
    """The baseline fit on the baseline's own family, course-unstable (item 2: "course-unstable ships
    are real: fit them"): the linear tanker's 20/20 + 10/10 to starboard, full-scale MARIN files at
    1:50, the diagnosis's own series, context and starts.  Every linear parameter within 10 % of the
    truth's (its Jacobian Froude-scaled to the model, r in deg/s), the unstable pole's sign kept.

    Measured 2026-11-24, seed 2000: a11 -0.116 against -0.111, a22 -0.363 against -0.362, a21 -6.89
    against -6.86 (max 4 % off).  Before the refits from each run's own start
    (pipeline.diagnose.fit._fit_from): a11 -0.26, a22 -0.20 (training MAE psi 1.72 deg against the
    truth's 0.07), and the diagnosis named two damping terms on this linear hull."""
    from pipeline.diagnose.core import _context
    from pipeline.diagnose.fit import fit_structure, is_stable, series_from_run, with_initial_states

    files = write_tanker(tk_root / "recover2000", "linear", 2000)
    runs = [load(files[(a, "starboard")], scale=TK_SCALE) for a in (20, 10)]
    series = [series_from_run(r) for r in runs]
    ctx = _context(series)
    cfg = DiagnoseConfig()
    series = with_initial_states(series, cfg.x0_window_T * ctx.t_ship, None, cfg.x0_box_sigma)
    fit = fit_structure(series, (), ctx)
    J, b, _ = tk._linear(tk.Tanker(form="linear"))
    q, rad = math.sqrt(TK_SCALE), math.pi / 180.0
    # model scale: rates x sqrt(lambda); r in deg/s; the published rudder is minus the contract's
    # (docs/contract.md#run-data)
    truth = [J[0, 0] * q, J[0, 1] * rad / q, J[1, 0] / rad * TK_SCALE * q, J[1, 1] * q, -b[0] * rad,
             -b[1] * TK_SCALE]
    for name, got, want in zip(("a11", "a12", "a21", "a22", "b11", "b21"), fit.theta, truth, strict=True):
        assert got == pytest.approx(want, rel=0.10), (name, list(fit.theta), truth)
    assert not is_stable(fit.theta) and not is_stable(truth)


#: (form, seed, fold) of the disturbed tanker below named wrongly (strict xfails, each with its date)
TK_DIST_KNOWN_WRONG = {
    ("full", 700, 1): "2026-11-29: offset + hull terms + a rudder asymmetry of -0.023 +- 0.014 named (the "
                      "reference structure, its speed loss carried below its floor), the asymmetry a kind "
                      "the tanker does not have; held-out 11.12 -> 2.61 deg (77 %)",
    ("full", 3000, 1): "2026-11-29: yaw damping + cross terms named, without the offset that the "
                       "propeller's constants make (named in the undisturbed runs of this seed); held-out "
                       "7.63 -> 2.37 deg (69 %)",
    ("full", 3000, 2): "2026-11-29: yaw damping + cross terms named, without the offset; held-out 6.20 -> "
                       "3.97 deg (36 %)",
    ("full", SEED * 100, 1): "2026-11-29: offset + hull terms + a rudder asymmetry of -0.027 +- 0.016 named "
                             "(the reference structure, its speed loss carried below its floor), the "
                             "asymmetry a kind the tanker does not have; held-out 6.32 -> 1.85 deg (71 %) "
                             "against the best linear model",
    ("full", SEED * 100, 2): "2026-11-29: the same structure, the asymmetry -0.019 +- 0.015; held-out "
                             "3.29 -> 1.89 deg (43 %)",
    ("full", 2000, 1): "2026-11-29: cross terms + a heading misalignment of -1.42 deg named (the files have "
                       "none), held-out 12.64 -> 1.89 deg (85 %) against the best linear model, here the "
                       "bounded fit; no offset",
    ("full", 2000, 2): "2026-11-29: cross terms + a heading misalignment of -0.94 deg named (the files have "
                       "none), held-out 6.46 -> 2.47 deg (62 %); no offset",
}


def _tk_dist_param(form, seed, fold):
    return known_wrong((form, seed, fold), TK_DIST_KNOWN_WRONG, (form, seed, fold),
                       f"{form}-seed{seed}-fold{fold}")


@pytest.mark.parametrize("form,seed,fold", [_tk_dist_param(f, s, k) for f in ("linear", "offset", "full")
                                            for s in (TK_SEED, *TK_SEEDS) for k in (1, 2)
                                            if FULL or (f, s, k) == ("linear", TK_SEED, 1)])
def test_tanker_process_disturbance(tk_root, form, seed, fold):
    """The tanker's side-swap folds with what measured runs carry and no model has: a random external
    yaw moment in every run, worth 0.5 deg of rudder (std), 30 s correlation time (full scale), drawn
    afresh per run (MR_DISTURBANCE_DEG's reasoning), on a course-unstable hull.  The same judgement as
    test_tanker_side_swap: linear none, the offset form the offset alone within 25 %, the published
    model a cause, a held-out cut of half and the offset among its effects.

    Measured 2026-11-25 (seeds 1300, 700, 2000, 3000, two folds each): linear none 8 of 8 (baseline
    0.31-1.74 deg); offset right 8 of 8 (-0.41 to -0.62 deg against -0.50, 85-95 %); full 5 of 8
    (TK_DIST_KNOWN_WRONG), every one of its folds naming the cross terms as cause.  make test runs
    the linear form's seed 1300 fold 1 only (CI time)."""
    _check_tanker(tanker_fold(tk_root, form, fold, seed, disturbance_deg=MR_DISTURBANCE_DEG), form)


#: deg: a heading reference set off the model's centreline (the files' heading reads this much more
#: than the ship's; the track is true), as a tank set-up nobody here has seen may leave it: 0.3 deg is
#: three times the 0.1 deg an optical tracking system resolves heading to, 1 deg a careless set-up.
#: A MARIN file gives earth-fixed velocities, so the reader's v = -dx0 sin(psi) + dy0 cos(psi) carries
#: u sin(misalignment): 0.006 / 0.021 m/s at the tanker's 1.16 m/s model speed, against 0.19 m/s of
#: largest sway
TK_MISALIGN_DEG = (0.3, 1.0)
#: (form, misalignment, fold) named wrongly (strict xfails, seed 1300).  Until the pair pool ranked by
#: the mean training cut (select._pair_pool, 2026-11-26) both 1 deg full folds were (measured
#: 2026-11-25: yaw + sway damping named without the offset or the misalignment, 12.11 -> 2.98 and
#: 6.00 -> 2.45 deg held-out); both were right on 2026-11-26 and fail since the best linear baseline
#: (below)
TK_MISALIGN_KNOWN_WRONG: dict = {
    ("full", 0.3, 1): "2026-11-29: the reference structure named (offset, speed loss, hull terms, a rudder "
                      "asymmetry of -0.022 +- 0.008, above its floor), not the misalignment; held-out 8.44 "
                      "-> 1.72 deg (80 %) against the best linear model",
    ("full", 0.3, 2): "2026-11-29: the reference structure named with an asymmetry of +0.064 +- 0.034, not "
                      "the misalignment; held-out 5.34 -> 5.12 deg (4 %)",
    ("full", 1.0, 1): "2026-11-29: cross terms + saturation + a rudder asymmetry named, not the "
                      "misalignment; held-out 8.74 -> 1.61 deg (82 %) against the best linear model",
    ("full", 1.0, 2): "2026-11-29: cross terms + saturation + a rudder asymmetry named, not the "
                      "misalignment; held-out 5.91 -> 1.52 deg (74 %)",
}


def _tk_mis_param(form, eps, fold):
    return known_wrong((form, eps, fold), TK_MISALIGN_KNOWN_WRONG, (form, eps, fold),
                       f"{form}-{eps:g}deg-fold{fold}")


@pytest.mark.parametrize("form,eps,fold", [_tk_mis_param(f, e, k) for f in ("linear", "offset", "full")
                                          for e in TK_MISALIGN_DEG for k in (1, 2)
                                          if FULL or (f, e, k) == ("linear", 0.3, 1)])
def test_tanker_heading_misalignment(tk_root, form, eps, fold):
    """A sensor artefact of measured files, not a ship effect: the heading reference misaligned with
    the track, so the sway velocity read from a MARIN file is biased by u sin(misalignment).  The same
    judgement as test_tanker_side_swap (noise seed 1300), and the sensor effect heading_misalignment
    named within 25 % (both sizes are above its 0.2 deg floor).

    Measured 2026-11-25 with the sensor effect in the catalogue (pipeline/diagnose/effects/
    heading_misalignment.py): linear: the misalignment alone, 1.02 / 1.00 deg at 1 deg (held-out 1.72 ->
    0.09, 1.89 -> 0.08 deg), 0.32 / 0.30 at 0.3 deg; offset: offset + misalignment, offset -0.512 /
    -0.509 deg against -0.502 and 1.02 / 1.00 deg at 1 deg (was 31 % off without the effect), -0.513 /
    -0.509 and 0.31 / 0.30 at 0.3 deg; published model at 0.3 deg offset + cross terms + misalignment
    0.28 / 0.24 deg, 12.11 -> 1.03 and 6.00 -> 1.21 deg (fold 2 was 23 %); at 1 deg missed
    (TK_MISALIGN_KNOWN_WRONG) until 2026-11-26, right in both folds by this test's statement since the
    pair pool ranks by the mean training cut (select._pair_pool).  Aligned files never name it
    (test_tanker_side_swap: TK_WRONG; the published model's fit gives -0.04 / -0.06 deg, under the
    floor).

    Before the sensor effect (measured 2026-11-25): linear none at both (baseline held-out 3.14 / 3.57 deg
    at 1 deg, 0.09 / 0.08 aligned: the biased v bends the fit, no effect takes it up); offset right at 0.3
    deg (-0.534 / -0.523, held-out 0.63 / 0.60 deg) and 0.5 deg (-0.557 / -0.534), 28-31 % off at 1 deg;
    the published model right in fold 1 at 0.3 deg (83 %), 23 % in fold 2, and at 0.5 deg (not tested)
    cross terms + saturation without the offset (83 % / 68 %).  Tried and not adopted: a constant
    sway-velocity bias fitted with every model (a nuisance like the starts, not judged held-out): the 1
    deg files came right (offset -0.512 / -0.509, linear 0.09 deg, published model offset + speed + cross
    terms 84 / 82 %), but on the aligned published model the bias took up the hull's sway misfit (-0.068
    m/s, a11 and a12 at their bounds, baseline held-out 6.01 -> 10.94 deg; with the cross terms 2.99
    against 11.27): a false misalignment of 3 deg (the catalogue effect, a bias growing with u and judged
    on held-out runs like any effect, is refused there).  Reweighting the outputs by their residual spread
    (maximum likelihood with unknown channel variances, two rounds): 0.3 deg gives cross terms alone, 80 /
    57 %, the offset missed.  make test runs the linear form's 0.3 deg fold 1 only (CI time)."""
    rep = tanker_fold(tk_root, form, fold, misalignment_deg=eps)
    # the user is told at 1 deg (the approach drifts -0.96 / -0.90 deg); at 0.3 deg the drift (-0.26 /
    # -0.20) is under the check's floor (pipeline.diagnose.datacheck, tests/test_diagnose_datacheck.py)
    warned = rep["data_checks"]["approach_drift"]["warning"]
    assert (warned is not None) == (eps >= 1.0) and (eps < 1.0 or warned in rep["summary"]), warned
    _check_tanker(rep, form, misalignment_deg=eps)


#: deg/s at model scale: a rate gyro's constant bias, of a MEMS sensor's size (a fibre-optic gyro's is a
#: hundred times smaller); over a 127 s run it integrates to 13 deg of disagreement between r and psi
TK_RATE_BIAS_DEG_S = 0.1


#: (form, fold) named wrongly (strict xfails)
TK_RATE_KNOWN_WRONG = {
    ("full", 1): "2026-11-29: cubic yaw damping + a rudder asymmetry of -0.059 +- 0.006 named (a kind the "
                 "tanker does not have), no offset; held-out 11.85 -> 2.60 deg (78 %) against the best "
                 "linear model",
    ("full", 2): "2026-11-29: cubic yaw damping + a rudder asymmetry of -0.046 +- 0.006 named, no offset; "
                 "held-out 3.34 -> 2.32 deg (31 %)",
}


def _tk_rate_param(form, fold):
    return known_wrong((form, fold), TK_RATE_KNOWN_WRONG, (form, fold), f"{form}-{fold}")


@pytest.mark.parametrize("form,fold", [_tk_rate_param(f, k) for f in ("linear", "offset", "full")
                                       for k in (1, 2) if FULL or (f, k) == ("linear", 1)])
def test_tanker_rate_gyro_bias(tk_root, form, fold):
    """Another sensor artefact: the MARIN files' yaw rate read with a constant bias (the heading is
    right), so r and the heading's derivative disagree in every sample.  The same judgement as
    test_tanker_side_swap (noise seed 1300): the fit, which weighs psi, r and v, must not turn the bias
    into an effect, nor lose the offset to it.

    Measured 2026-11-25: linear none (baseline held-out 0.39 / 0.45 deg, 0.09 / 0.08 without the bias);
    offset -0.507 / -0.503 deg against -0.502 (0.44 deg held-out); the published model offset + cross
    terms, 13.01 -> 1.26 and 6.19 -> 1.52 deg (90 / 75 %).  At 0.02 deg/s: linear none, offset -0.512 /
    -0.508, published offset + cross terms + saturation 92 / 83 %.  Since 2026-11-25 the bias is read
    against the heading and corrected before any fit (pipeline.diagnose.datacheck.rate_bias), so
    these folds see the unbiased files' r again.  make test runs the linear form's fold 1 only (CI
    time)."""
    rep = tanker_fold(tk_root, form, fold, rate_bias_deg_s=TK_RATE_BIAS_DEG_S)
    rates = rep["data_checks"]["rate_bias"]["per_run"]
    assert len(rates) == 4 and all(x["corrected"] for x in rates.values()), rates
    assert all(x["bias_deg_s"] == pytest.approx(TK_RATE_BIAS_DEG_S, abs=0.005) for x in rates.values()), rates
    _check_tanker(rep, form)


#: (rudder deg, duration s full scale) of the tanker's turning circles, to both sides, beside its four
#: zigzags: SIMMAN's 35 deg circle for the published model (600 s, 85 s at 1:50: it turns through
#: about 290 deg, its speed down to 29 %); the linear forms have no steady turn at 35 deg (their hull is
#: course-unstable: the sway grows to 37 m/s), so their circles are 10 deg for 300 s (165 deg)
TK_CIRCLE = {"full": (35.0, 600.0), "linear": (10.0, 300.0)}


def write_tanker_circles(folder: Path, form: str, seed: int = TK_SEED) -> dict:
    """The four tanker zigzags (:func:`write_tanker`) and a turning circle to each side (the zigzag
    logic with a heading trigger never reached: the rudder stays put), full-scale MARIN files."""
    files = write_tanker(folder, form, seed)
    rudder, duration = TK_CIRCLE[form]
    for j, side in enumerate(("starboard", "port")):
        f = tk.simulate_zigzag(tk.Tanker(form=form), rudder, 1e9, side, duration=duration, seed=seed + 4 + j,
                               scale=TK_SCALE)
        files[("circle", side)] = write_marin(f, folder / f"tanker_{form}_tc{rudder:g}_{side[0].upper()}.dat",
                                              f"Turning circle {rudder:g} deg {side} for Tanker")
    return files


#: (form, seed) of the tanker with turning circles the test judges wrong (an effect the truth lacks, no
#: cause, or an honest gain short of half the best linear model's error): strict xfails, measured
TK_CIRCLE_WRONG: dict = {
    ("full", TK_SEED): "2026-11-30 (midday): cause speed_loss, the main model speed loss + hull terms + "
                       "a rudder asymmetry (the truth lacks the asymmetry; the offset carried below its "
                       "floor); honest gain 62 % [48 %, 74 %] (6.71 -> 2.54 deg: the half asked is "
                       "reached), five rounds of six naming the truth's kinds (the asymmetry in two), the "
                       "round holding out the 20/20 S zigzag none (the reference refitted there 2.72 deg "
                       "against 6.87), the reference refitted in the same rounds 71 %.  On 2026-11-28 "
                       "(evening) 49.7 % [34 %, 64 %] (6.71 -> 3.38 deg); before twin_left_trains and "
                       "anchor_either_linear 21 % [7 %, 35 %]",
    ("full", 2000): "2026-11-30 (midday): none in the design folds (the reference fitted on three runs "
                    "runs away on the other side's); honest gain 44 % [27 %, 60 %] (6.65 -> 3.74 deg), "
                    "four rounds of six naming speed loss + hull terms (the asymmetry in one), the rounds "
                    "holding out the 20/20 S zigzag and the port circle none (the reference refitted "
                    "there 2.79 and 0.56 deg against 7.38 and 6.17), the reference in the same rounds "
                    "69 %.  On 2026-11-28 (evening) 47 % [30 %, 62 %] (6.65 -> 3.55 deg); before the two "
                    "settings 12 % [-0.2 %, 25 %]",
}


@pytest.mark.parametrize("form,seed", [
    known_wrong((f, s), TK_CIRCLE_WRONG, (f, s), f"{f}-{s}")
    for f in ("linear", "full") for s in (TK_SEED, 2000) if FULL or (f, s) == ("linear", TK_SEED)])  # CI time
def test_tanker_with_turning_circles(tk_root, form, seed):
    """The runs a tank gives beside its zigzags: a turning circle to each side (item 5: use
    all the runs).  The catalog rule (pipeline.cli.diagnose.pick_catalog_runs) puts them in the
    selection, one trained and one validated, the zigzag pairs crossed beside them; no run is left for
    a test, so the gain is the nested leave-one-run-out's.

    - linear (course-unstable, 10 deg circles): none;
    - full (the published model, 35 deg circles: drift and speed loss no zigzag reaches): a cause of
      the truth's kinds, and a positive honest gain whose interval excludes 0; the held-out circles
      together predicted better by the models chosen without them.

    Measured 2026-11-25, seed 1300: linear none; full nonlinear_sway_damping, validation 9.84 -> 6.59
    deg (33 %), honest gain 40 % [25 %, 55 %], the held-out circles 12.89 -> 9.50 and 11.71 -> 7.80
    deg; since the hinge check (Search.hinges), 9.81 -> 6.58 deg, honest 58 % [41 %, 69 %], the
    circles 12.88 -> 4.08 and 11.71 -> 4.83 deg.  Seed 2000: full nonlinear_sway_damping, 9.73 -> 6.52
    deg, honest 25 % [8 %, 44 %]; the selection without the starboard circle chose a servo lag and
    predicts it worse (12.82 -> 14.24 deg), the port circle 11.59 -> 7.05; since the hinge check, 19 %
    [-5 %, 41 %] (a strict xfail); since a cut must not be carried by one held-out run
    (select.carried_by_one_run), 42 % [13 %, 61 %] (the starboard circle 12.82 -> 5.37 deg).  With
    side-swap folds (all starboard runs training) the
    published model gives offset + cross terms, 74 % / 70 % (seed 1300).  The same six runs of the
    virtual KCS tank give no honest gain (README).  Against the best linear model (2026-11-28) the
    published model's gain is lost at both seeds (TK_CIRCLE_WRONG); since twin_left_trains and
    anchor_either_linear, 49.7 % / 47 %, short of the half asked; on 2026-11-30 62 % (with an asymmetry
    the truth lacks) / 44 % (TK_CIRCLE_WRONG).  make test runs the linear form's
    seed 1300 only (CI time)."""
    from pipeline.diagnose.design import pick_catalog_runs

    files = write_tanker_circles(tk_root / f"circles_{form}{seed}", form, seed)
    runs = {p.stem: load(p, scale=TK_SCALE) for p in files.values()}
    keys = ("kind", "rudder_deg", "heading_deg", "first_side")
    entries = [{"run_id": k, **{m: r.meta.get(m) for m in keys}} for k, r in runs.items()]
    tr, va, te = pick_catalog_runs(entries)
    circles = sorted(p.stem for k, p in files.items() if k[0] == "circle")
    assert te == [] and sorted(tr + va) == sorted(runs) and {tr[-1], va[-1]} == set(circles), (tr, va)
    rep = diagnose_report([runs[k] for k in tr], [runs[k] for k in va],
                          cfg=DiagnoseConfig(nested_gain=form != "linear"))
    if form == "linear":
        assert rep["cause"] == "none" and rep["extended"]["effects"] == [], rep["extended"]
        return
    assert rep["cause"] != "none" and not set(rep["extended"]["effects"]) & set(TK_WRONG), rep["extended"]
    g = rep["gain"]
    assert sorted(g["measured_on"]) == sorted(runs) and g["flag"] is None, g
    assert g["mae_psi_relative_reduction"] > 0 and g["interval_95"][0] > 0, g
    # the bar of another ship's turning circles (docs/diagnosis.md, Known limits): half the best linear
    # model's error
    assert g["mae_psi_relative_reduction"] >= 0.5, g
    held = [n for n in g["nested"] if n["measured_on"][0] in circles]
    assert len(held) == 2 and sum(n["extended_mae_psi_deg"] for n in held) < sum(
        n["baseline_mae_psi_deg"] for n in held), held


#: The structure a reference model of the tanker writes in the catalogue's terms: a rudder offset (the
#: propeller's constant side force and moment), the hull's nonlinear forces to second and third order
#: in both equations (its published hull has the modulus forms v|v| and |v| r: hull_nonlinearity's
#: mixed form), coefficients that scale with the measured speed (it slows in turns) and a rudder more
#: effective to one side.  Written here, not read from the method's configuration, so that the known
#: answer does not move with it.
TK_ORACLE = (("rudder_offset", "constant"), ("hull_nonlinearity", "mixed"), ("speed_loss", "power"),
             ("rudder_asymmetry", "two_sided"))


def _side_swap_oracle(files: dict, fold: int, scale: float, structures) -> tuple[float, float]:
    """(best linear model, best of ``structures``): held-out MAE psi (deg) pooled over side-swap fold
    ``fold``'s validation side (:func:`side_swap_fold`).  The linear fits with and without the
    ship-sign bounds, the better one on the validation side (chosen with hindsight); each structure
    fitted on the training side in either family, of its fits from that family's linear fit and
    from the equation-error start the one of least TRAINING cost, then the best structure on the
    validation side: what the catalogue can reach on the fold, not the diagnosis's choice."""
    from pipeline.diagnose.fit import evaluate, fit_structure, series_from_run, structure_of

    sides = ("starboard", "port") if fold == 1 else ("port", "starboard")
    ctx, cfg, runs = _with_starts([series_from_run(load(files[(a, side)], scale=scale))
                                   for side in sides for a in (20, 10)])
    train, held = runs[:2], runs[2:]
    kw = {"max_nfev": cfg.max_nfev, "block_T": cfg.block_T}

    def mae(fit) -> float:
        return float(evaluate(fit, held)[0]["mae_psi_deg"])

    linear = {b: fit_structure(train, (), ctx, **kw, sign_bounds=b) for b in (True, False)}
    best = []
    for st in structures:
        for b, lin in linear.items():
            fits = [fit_structure(train, structure_of(*st), ctx, start=s0, **kw, sign_bounds=b)
                    for s0 in (lin, None)]
            best.append(mae(min(fits, key=lambda f: f.cost)))
    return min(mae(f) for f in linear.values()), min(best)


#: the reference structure without its rudder asymmetry, a kind the KVLCC2 stand-in's truth has but
#: that the side-swap folds' training side (one side's zigzags) can hardly size
TK_ORACLE_SYMMETRIC = tuple(x for x in TK_ORACLE if x[0] != "rudder_asymmetry")


@pytest.mark.skipif(not FULL, reason="8 fits of two 20/20 and 10/10 zigzags per case (about 2 min on 2 "
                    "cores): make generalise (TANKTEST_GENERALISE=full)")
@pytest.mark.parametrize("seed,fold,reachable", [(SEED * 100, 2, True), (700, 1, False)])
def test_kvlcc2_disturbed_side_swap_oracle(tmp_path, seed, fold, reachable):
    """What the catalogue can reach on the disturbed KVLCC2 stand-in's side-swap folds
    (KV_DIST_KNOWN_WRONG's reasons), a known answer of the files: the reference structure, with or
    without its asymmetry, fitted on one side's zigzags halves the best linear model's held-out error
    on the other side at seed 1300 fold 2 (3.07 -> 1.31 deg, measured 2026-11-29), where the diagnosis
    cuts it by 18 %; at seed 700 fold 1 it cuts nothing (2.61 -> 2.61 deg), so no choice from the
    catalogue can pass the side-swap bar there."""
    files = write_kvlcc2(tmp_path, seed=seed, disturbance_deg=MR_DISTURBANCE_DEG)
    best, ora = _side_swap_oracle(files, fold, SCALE, (TK_ORACLE, TK_ORACLE_SYMMETRIC))
    assert (ora <= (1.0 - KV_MIN_GAIN) * best) is reachable, (best, ora)


@pytest.mark.skipif(not FULL, reason="18 fits of the six 600-900 s tanker runs per seed (about 3 min on 2 "
                    "cores): make generalise (TANKTEST_GENERALISE=full)")
@pytest.mark.parametrize("seed", [TK_SEED, 2000])
def test_tanker_oracle_with_turning_circles_halves_the_best_linear_models_error(tk_root, seed):
    """The tanker's four zigzags and two 35 deg circles, leave-one-run-out: the oracle structure fitted on
    five runs holds the sixth out better than each run's better linear fit (chosen with hindsight) on
    every run, at under half its error on average: the bar the diagnosis's honest gain is held to on
    another ship's turning circles is within the catalogue's reach.  The truth is the published tanker,
    not written in these terms.  Measured 2026-11-28 (held-out MAE psi deg, better linear -> oracle):
    seed 1300 zz20 S 6.87 -> 3.32, zz10 S 6.84 -> 1.10, zz20 P 6.78 -> 5.32, zz10 P 6.29 -> 1.17,
    circle S 7.90 -> 1.95, circle P 5.60 -> 0.59, mean 6.71 -> 2.24 (-67 %); with the Abkowitz form
    alone (the third-order cross terms only) 4.37 (-35 %); seed 2000 zz20 S 7.38 -> 2.79, zz10 S
    6.82 -> 1.32, zz20 P 7.12 -> 5.69, zz10 P 6.23 -> 1.21, circle S 6.18 -> 1.65, circle P 6.17 ->
    0.56, mean 6.65 -> 2.20 (-67 %; the Abkowitz form alone -32 %).  The virtual KCS's six runs with
    this structure (its hull in the MMG's third-order terms): 6.61 -> 2.02 deg (-69 %), as with the
    Abkowitz form (2.08)."""
    from pipeline.diagnose.fit import series_from_run

    files = write_tanker_circles(tk_root / f"oracle{seed}", "full", seed)
    bnd, free, ora = _oracle_leave_one_out([series_from_run(load(p, scale=TK_SCALE)) for p in files.values()],
                                           TK_ORACLE)
    best = np.minimum(bnd, free)
    assert np.all(ora < best) and ora.mean() < 0.5 * best.mean(), (best, ora)


def test_a_step_that_hinges_on_one_training_run_is_found(tk_root):
    """The hinge check (pipeline.diagnose.select.Search.hinges) on a truth not written in the
    candidates' formulas: the published tanker (|v| v, |v| r hull terms, course-unstable linear part)
    with a random yaw moment worth 1 deg of rudder, trained on 20/20, 10/10 and a 1 deg zigzag 10/1
    to starboard, validated on the same to port.

    - cubic yaw damping (not the truth's kind), refitted without the 20/20 zigzag, diverges on it: the
      small zigzags do not hold r^3 where the large one goes (measured 2026-11-25: 6.20 -> 13128 deg,
      heading swing 34.4 deg); judged as a step it passes every other test and is refused for that
      alone, the run in ``Step.hinges`` (diagnosis.json's ``findings[].hinges_on``);
    - the truth's kind, sway damping, hinges on no run (it passes every other check too: +65 %);
    - with fewer training runs than ``jackknife_min_train`` nothing is refitted and nothing hinges."""
    from threadpoolctl import threadpool_limits

    from pipeline.diagnose import core
    from pipeline.diagnose.fit import series_from_run, structure_of, with_initial_states
    from pipeline.diagnose.select import Fold, Search, heading_noise_deg

    folder = tk_root / "hinge"
    folder.mkdir()
    legs = [(20, 20, "starboard"), (10, 10, "starboard"), (10, 1, "starboard"),
            (20, 20, "port"), (10, 10, "port"), (10, 1, "port")]
    series = []
    for j, (a, h, side) in enumerate(legs):
        f = tk.simulate_zigzag(tk.Tanker(), a, h, side, duration=TK_DURATION, seed=41 + j, scale=TK_SCALE,
                               disturbance_deg=1.0)
        p = write_marin(f, folder / f"z{a}_{h}_{side[0].upper()}.dat", marin_test_name("Tanker", a, h))
        series.append(series_from_run(load(p, scale=TK_SCALE)))
    cfg = DiagnoseConfig()
    ctx = core._context(series)
    series = with_initial_states(series, cfg.x0_window_T * ctx.t_ship, None, cfg.x0_box_sigma)
    train, val = series[:3], series[3:]
    cubic = structure_of(("nonlinear_yaw_damping", "cubic"))
    sway = structure_of(("nonlinear_sway_damping", "abs"))
    with threadpool_limits(limits=1, user_api="blas"):
        search = Search([Fold(train, val)], ctx, cfg)
        hinge = search.hinges([0], (), cubic)
        assert len(hinge) == 1 and hinge[0].startswith(train[0].name), hinge
        before, after = (float(x) for x in hinge[0].split()[1:4:2])
        assert after - before > 10 * 0.5 * np.ptp(train[0].psi), hinge      # diverges, not a near miss
        assert search.hinges([0], (), sway) == []
        # in the selection: the step passes every other test (held-out +11 %, measured) and is refused
        # for the hinge alone, whose runs diagnosis.json carries (findings[].hinges_on)
        search.fit(0, cubic, start=search.fit(0, ()))
        step = search.step([0], (), cubic, "nonlinear_yaw_damping", heading_noise_deg(val, ctx.t_ship))
        assert not step.passes and step.hinges == hinge, (step.why, step.hinges)
        assert len(step.why) == 1 and step.why[0].startswith("hinges on one training run"), step.why
        fewer = Search([Fold(train, val)], ctx, dc.replace(cfg, jackknife_min_train=4))
        assert fewer.hinges([0], (), cubic) == []


# ------------------------------- a fifth ship and model family, with roll: the Son & Nomoto container ship
CT_SCALE = 35.0           # a 5 m tank model of the 175 m ship
CT_DURATION = 600.0       # s full scale (101 s at 1:35): 3-4 periods of the 20/20 zigzag
#: not in the truth: the measured rudder is logged (the servo is no hidden effect), the hull and the
#: propeller are port/starboard symmetric (no side force: no offset, no asymmetry), the heading is true
CT_WRONG = ("rudder_offset", "rudder_asymmetry", "rudder_delay", "rudder_lag", "heading_misalignment")
#: (form, seed, disturbance deg, fold) named wrongly (strict xfails, measured 2026-11-25)
CT_KNOWN_WRONG = {
    ("full", 1300, MR_DISTURBANCE_DEG, 2): "2026-11-29: yaw damping named (a kind the truth has), held-out "
    "2.88 -> 3.29 deg (-14 %) against the best linear model (the unconstrained fit; 5.19 -> 3.29, 36 %, "
    "against the bounded one on 2026-11-25)",
    ("full", 700, MR_DISTURBANCE_DEG, 1): "2026-11-29: sway damping named, held-out 3.33 -> 1.67 deg "
    "(49.9 %) against the best linear model (the unconstrained fit); the hull terms with the speed loss "
    "fitted on the same runs 2.09 deg (37 %): the bar is beyond the catalogue on this fold",
    ("full", 700, MR_DISTURBANCE_DEG, 2): "2026-11-29: sway damping named, held-out 2.88 -> 2.05 deg (29 %) "
    "against the best linear model; the hull terms with the speed loss 1.54 deg (47 %)",
}


def _ct_param(form, seed, dist, fold):
    return known_wrong((form, seed, dist, fold), CT_KNOWN_WRONG, (form, seed, dist, fold),
                       f"{form}-seed{seed}-dist{dist:g}-fold{fold}")


_CT: dict = {}


def container_fold(tmp_root: Path, form: str, fold: int, seed: int = TK_SEED,
                   disturbance_deg: float = 0.0) -> dict:
    """Side-swap fold 1 (train starboard 20/20 + 10/10, validate port) or 2 (the reverse) of one
    container-ship form and noise seed, made once per process (selection only)."""
    return cached_fold(_CT, (form, seed, disturbance_deg), fold, lambda: write_ship(
        tmp_root / f"{form}{seed}d{disturbance_deg:g}", ct.simulate_zigzag, ct.Container(form=form),
        "Container", CT_DURATION, CT_SCALE, seed, disturbance_deg), CT_SCALE)


@pytest.fixture(scope="module")
def ct_root(tmp_path_factory):
    return tmp_path_factory.mktemp("container")


def test_container_truth_is_what_it_says():
    """contract signs (docs/contract.md#run-data) and an outward heel in a steady turn; a lightly damped roll
    mode in the zigzag's band (linearised: a complex pair of period 20-40 s, damping ratio under 0.1) beside
    two real, stable sway-yaw poles; the published model slows in a 20/20 zigzag, heels several degrees, and
    the heel changes the heading it makes (its overshoots differ from the same ship held upright)."""
    s = ct.check_signs()
    assert s["r_deg_s"] > 0 and s["v_m_s"] < 0 and -10.0 < s["phi_deg"] < -2.0, s
    poles = ct.linear_poles()
    roll = poles[np.abs(poles.imag) > 1e-6]
    assert len(roll) == 2 and 20.0 < 2 * np.pi / abs(roll[0].imag) < 40.0, poles
    assert -roll[0].real / abs(roll[0]) < 0.1 and np.all(poles.real < 0), poles
    full = ct.simulate_zigzag(ct.Container(), 20, 20, noise=False, duration=CT_DURATION)
    up = ct.simulate_zigzag(ct.Container(form="noroll"), 20, 20, noise=False, duration=CT_DURATION)
    assert 3.0 < full["phi"].abs().max() < 15.0 and up["phi"].abs().max() == 0.0
    assert full["u"].min() < 0.8 * full["u"].iloc[0]
    over = [kv.zigzag_metrics(f, 20)["overshoots_deg"][0] for f in (full, up)]
    assert over[0] > over[1] + 0.5, over


@pytest.mark.parametrize("form,seed,dist,fold", [
    _ct_param(f, s, d, k) for d in (0.0, MR_DISTURBANCE_DEG) for f in ("linear", "full")
    for s in (TK_SEED, *TK_SEEDS) for k in (1, 2) if FULL or (d, s, k) == (0.0, TK_SEED, 1)])
def test_container_side_swap(ct_root, form, seed, dist, fold):
    """A ship, a model family and a degree of freedom no part of the method was built for (added after
    the method, run as found): the Son & Nomoto container ship, whose heel in a turn feeds back into sway
    and yaw (tests/truths/container.py), full-scale MARIN .dat read with ``--scale 35``, the side-swap
    folds (``KV_MIN_GAIN``); clean, and with the process disturbance of the Mariner and tanker tests.

    - linear (the baseline's family plus the roll mode, speed held): none.  The roll is in no candidate's
      formula; whatever it leaves must not be named as a rudder lag, a dead time or a hull term;
    - full (the published model): a cause, a held-out cut of at least half, and none of CT_WRONG (the
      truth's kinds: hull nonlinearity of every cubic form, the speed it loses, the rudder's flow).

    Measured 2026-11-25, clean, seeds 1300 / 700 / 2000 / 3000, both folds: linear none in all 8
    (baseline held-out 0.20-0.22 deg; the best candidate, cubic yaw damping, +36 %, cuts 0.07 deg:
    under the heading-noise floor); full the cross terms in all 8 (with speed loss at seed 2000),
    3.70-3.84 -> 0.35-0.61 deg (84-91 %).  Held upright (form "noroll", not tested) the same ship gives
    cross terms + saturation, 3.11 -> 0.22 deg: the heel roughly doubles what the best model leaves.
    Disturbed (0.5 deg of rudder, 30 s): linear none at 1300, 2000, 3000; full 65-73 % with hull kinds
    at 2000, 3000, 700 (fold 1) and 1300 fold 1; CT_KNOWN_WRONG for the rest.  make test runs the clean
    seed 1300 fold 1 of both forms."""
    rep = container_fold(ct_root, form, fold, seed, dist)
    effects = rep["extended"]["effects"]
    if form == "linear":
        assert rep["cause"] == "none" and effects == [], (rep["cause"], rep["extended"])
        return
    assert_names_a_cause_and_halves(rep)
    assert not set(effects) & set(CT_WRONG), effects


# ------------- a sixth model family, logged as another tank logs: Clarke's hull + Hoerner's cross-flow drag
FY_HULLS = ("ferry", "bulker")
#: the hull's kinds: Hoerner's cross-flow drag integral mixes v|v|, r|r| and the |.| cross forms (its
#: rudder is linear and logged as measured, its speed held, its sensors true in the mean)
FY_HULL_KINDS = ("nonlinear_yaw_damping", "nonlinear_sway_damping", "sway_yaw_coupling", "hull_nonlinearity")
#: disturbed runs: where the truth's own equations (no disturbance, free run from the logged rudder)
#: cut the fold's held-out heading MAE by this much against the linear baseline, the data show the
#: hull's nonlinearity and a hull kind must be named; the bar of the hidden-effect cases
#: (an effect worth less than 30 % held-out is not asked for); below it the data may not show it
FY_ORACLE_BAR = 0.30

_FY: dict = {}


def write_ferry(folder: Path, hull: str, form: str, seed: int, disturbance_deg: float = 0.0) -> dict:
    """The four zigzags (KV_LEGS) of one hull and form of :mod:`truths.crossflow` as canonical CSV at
    model scale, logged at 20 Hz (as a tank's own logger exports them; read without ``--scale``)."""
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for j, (a, side) in enumerate(KV_LEGS):
        f = cf.simulate_zigzag(cf.hull(hull, form), a, a, side, seed=seed + j,
                               disturbance_deg=disturbance_deg)
        header = {"ship": f"{hull} (tests/truths/crossflow.py)", "test": f"zigzag {a}/{a} {side}",
                  "provenance": "virtual"}
        out[(a, side)] = write_csv(f, folder / f"{hull}_{form}_zz{a}_{side[0].upper()}.csv", header)
    return out


def ferry_fold(tmp_root: Path, hull: str, form: str, fold: int, seed: int = TK_SEED,
               disturbance_deg: float = 0.0) -> tuple[dict, dict]:
    """(files, selection-only report) of side-swap fold 1 (train starboard 20/20 + 10/10, validate
    port) or 2 (the reverse) of one hull, form and noise seed, made once per process."""
    key = (hull, form, seed, disturbance_deg)
    rep = cached_fold(_FY, key, fold, lambda: write_ferry(
        tmp_root / f"{hull}{form}{seed}d{disturbance_deg:g}", *key), None)
    return _FY[key], rep


def ferry_oracle_gain(files: dict, fold: int, hull: str, form: str, rep: dict) -> float:
    """The relative cut of the fold's held-out heading MAE that the truth's own equations (no
    disturbance: :func:`truths.crossflow.free_run` from each held-out run's logged rudder, as ingested)
    make against the diagnosis's linear baseline."""
    side = "port" if fold == 1 else "starboard"
    maes = []
    for a in (20, 10):
        fr = load(files[(a, side)]).frame
        psi = cf.free_run(cf.hull(hull, form), fr["time"].to_numpy(), fr["delta"].to_numpy(),
                          float(fr["r"].iloc[0]), float(fr["psi"].iloc[0]))
        maes.append(float(np.mean(np.abs(psi - fr["psi"].to_numpy()))))
    return 1.0 - float(np.mean(maes)) / rep["baseline"]["validation"]["mae_psi_deg"]


@pytest.fixture(scope="module")
def fy_root(tmp_path_factory):
    return tmp_path_factory.mktemp("crossflow")


def test_crossflow_truth_is_what_it_says():
    """The closed-form cross-flow integrals against quadrature (where the cross-flow changes sign on the
    hull and where it does not, and r -> 0); Hoerner's coefficient at the ferry's B/2T = 2 (0.6489,
    between the table's points at 1.86 and 2.31); contract signs (docs/contract.md#run-data); both hulls'
    linear parts stable, the bulker's slow pole within 0.02 1/s of course instability; the cross-flow drag at
    least a third off the linear hull's 20/20 overshoots; the oracle's free run replays a noise-free run."""
    from scipy.integrate import quad

    L = 4.0
    for v, r in ((0.1, 0.05), (-0.05, 0.2), (0.02, -0.3), (-0.1, 1e-4), (0.1, 1e-14)):
        pts = [-v / r] if abs(v / r) < L / 2 else None
        i1, ix = cf.crossflow_integrals(v, r, L)
        def w2(x, v=v, r=r):
            return (v + x * r) * abs(v + x * r)

        assert i1 == pytest.approx(quad(w2, -L / 2, L / 2, points=pts)[0], rel=1e-9, abs=1e-15)
        assert ix == pytest.approx(quad(lambda x: x * w2(x), -L / 2, L / 2, points=pts)[0],
                                   rel=1e-6, abs=1e-12)
    s = cf.Ferry()
    assert np.interp(s.B / (2 * s.T), cf.HOERNER_B2T, cf.HOERNER_CD) == pytest.approx(
        0.6571 + (2.0 - 1.8600) / (2.3129 - 1.8600) * (0.6307 - 0.6571), rel=1e-12)
    for hull in FY_HULLS:
        sg = cf.check_signs(cf.hull(hull))
        assert sg["r_deg_s"] > 0 and sg["v_m_s"] < 0, (hull, sg)
        poles = cf.linear_poles(cf.hull(hull))
        assert np.all(poles.real < 0), (hull, poles)
        over = [max(kv.zigzag_metrics(cf.simulate_zigzag(cf.hull(hull, f), 20, 20, noise=False), 20)
                    ["overshoots_deg"]) for f in ("crossflow", "linear")]
        assert over[0] < over[1] * 2.0 / 3.0, (hull, over)
    assert max(cf.linear_poles(cf.hull("bulker"))) > -0.02
    # the oracle's free run is the truth: noise-free, it replays the logged heading
    f = cf.simulate_zigzag(cf.hull("bulker"), 20, 20, noise=False, duration=40.0)
    psi = cf.free_run(cf.hull("bulker"), f["time"].to_numpy(), f["delta"].to_numpy(), 0.0, 0.0)
    assert np.max(np.abs(psi - f["psi"].to_numpy())) < 0.05


@pytest.mark.parametrize("hull,form,seed,fold", [
    pytest.param(h, f, s, k, id=f"{h}-{f}-seed{s}-fold{k}") for h in FY_HULLS for f in ("linear", "crossflow")
    for s in (TK_SEED, *TK_SEEDS) for k in (1, 2) if FULL or (h, s, k) == ("ferry", TK_SEED, 1)])
def test_crossflow_side_swap(fy_root, hull, form, seed, fold):
    """A sixth model family, added after the method and run as found (nothing in the method changed for
    it): linear hull derivatives from Clarke et al.'s (1983) regression on the main particulars, twin
    rudders with flow straightening, and the hull's nonlinearity as Hoerner's cross-flow drag integrated
    over the length (tests/truths/crossflow.py), logged as another tank's logger would: canonical CSV at
    model scale, 20 Hz, AR(1) heading and rate noise, the rudder quantised to 0.1 deg; two hulls (a
    nimble ferry, a full-form bulker close to course instability).  Side-swap folds.

    - linear: none;
    - crossflow: a cause, a held-out cut of at least half, and only hull kinds (FY_HULL_KINDS).

    Measured 2026-11-26, seeds 1300 / 700 / 2000 / 3000, both folds, 32 of 32 right: linear none
    (baseline held-out 0.037-0.059 deg); ferry crossflow the cross terms in all 8 (1.40-1.67 -> 0.049-
    0.061 deg, 96-97 %); bulker crossflow yaw + sway damping in 6 (sway damping the cause), the cross
    terms at seed 2000 (2.46-3.10 -> 0.061-0.092 deg, 96-98 %).  make test runs the ferry's seed 1300
    fold 1 of both forms."""
    _, rep = ferry_fold(fy_root, hull, form, fold, seed)
    effects = rep["extended"]["effects"]
    if form == "linear":
        assert rep["cause"] == "none" and effects == [], (rep["cause"], rep["extended"])
        return
    assert_names_a_cause_and_halves(rep)
    assert set(effects) <= set(FY_HULL_KINDS), effects


@pytest.mark.parametrize("hull,form,seed,fold", [
    pytest.param(h, f, s, k, id=f"{h}-{f}-seed{s}-fold{k}") for h in FY_HULLS for f in ("linear", "crossflow")
    for s in (TK_SEED, *TK_SEEDS) for k in (1, 2)
    if FULL or (h, f, s, k) == ("bulker", "crossflow", 2000, 1)])
def test_crossflow_disturbed_side_swap(fy_root, hull, form, seed, fold):
    """The same folds with the process disturbance of the other side-swap tests (a random yaw moment worth
    0.5 deg of rudder, Ornstein-Uhlenbeck, 5 s at model scale = 32 s full scale).  A free run then
    integrates the disturbance, which no model can predict: what the data can show is measured by the
    oracle, the truth's own equations without the disturbance driven by the held-out runs' logged rudder
    (:func:`ferry_oracle_gain`).

    - linear: none (a disturbance is not an effect);
    - crossflow: only hull kinds; a cause among them where the oracle cuts at least FY_ORACLE_BAR.

    Measured 2026-11-26: linear none in 16 of 16; ferry crossflow: the oracle cuts 26 / 11, 21 / -21,
    36 / 43, -5 / -9 % (seeds 1300, 700, 2000, 3000, folds 1 / 2) and the diagnosis names the yaw
    damping at seed 2000 (37 / 41 %), none elsewhere; bulker crossflow: the oracle cuts 61 / 39, 51 / 5,
    67 / 66, -1 / 62 % and the diagnosis names the yaw damping in all 8 (65 / 55, 45 / 33, 67 / 66, 35 /
    69 %).  make test runs the bulker's seed 2000 fold 1 (the oracle 67 %)."""
    files, rep = ferry_fold(fy_root, hull, form, fold, seed, MR_DISTURBANCE_DEG)
    effects = rep["extended"]["effects"]
    if form == "linear":
        assert rep["cause"] == "none" and effects == [], (rep["cause"], rep["extended"])
        return
    assert set(effects) <= set(FY_HULL_KINDS), effects
    oracle = ferry_oracle_gain(files, fold, hull, form, rep)
    if oracle >= FY_ORACLE_BAR:
        assert rep["cause"] in FY_HULL_KINDS, (oracle, rep["cause"], rep["baseline"]["validation"])


# ---------------------------------------------------------------------------- the virtual KCS's oracle
#: The structure an Abkowitz-type model of the virtual KCS writes in the catalogue's terms: a rudder
#: offset, the hull terms v|v|, r|r|, v^2 r, v r^2 in both equations in the non-dimensional speed
#: scaling (hull_nonlinearity), coefficients that scale with the measured speed (speed_loss), and a
#: rudder more effective to one side (the tank's flow-straightening coefficient gamma_R differs with
#: the side of the rudder's drift, its one port/starboard asymmetry: pipeline/tank/kcs.py).  Written
#: here, not read from the method's configuration, so that the known answer does not move with it.
KCS_ORACLE = (("rudder_offset", "constant"), ("hull_nonlinearity", "abkowitz"), ("speed_loss", "power"),
              ("rudder_asymmetry", "two_sided"))


def _with_starts(series: list):
    """(context, the default DiagnoseConfig, ``series`` with their initial states) as the diagnosis
    prepares its runs (pipeline.diagnose.fit.with_initial_states)."""
    from pipeline.diagnose.core import _context
    from pipeline.diagnose.fit import with_initial_states

    ctx, cfg = _context(series), DiagnoseConfig()
    return ctx, cfg, with_initial_states(series, cfg.x0_window_T * ctx.t_ship,
                                         cfg.x0_model_window_T * ctx.t_ship, cfg.x0_box_sigma)


def _oracle_leave_one_out(series: list, oracle: tuple):
    """Leave-one-run-out over ``series`` (Series): per held-out run (MAE psi deg) the linear fit with the
    ship-sign bounds, the one without, and the ``oracle`` structure fitted on the other runs, of its
    fits from the bounded linear fit and from the equation-error start the one of least TRAINING cost
    (the output-error cost has several optima; the held-out run plays no part)."""
    from pipeline.diagnose.fit import evaluate, fit_structure, structure_of

    ctx, cfg, runs = _with_starts(series)
    bnd, free, ora = [], [], []
    for held in runs:
        tr = [s for s in runs if s is not held]
        kw = {"max_nfev": cfg.max_nfev, "block_T": cfg.block_T}
        bounded = fit_structure(tr, (), ctx, **kw)
        bnd.append(evaluate(bounded, [held])[0]["mae_psi_deg"])
        free.append(evaluate(fit_structure(tr, (), ctx, **kw, sign_bounds=False), [held])[0]["mae_psi_deg"])
        full = min((fit_structure(tr, structure_of(*oracle), ctx, start=st, **kw) for st in (bounded, None)),
                   key=lambda f: f.cost)
        ora.append(evaluate(full, [held])[0]["mae_psi_deg"])
    return np.array(bnd), np.array(free), np.array(ora)


def _kcs_oracle_leave_one_out():
    """The virtual tank's six selection runs, leave-one-run-out (:func:`_oracle_leave_one_out`), the
    structure KCS_ORACLE."""
    from pipeline import tank
    from pipeline.config import TankConfig
    from pipeline.diagnose.fit import series_from_run
    from pipeline.tank.manoeuvres import selection_set

    return _oracle_leave_one_out([series_from_run(tank.simulate(m, TankConfig())) for m in selection_set()],
                                 KCS_ORACLE)


@pytest.fixture(scope="module")
def kcs_oracle():
    return _kcs_oracle_leave_one_out()


@pytest.mark.skipif(not FULL, reason="24 fits of the six 90-150 s tank runs (about 2 min on 2 shared "
                    "cores): make generalise (TANKTEST_GENERALISE=full)")
def test_kcs_oracle_is_the_known_answer(kcs_oracle):
    """The virtual tank's six selection runs (20/20 and 10/10 zigzags, 35 deg turning circles, both sides),
    leave-one-run-out: the oracle structure fitted on five runs holds the sixth out better than the
    linear model with the ship-sign bounds on every run, at under a quarter of its error on average.
    The truth is the tank's MMG model, not written in these terms.  Measured (held-out MAE psi deg,
    bounded / unconstrained linear -> oracle): 20/20 S 10.69 / 7.95 -> 1.98, 20/20 P 18.96 / 6.61 ->
    1.92, 10/10 S 11.27 / 5.33 -> 1.32, 10/10 P 13.08 / 4.93 -> 0.95, circle S 21.43 / 3.81 -> 3.72,
    circle P 11.45 / 11.01 -> 2.57; mean 14.48 (bounded) -> 2.08 deg (-86 %)."""
    bnd, free, ora = kcs_oracle
    assert np.all(ora < bnd), (bnd, ora)
    assert ora.mean() < 0.25 * bnd.mean(), (bnd, ora)


@pytest.mark.skipif(not FULL, reason="shares the fits of test_kcs_oracle_is_the_known_answer: make "
                    "generalise (TANKTEST_GENERALISE=full)")
def test_kcs_oracle_halves_the_best_linear_models_error_on_every_run(kcs_oracle):
    """The bar item 1 of the diagnosis issue was written against (under half the linear model's error,
    better on every run), held against the best linear model instead of the bounded fit: each run's
    better linear fit, chosen with hindsight, so a bar no selection's baseline can beat.  Measured:
    6.61 deg (the better linear fit of each run) -> 2.08 deg, -69 %; the closest run is the starboard
    circle (3.81 -> 3.72 deg).  Without the rudder asymmetry the same fits (same start rule) cut the
    mean by 18 % only (6.61 -> 5.45 deg) and lose two runs (10/10 P 6.35 against 4.93 deg, circle S
    9.47 against 3.81)."""
    bnd, free, ora = kcs_oracle
    best = np.minimum(bnd, free)
    assert np.all(ora < best) and ora.mean() < 0.5 * best.mean(), (best, ora)
