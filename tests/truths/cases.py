"""The seeded cases of tests/test_diagnose_generalise.py: what each truth is, what a right diagnosis says.

Every case is a set of runs of one truth of :mod:`truths.swayyaw` (model scale, logged at 0.08 s):

- train: zigzag 20/20 to starboard + 10/10 to port;
- validate: 20/20 to port + 10/10 to starboard (both sides and both amplitudes on each side);
- test: 15/15 to starboard + 15/15 to port (a third amplitude no choice has seen; used when the
  diagnosis API takes ``test``).

Durations: 60 s on the fast ship (about 4 zigzag periods), 90 s on the slow one (its 20/20 period
is about 75 s).  Magnitudes are drawn from ``np.random.default_rng(seed)`` with the seed from
configuration (``DiagnoseConfig().seed`` + 2: the existing truth and tank cases use + 0 and + 1).

Judging (:func:`judge`), from diagnosis.json's documented keys (docs/diagnosis.md) only:

- clean truth: ``cause == "none"`` and ``extended.effects == []``;
- injected effect: ``cause`` in the case's accepted set, at least one accepted effect in
  ``extended.effects`` and nothing outside the accepted set there (a single-effect truth has no
  second cause to find), the accepted finding ``significant``, the reported held-out gain
  ``gain.mae_psi_relative_reduction >= MIN_GAIN``, and the estimate within ``EST_TOL`` of the truth
  where the candidate's form matches the truth's (a key the method reports for that form);
- injected effect that no model could show in heading (:func:`demonstrable`: the baseline's
  validation heading MAE is within the diagnosis's own floor of the truth's, i.e. of the noise):
  "none" or an accepted name, nothing else, no gain required.  Only the v|v| cases 18 and 19 are
  judged so (measured); a sway-channel judge is what they would need, held by a strict xfail.

Why some cases accept more than one name (stated per case in ``reason``):

- servo lag truth: a first-order lag of time constant tau delays a ramp by exactly tau once the
  transient exp(-t/tau) has died, and the zigzag rudder is ramps at the servo rate; the heading
  responses of a lag tau and a dead time tau differ by less than the sensor noise.  So
  ``rudder_lag`` (lag_s ~ tau) and ``rudder_delay`` (delay_s ~ tau, the lag's mean delay) are both
  right; the estimate is checked against tau in either key.
- v|v| and cross-term truths: in a zigzag the sway follows the yaw rate quasi-steadily
  (v ~ -c r), so v^2 r ~ c^2 r^3 and v|v| in yaw ~ r|r|: the hull's nonlinearity can be named as
  any of ``nonlinear_sway_damping``, ``sway_yaw_coupling``, ``nonlinear_yaw_damping`` (the ideal
  name is still recorded and shown by run_cases.py).  A rudder-side name is wrong.
- r|r| and r^3 truths: both are ``nonlinear_yaw_damping``; the estimate is compared only in the
  key of the truth's own form (n_rr_per_deg for r|r|, n_rrr_s_per_deg2 for r^3); in the other form
  only its sign (more damping) is checked.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from truths import swayyaw as sy
from truths.files import write_csv

MIN_GAIN = 0.30   # a named effect must cut the held-out heading MAE by 30 %: the effects are injected at
#                   magnitudes where the truth's own structure is worth far more than that (shares of
#                   0.4-1.0 of the linear term, offsets of 1-2 deg), so a smaller gain is a misfit
EST_TOL = 0.25    # estimates within 25 % where the form matches (the bar of docs/diagnosis.md)
#: with hull_nonlinearity, the Abkowitz-type set of those terms in one effect (docs/diagnosis.md)
HULL_NL = ("nonlinear_sway_damping", "sway_yaw_coupling", "nonlinear_yaw_damping", "hull_nonlinearity")
TRAIN = ((20, "starboard"), (10, "port"))
VALIDATE = ((20, "port"), (10, "starboard"))
TEST = ((15, "starboard"), (15, "port"))
DURATION = {"fast": 60.0, "slow": 90.0}

AR1 = {"noise_psi": 0.1, "noise_r": 0.1, "noise_v": 0.01, "noise_u": 0.01, "noise_delta": 0.05,
       "ar1_phi": 0.95}      # coloured: correlation time 0.08 / (1 - 0.95) = 1.6 s, twice the white level
QUANT = {"noise_delta": 0.0, "quant_delta": 0.1}   # a 0.1 deg rudder encoder, no other rudder noise
QUIET = {"noise_psi": 0.01, "noise_r": 0.01, "noise_v": 0.001, "noise_u": 0.001, "noise_delta": 0.0}


@dataclass(frozen=True)
class Case:
    cid: str
    ship: str
    truth: str                       # short description of the injected truth
    effects: dict = field(default_factory=dict)
    nonlinear: tuple = ()            # (kind, share) pairs resolved by sy.effect_coefficients (lazily)
    loss: float | None = None        # speed loss of the 20/20, resolved to x_vr (lazily)
    sensors: dict = field(default_factory=dict)
    h: float = 0.01
    expected: str = "none"           # the ideal cause
    accepted: tuple = ("none",)      # causes judged right on these data (see module docstring)
    estimate: dict = field(default_factory=dict)   # estimate key -> true value, or "@field" of effects
    sign: dict = field(default_factory=dict)       # estimate key -> required sign (other form)
    reason: str = ""
    seed: int = 0

    def resolved_effects(self) -> dict:
        """The Effects fields, nonlinear shares and speed loss resolved on the ship (cached)."""
        ef = dict(self.effects)
        for kind, share in self.nonlinear:
            ef.update(sy.effect_coefficients(sy.SHIPS[self.ship], kind, share, _ref(self.ship)))
        if self.loss is not None:
            ef["x_vr"] = _x_vr(self.ship, self.loss)
        return ef

    def true_estimates(self) -> dict:
        ef = self.resolved_effects()
        return {k: (ef[v[1:]] if isinstance(v, str) else v) for k, v in self.estimate.items()}

    def truth_model(self) -> sy.Truth:
        return sy.Truth(ship=sy.SHIPS[self.ship], effects=sy.Effects(**self.resolved_effects()),
                        sensors=sy.Sensors(**self.sensors), h=self.h)


@functools.cache
def _ref(ship: str) -> dict:
    return sy.reference_amplitudes(sy.SHIPS[ship])


@functools.cache
def _x_vr(ship: str, loss: float) -> float:
    return sy.speed_loss_for(sy.SHIPS[ship], loss)


def draw_cases(seed: int) -> list[Case]:
    """The >= 30 cases, magnitudes drawn from ``default_rng(seed)`` (deterministic)."""
    rng = np.random.default_rng(seed)
    u = lambda lo, hi: float(rng.uniform(lo, hi))  # noqa: E731
    pm = lambda: float(rng.choice([-1.0, 1.0]))  # noqa: E731
    cases: list[Case] = []

    def add(ship, truth, **kw):
        seed_i = int(rng.integers(1, 10**6))
        cases.append(Case(cid=f"{len(cases):02d}", ship=ship, truth=truth, seed=seed_i, **kw))

    # --- clean truths: "none" ---
    add("fast", "clean, white noise")
    add("slow", "clean, white noise (nearly course-unstable)")
    add("fast", "clean, AR(1) noise phi 0.95", sensors=AR1)
    add("slow", "clean, AR(1) noise phi 0.95", sensors=AR1)
    add("fast", "clean, rudder quantised 0.1 deg", sensors=QUANT)
    add("slow", "clean, rudder quantised 0.1 deg", sensors=QUANT)
    add("slow", "clean, RK4 at 0.0025 s, quiet sensors", sensors=QUIET, h=0.0025)
    add("fast", "clean, AR(1) noise + quantised rudder", sensors={**AR1, **QUANT})

    # --- rudder offset ---
    for ship, lo, hi in (("fast", 1.0, 2.0), ("slow", 0.5, 1.5)):
        off = u(lo, hi) * pm()
        add(ship, f"rudder offset {off:+.2f} deg", effects={"offset_deg": off}, expected="rudder_offset",
            accepted=("rudder_offset",), estimate={"offset_deg": off})
    # --- dead time (fast ship: on the slow one, T = 39 s, a dead time of < 1 s is immaterial) ---
    for _ in range(2):
        tau = u(0.4, 0.8)
        add("fast", f"rudder dead time {tau:.2f} s", effects={"delay_s": tau}, expected="rudder_delay",
            accepted=("rudder_delay",), estimate={"delay_s": tau})
    # --- first-order servo lag ---
    for _ in range(2):
        tau = u(0.6, 1.0)
        add("fast", f"servo lag {tau:.2f} s (first order)", effects={"lag_s": tau}, expected="rudder_lag",
            accepted=("rudder_lag", "rudder_delay"), estimate={"lag_s": tau, "delay_s": tau},
            reason="a first-order lag tau delays the servo's ramps by tau: a dead time tau is as right")
    # --- yaw damping r|r| and r^3 on both ships ---
    for ship in ("fast", "slow"):
        sh = u(0.4, 0.8)
        add(ship, f"yaw damping r|r| share {sh:.2f}", nonlinear=(("r|r|", sh),),
            expected="nonlinear_yaw_damping", accepted=("nonlinear_yaw_damping",),
            estimate={"n_rr_per_deg": "@n_rr"}, sign={"n_rrr_s_per_deg2": -1.0},
            reason="r|r| truth: a cubic candidate is the other form (sign checked only)")
    for ship in ("fast", "slow"):
        sh = u(0.4, 0.8)
        add(ship, f"yaw damping r^3 share {sh:.2f}", nonlinear=(("r^3", sh),),
            expected="nonlinear_yaw_damping", accepted=("nonlinear_yaw_damping",),
            estimate={"n_rrr_s_per_deg2": "@n_rrr"}, sign={"n_rr_per_deg": -1.0},
            reason="r^3 truth: an r|r| candidate is the other form (sign checked only)")
    # --- nonlinear sway damping v|v| (both equations) ---
    for ship in ("fast", "slow"):
        sh = u(0.6, 1.0)
        add(ship, f"sway damping v|v| share {sh:.2f}", nonlinear=(("v|v|", sh),),
            expected="nonlinear_sway_damping",
            accepted=HULL_NL, reason="v follows r quasi-steadily: v|v| in yaw ~ r|r| (any hull nonlinearity)")
    # --- sway-yaw cross terms v^2 r (yaw), v r^2 (sway); and the |.| forms ---
    for ship in ("fast", "slow"):
        sh = u(0.5, 0.9)
        add(ship, f"cross terms v^2 r, v r^2 share {sh:.2f}", nonlinear=(("cross", sh),),
            expected="sway_yaw_coupling",
            accepted=HULL_NL, reason="v ~ -c r in a zigzag: v^2 r ~ r^3 (any hull nonlinearity)")
    sh = u(0.5, 0.9)
    add("fast", f"cross terms r|v|, v|r| share {sh:.2f}", nonlinear=(("cross_abs", sh),),
        expected="sway_yaw_coupling", estimate={"n_avr_per_m": "@n_rabsv", "y_var_per_deg": "@y_vabsr"},
        accepted=HULL_NL, reason="v ~ -c r in a zigzag: r|v| ~ r|r| (any hull nonlinearity); where the "
        "coupling's modulus form is named, its |v| r and v |r| terms are the truth's own")
    # --- rudder stall / saturation (tanh) ---
    for ship in ("fast", "slow"):
        st = u(20.0, 28.0)
        add(ship, f"rudder stall tanh, {st:.1f} deg (20 deg acts as {st * np.tanh(20 / st):.1f})",
            effects={"stall_deg": st}, expected="rudder_saturation", accepted=("rudder_saturation",))
    # --- rudder asymmetry ---
    for ship in ("fast", "slow"):
        a = u(0.10, 0.20) * pm()
        add(ship, f"rudder asymmetry {a:+.2f} (starboard x{1 + a:.2f}, port x{1 - a:.2f})",
            effects={"asym": a}, expected="rudder_asymmetry", accepted=("rudder_asymmetry",))
    # --- speed loss, coefficients ~ u/U0, rudder ~ (u/U0)^2 ---
    for ship in ("fast", "slow"):
        loss = round(u(0.15, 0.25), 3)
        add(ship, f"speed loss {loss:.0%} in the 20/20, coefficients ~ u", loss=loss,
            expected="speed_loss", accepted=("speed_loss",), estimate={"speed_exponent": 1.0},
            reason="truth: a_ij ~ (u/U0)^1, b ~ (u/U0)^2: speed_exponent 1")
    # --- effects under difficult sensors, and two effects together ---
    off = u(0.5, 1.5) * pm()
    add("slow", f"rudder offset {off:+.2f} deg, AR(1) noise", effects={"offset_deg": off}, sensors=AR1,
        expected="rudder_offset", accepted=("rudder_offset",), estimate={"offset_deg": off})
    sh = u(0.4, 0.8)
    add("fast", f"yaw damping r|r| share {sh:.2f}, rudder quantised", nonlinear=(("r|r|", sh),),
        sensors=QUANT,
        expected="nonlinear_yaw_damping", accepted=("nonlinear_yaw_damping",),
        estimate={"n_rr_per_deg": "@n_rr"}, sign={"n_rrr_s_per_deg2": -1.0})
    off = u(0.5, 1.5) * pm()
    sh = u(0.4, 0.8)
    add("slow", f"offset {off:+.2f} deg + r^3 share {sh:.2f}", effects={"offset_deg": off},
        nonlinear=(("r^3", sh),),
        expected="rudder_offset+nonlinear_yaw_damping", accepted=("rudder_offset", "nonlinear_yaw_damping"),
        estimate={"offset_deg": off, "n_rrr_s_per_deg2": "@n_rrr"}, sign={"n_rr_per_deg": -1.0},
        reason="two effects: both must be in the extended model, either may be the cause")
    return cases


def _legs(case: Case):
    """(role, zigzag, seed) of every run of ``case``, in the order the seeds are drawn."""
    j = 0
    for role, legs in (("train", TRAIN), ("validate", VALIDATE), ("test", TEST)):
        for a, side in legs:
            yield role, sy.Zigzag(a, a, side, DURATION[case.ship]), case.seed * 10 + j
            j += 1


def write_runs(case: Case, folder: Path) -> dict[str, list[Path]]:
    """Simulate the case's runs and write them as canonical CSVs; {"train", "validate", "test"}."""
    folder.mkdir(parents=True, exist_ok=True)
    truth = case.truth_model()
    out: dict[str, list[Path]] = {"train": [], "validate": [], "test": []}
    for role, zz, seed in _legs(case):
        f = sy.simulate(truth, zz, seed=seed)
        header = {"ship": f"{case.ship} (tests/truths.swayyaw)", "test": zz.test_name,
                  "provenance": "virtual (tests/truths, independent truth)",
                  "lpp": sy.SHIPS[case.ship].lpp_m, "seed": seed + 1}
        out[role].append(write_csv(f, folder / f"{case.cid}_{zz.name}.csv", header))
    return out


def noise_mae_psi(case: Case, role: str = "validate") -> float:
    """Mean over the ``role`` runs of the heading MAE (deg) of the TRUTH itself: its noise-free heading
    against the logged one, i.e. the heading error of a perfect model started from the true state.

    No model fitted on the data can do better on average, so ``baseline MAE - noise_mae_psi`` is the
    most any extension could cut on those runs (:func:`judge`).  Re-simulates the runs with the seeds
    of :func:`write_runs` (the same bytes)."""
    truth = case.truth_model()
    maes = []
    for r, zz, seed in _legs(case):
        if r == role:
            f = sy.simulate(truth, zz, seed=seed)
            maes.append(float(np.mean(np.abs(f["psi"].to_numpy() - f.attrs["true"]["psi"].to_numpy()))))
    return float(np.mean(maes))


def _finding(report: dict, effect: str) -> dict | None:
    return next((f for f in report.get("findings", []) if f.get("effect") == effect), None)


def _est_value(est: dict, key: str):
    v = est.get(key) if isinstance(est, dict) else None
    return float(v) if isinstance(v, (int, float)) and np.isfinite(v) else None


def demonstrable(report: dict, noise_mae: float) -> tuple[bool, str]:
    """Can ANY model show the case's effect on the runs that choose?  (bool, the figures in words).

    The most an extension can cut the baseline's validation heading MAE by is down to the truth's own
    (:func:`noise_mae_psi`: the measurement noise).  When that room is under the diagnosis's own
    materiality bars, the floor in degrees (max of twice the heading noise and ``min_abs_gain_deg``,
    from the report's settings) or ``MIN_GAIN`` relative, the effect is immaterial in heading on these
    runs and "none" is as right as the effect's name: the diagnosis names an effect only when it
    is material in held-out heading (docs/diagnosis.md).  The linear-truth cases apply the same rule with the
    truth's own structure (tests/test_diagnose_cases.py ``_oracle_gain``).  Measured: a v|v| share of 0.70 on
    the fast ship leaves the baseline at 0.12 deg against a noise MAE of 0.08 deg."""
    s = report.get("settings", {})
    base = report["baseline"]["validation"]["mae_psi_deg"]
    floor = max(2.0 * s.get("heading_noise_deg", 0.0), s.get("min_abs_gain_deg", 0.0))
    room = base - noise_mae
    ok = room >= floor and room >= MIN_GAIN * base
    return ok, (f"baseline {base:.3f} deg, truth's own (noise) {noise_mae:.3f} deg: at most {room:.3f} deg "
                f"({room / base:.0%}) to cut, against the floor {floor:.3f} deg and {MIN_GAIN:.0%}")


def judge(case: Case, report: dict, noise_mae: float | None = None) -> tuple[bool, list[str], dict]:
    """(passed, reasons it failed, figures for the table) from diagnosis.json's documented keys
    (docs/diagnosis.md).

    With ``noise_mae`` (:func:`noise_mae_psi` of the validation runs), a case whose effect is not
    :func:`demonstrable` in heading is right when it names the effect or nothing, and names nothing
    else; no gain is then required (a named effect's estimate is still checked)."""
    cause = report.get("cause")
    ext = list(report.get("extended", {}).get("effects", []))
    gain = report.get("gain", {}).get("mae_psi_relative_reduction")
    why: list[str] = []
    figures = {"cause": cause, "extended": ext, "gain": gain, "estimates": {}}
    if case.accepted == ("none",):
        if cause != "none":
            why.append(f"clean truth, but cause {cause!r}")
        if ext:
            why.append(f"clean truth, but extended effects {ext}")
        return not why, why, figures
    if noise_mae is not None:
        shown, words = demonstrable(report, noise_mae)
        figures["demonstrable"] = (shown, words)
        if not shown:
            if cause != "none" and cause not in case.accepted:
                why.append(f"immaterial effect ({words}), but cause {cause!r}")
            extra = [e for e in ext if e not in case.accepted]
            if extra:
                why.append(f"immaterial effect, but spurious effects {extra}")
            _check_estimates(case, report, [e for e in case.accepted if e in ext or e == cause], why, figures)
            return not why, why, figures
    if cause not in case.accepted:
        why.append(f"cause {cause!r} not in {list(case.accepted)}")
    both = "+" in case.expected
    need = case.expected.split("+") if both else None
    if both:
        miss = [e for e in need if e not in ext]
        if miss:
            why.append(f"extended model lacks {miss}")
    elif not any(e in case.accepted for e in ext):
        why.append(f"no accepted effect in the extended model {ext}")
    extra = [e for e in ext if e not in case.accepted]
    if extra:
        why.append(f"spurious effects in the extended model: {extra}")
    if gain is None or not gain >= MIN_GAIN:
        why.append(f"held-out gain {gain} < {MIN_GAIN}")
    named = [e for e in (need or case.accepted) if e in ext or e == cause]
    _check_estimates(case, report, named, why, figures)
    return not why, why, figures


def _check_estimates(case: Case, report: dict, named: list[str], why: list[str], figures: dict) -> None:
    """Each named effect significant, its estimate within ``EST_TOL`` where the form matches, its sign
    right in the other form (appends to ``why`` and ``figures``)."""
    for e in named:
        f = _finding(report, e)
        if f is None:
            why.append(f"no findings row for {e}")
            continue
        if not f.get("significant"):
            why.append(f"{e} not significant")
        est = f.get("estimate", {}) or {}
        for key, true in case.true_estimates().items():
            got = _est_value(est, key)
            if got is None:
                continue
            figures["estimates"][key] = (got, true)
            if abs(got - true) > EST_TOL * abs(true):
                why.append(f"{e}: {key} {got:.4g} vs truth {true:.4g} (beyond {EST_TOL:.0%})")
        for key, sgn in case.sign.items():
            got = _est_value(est, key)
            if got is not None and key not in case.estimate:
                figures["estimates"][key] = (got, "sign " + ("-" if sgn < 0 else "+"))
                if got * sgn <= 0:
                    why.append(f"{e}: {key} {got:.3g} has the wrong sign (truth adds damping)")
