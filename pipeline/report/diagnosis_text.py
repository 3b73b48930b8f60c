"""Plain words and tables of the diagnosis report, from diagnosis.json (docs/diagnosis.md) alone.

Pure functions of the stage's output (no file access), so the notebook stays thin and every
sentence a reviewer reads can be tested.  Nothing here returns a raw dict, ``None`` or an internal
key: missing numbers become "n/a" and effect names become words.

Units: heading psi deg, yaw rate r deg/s, sway v m/s, rudder delta deg, time s (docs/contract.md#run-data).
Residuals are measured minus model.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

# Each effect's words, signature axis and residual are its own (pipeline.diagnose.effects.base.Effect:
# label, signature_axis, signature_residual), read from the catalogue at call time.
_R_RESIDUAL = ("r", "r error (deg/s)", "deg/s")


def _effect(name: Any):
    """The catalogue's effect of that name, or None (an effect this catalogue does not hold)."""
    from pipeline.diagnose.effects import BY_NAME

    return BY_NAME.get(str(name))


def effect_words_table() -> dict[str, str]:
    """{effect name: its words for a reader} over the catalogue (``Effect.label``)."""
    from pipeline.diagnose.effects import CATALOGUE

    return {e.name: e.reader_label() for e in CATALOGUE}


def signature_residual(effect: str) -> tuple[str, str, str]:
    """(series column, axis label, unit) of the held-out residual ``effect``'s signature is drawn in
    (``Effect.signature_residual``): the yaw rate's for an effect the catalogue does not hold."""
    e = _effect(effect)
    return tuple(e.signature_residual) if e is not None else _R_RESIDUAL


#: parameter-key unit suffixes of diagnosis.json -> unit text (the stage writes units only in the key
#: names; matched longest first).  Keys without a suffix are dimensionless.
_UNIT_SUFFIX = tuple(sorted({
    "_s_per_deg2": "s/deg^2", "_per_deg2": "1/deg^2", "_per_deg": "1/deg", "_s_per_m_deg": "s/(m deg)",
    "_s2_per_deg2": "s^2/deg^2", "_s_per_m2": "s/m^2", "_deg_per_m2": "deg/m^2", "_per_m": "1/m",
    "_deg_s": "deg/s", "_m_s": "m/s", "_deg": "deg", "_s": "s", "_m": "m",
}.items(), key=lambda kv: -len(kv[0])))


def effect_label(name: Any) -> str:
    """'nonlinear_yaw_damping' -> 'nonlinear yaw damping'; 'none' / empty -> 'none'."""
    if not name or name == "none":
        return "none"
    e = _effect(name)
    return e.reader_label() if e is not None else str(name).replace("_", " ")


def carried_text(entry: dict) -> str:
    """The words for what a model (diagnosis.json ``extended`` or a ``gain.nested[]`` round) carries
    without naming it (``carried``: in the model, below its physical floor); "" where nothing."""
    carried = [effect_label(e) for e in entry.get("carried") or []]
    return f"; also carried, not named (below its physical floor): {', '.join(carried)}" if carried else ""


def num(x: Any, digits: int = 3, unit: str = "") -> str:
    """A number for a sentence ('n/a' when absent or not finite), with its unit."""
    if x is None or isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)):
        return "n/a"
    if not math.isfinite(float(x)):
        return "n/a"
    return f"{float(x):.{digits}g}" + (f" {unit}" if unit else "")


def pct(x: Any, signed: bool = False) -> str:
    """0.61 -> '61 %' ('n/a' when absent)."""
    if not isinstance(x, (int, float)) or isinstance(x, bool) or not math.isfinite(float(x)):
        return "n/a"
    return f"{100 * x:+.0f} %" if signed else f"{100 * x:.0f} %"


def gain_text(g: Any) -> str:
    """A relative gain for a table cell or sentence: '+55 %', '-148 %', and for a model whose error
    grows more than tenfold '-205363 % (diverges)' (a free-run that leaves the data is no estimate)."""
    if not isinstance(g, (int, float)) or isinstance(g, bool) or not math.isfinite(float(g)):
        return "n/a"
    return pct(g, True) + (" (diverges)" if g < -9.0 else "")


def gain_sentence(g: Any, iv: Any = None) -> str:
    """'cuts the heading error by 55 % (95 % interval [48 %, 70 %])' or, for a negative gain,
    'makes the heading error WORSE by 148 % (95 % interval of the cut [-219 %, -41 %])'."""
    if not isinstance(g, (int, float)) or isinstance(g, bool):
        return "has no measured gain"
    ivt = interval(iv)
    if g >= 0:
        return f"cuts the heading error by {pct(g)}" + (f" (95 % interval {ivt})" if ivt else "")
    return (f"makes the heading error WORSE by {pct(-g)}" + (" (diverges)" if g < -9.0 else "")
            + (f" (95 % interval of the cut {ivt})" if ivt else ""))


def interval(iv: Any, *, percent: bool = True, digits: int = 3) -> str:
    """[a, b] as '[48 %, 70 %]' or '[3.9, 4.8]'; '' when there is none."""
    if not (isinstance(iv, (list, tuple)) and len(iv) == 2
            and all(isinstance(x, (int, float)) for x in iv)):
        return ""
    if percent:
        return f"[{pct(iv[0])}, {pct(iv[1])}]"
    return f"[{num(iv[0], digits)}, {num(iv[1], digits)}]"


def param_label(key: str) -> str:
    """'n_rrr_s_per_deg2' -> 'n_rrr (s/deg^2)', 'offset_deg' -> 'offset (deg)', 'asymmetry' ->
    'asymmetry (-)' (the coefficient's symbol is kept as written: n_rrr is a symbol, not a word)."""
    for suffix, unit in _UNIT_SUFFIX:
        if key.endswith(suffix) and len(key) > len(suffix):
            return f"{key[: -len(suffix)]} ({unit})"
    return f"{key} (-)"


def estimate_text(estimate: dict | None, uncertainty: dict | None) -> str:
    """'offset (deg) = -1.19 +- 0.03; ...': the fitted parameters with one standard error; derived
    numbers (non-parameters, e.g. the share of the largest rudder) are left to the physical words."""
    est, unc = estimate or {}, uncertainty or {}
    parts = []
    for k, v in est.items():
        if k not in unc or not isinstance(v, (int, float)) or isinstance(v, bool):
            continue
        u = unc.get(k)
        pm = f" +- {num(u, 2)}" if isinstance(u, (int, float)) and math.isfinite(u) else ""
        parts.append(f"{param_label(k)} = {num(v, 3)}{pm}")
    return "; ".join(parts)


# ------------------------------------------------------------------------------- verdicts
VERDICTS = ("named", "immaterial", "failed a fold", "no better than the best linear model",
            "harms a held-out run", "worse from the measured state", "carried by one held-out run",
            "hinges on a training run", "not significant", "not tried", "fit failed")


def rivals_text(f: dict) -> str:
    """A named finding's rivals (diagnosis.json ``findings[].rivals``: the candidates its selection
    step could not tell from it) in words, "rudder offset (+25 %), ..."; "" when it has none."""
    return ", ".join(f"{effect_label(r['effect'])} ({gain_text(r.get('validation_gain'))})"
                     for r in f.get("rivals") or [] if r.get("effect"))


def verdict(f: dict, settings: dict | None = None, *, all_tests: bool = False) -> tuple[str, ...]:
    """(verdict, reason in words) of one finding of diagnosis.json.

    The verdict is the first that applies, in this order: named (significant); not tried (the data cannot
    carry it); fit failed; immaterial (below its physical floor, a heading cut below the noise level, or a
    relative gain below the threshold); failed a fold (not better in every fold); no better than the best
    linear model (the extension of the bounded fit predicts the held-out runs no better than the linear
    model fitted without the bounds); harms a held-out run (significantly worse on one, or runs away on
    it); worse from the measured state (the held-out runs' pieces of a ship time scale, each from the
    measured state, predicted significantly worse: select.py's short-horizon judge); carried by one
    held-out run (significant only with that run's blocks: select.carried_by_one_run); hinges on a
    training run (refitted without one of its training runs, the model no longer makes that run: select.py's
    Search.hinges); not significant (block t-test).
    The reason lists every test it failed, with its numbers: the words of the finding's failed
    ``gates`` (diagnosis.json, read by code), or for a finding without them its numeric keys.
    ``all_tests``: return every verdict it earns instead (see :func:`failed_tests`).
    """
    s = settings or {}
    ev = str(f.get("evidence") or "")
    if f.get("significant"):
        why = "passes every test: gain, every fold, above noise and floor, significant"
        told = rivals_text(f)
        if told:
            why += f"; but when it was added the held-out runs hardly told it from {told}, within one " \
                   "standard error"
        return "named", why
    if f.get("validation_gain") is None:
        if ev.lower().startswith("not tried"):
            return "not tried", ev[len("not tried"):].lstrip(": ").rstrip(".") or "not applicable"
        return "fit failed", "its fit failed in some fold, so it was not judged"
    gates = [g for g in f.get("gates") or [] if isinstance(g, dict) and g.get("passed") is False]
    if gates:   # the selection's own criteria (diagnosis.json findings[].gates, pipeline.diagnose.gates)
        reasons = [(GATE_VERDICT.get(str(g.get("code")), "not significant"), effect_words(g.get("words")))
                   for g in gates]
    else:       # a finding written without gates: its numeric keys
        reasons = _reasons_from_keys(f, s)
    reasons.sort(key=lambda vr: VERDICTS.index(vr[0]))
    if not reasons:
        return "not significant", "another effect already explained the same error"
    if all_tests:
        return tuple(dict.fromkeys(v for v, _ in reasons))
    return reasons[0][0], "; ".join(dict.fromkeys(r for _, r in reasons))


#: a gate's code (pipeline.diagnose.gates.CODES) -> the report's verdict when it fails
GATE_VERDICT = {
    "min_gain": "immaterial", "noise_floor": "immaterial", "physical_floor": "immaterial",
    "every_fold": "failed a fold", "no_harm": "harms a held-out run", "no_runaway": "harms a held-out run",
    "short_horizon": "worse from the measured state", "carried_by_one_run": "carried by one held-out run",
    "hinge": "hinges on a training run", "block_t": "not significant",
    "beats_best_linear": "no better than the best linear model",
}


def _reasons_from_keys(f: dict, s: dict) -> list[tuple[str, str]]:
    """(verdict, reason) of a finding without ``gates``, from its numeric keys alone."""
    reasons: list[tuple[str, str]] = []
    if f.get("material") is False:
        reasons.append(("immaterial", "below its physical floor (" + floor_measured(f.get("floor")) + ")"))
    g, gmin = f.get("validation_gain"), s.get("min_gain")
    if isinstance(g, (int, float)) and isinstance(gmin, (int, float)) and g < gmin:
        reasons.append(("immaterial", f"held-out gain {gain_text(g)} below the {pct(gmin)} threshold"))
    folds = [x for x in f.get("validation_gain_folds") or [] if isinstance(x, (int, float))]
    if folds and min(folds) <= 0:
        reasons.append(("failed a fold", "worse in a fold (per fold " + ", ".join(gain_text(x) for x in folds)
                        + ")"))
    if f.get("hinges_on"):
        reasons.append(("hinges on a training run", "refitted without it, the model no longer makes that "
                        "training run: " + "; ".join(f["hinges_on"])))
    t, tc = f.get("block_t"), f.get("block_t_crit")
    if isinstance(t, (int, float)) and isinstance(tc, (int, float)) and not t >= tc:
        dof = (f.get("blocks") or 0) - 1
        reasons.append(("not significant", f"block t = {num(t, 2)} below {num(tc, 3)} ({dof} dof)"))
    return reasons


def failed_tests(f: dict, settings: dict | None = None) -> tuple[str, ...]:
    """Every verdict a rejected finding earns (an effect may be immaterial AND fail a fold), in the
    order of :data:`VERDICTS`; a named effect gives ('named',)."""
    out = verdict(f, settings, all_tests=True)
    return out if isinstance(out, tuple) and all(x in VERDICTS for x in out) else (out[0],)


#: deg: a removal that raises the mean free-run heading error by more than half a turn no longer
#: mis-predicts the manoeuvre, the simulated ship has turned away from it (its free run diverged)
DIVERGED_CUT_DEG = 180.0


def cut_text(cut: Any) -> str:
    """'cut 2.3 deg' (the held-out heading error a finding's removal adds), or, beyond
    :data:`DIVERGED_CUT_DEG`, the divergence in words rather than as a size ('cut 1e+04 deg')."""
    if isinstance(cut, (int, float)) and not isinstance(cut, bool) and math.isfinite(cut) \
            and cut > DIVERGED_CUT_DEG:
        return (f"without it the free run diverges (mean heading error {num(cut, 2)} deg larger, "
                f"over half a turn)")
    return f"cut {num(cut, 2, 'deg')}"


def floor_measured(floor: Any) -> str:
    """The measured side of a finding's ``floor`` text ('|offset| 0.09 deg (floor 0.3 deg)'), one
    per distinct fold reading; the stated reason in brackets is left to :func:`floor_reason`."""
    text = str(floor or "").split(" [")[0]
    return "; ".join(dict.fromkeys(x.strip() for x in text.split(";") if x.strip())) or "n/a"


def floor_reason(floor: Any) -> str:
    """The stated physical reason of a finding's floor (the bracketed part of ``floor``)."""
    text = str(floor or "")
    return text.split(" [", 1)[1].rstrip("]") if " [" in text else ""


def effect_words(text: Any) -> str:
    """A stage sentence with the catalogue's effect names as words: 'rudder_offset + sway_yaw_coupling'
    -> 'rudder offset + sway-yaw cross terms' (whole names only, longest first)."""
    out = str(text or "")
    words = effect_words_table()
    for name in sorted(words, key=len, reverse=True):
        out = re.sub(rf"(?<![\w]){re.escape(name)}(?![\w])", words[name], out)
    return out


def plain(text: Any, keys: Any = ()) -> str:
    """A stage sentence with its parameter keys as words: 'n_rrr_s_per_deg2 = -0.03' ->
    'n_rrr (s/deg^2) = -0.03' (keys: the parameter names of the finding)."""
    out = str(text or "")
    for k in sorted(keys or (), key=len, reverse=True):
        if "_" in str(k):
            out = out.replace(str(k), param_label(str(k)))
    return out


# ------------------------------------------------------------------------------- the baseline
def poles(params: dict | None) -> list[complex] | None:
    """Eigenvalues (1/s) of the linear sway-yaw model's state matrix [[a11, a12], [a21, a22]].

    Eigenvalues do not depend on the state units (a similarity transform), so the mixed units of
    docs/contract.md#run-data (v m/s, r deg/s) give the poles in 1/s directly."""
    p = params or {}
    try:
        a = np.array([[p["a11"], p["a12"]], [p["a21"], p["a22"]]], dtype=float)
    except (KeyError, TypeError, ValueError):
        return None
    if not np.all(np.isfinite(a)):
        return None
    return [complex(x) for x in np.linalg.eigvals(a)]


def stability_words(params: dict | None, course_stable: Any) -> str:
    """One sentence on the baseline's course stability, with the slowest pole and its time scale."""
    ev = poles(params)
    if ev is None:
        return ("course stability not reported" if course_stable is None else
                ("course-stable" if course_stable else "course-UNSTABLE"))
    lead = max(ev, key=lambda z: z.real)
    lam = lead.real
    if lam > 0:
        return (f"course-UNSTABLE: its slowest pole is +{num(lam, 3)} 1/s, so with the rudder held a "
                f"heading disturbance doubles in {num(math.log(2) / lam, 3)} s (fitted as it is, "
                "stability not forced)")
    if lam == 0:
        return "marginally course-stable (a pole at zero)"
    return (f"course-stable: its slowest pole is {num(lam, 3)} 1/s, a yaw time constant of "
            f"{num(-1.0 / lam, 3)} s")


def steady_turn(params: dict | None, delta_deg: float) -> float | None:
    """Steady yaw rate (deg/s) of the linear model for a constant rudder ``delta_deg`` (deg); None for
    a singular or unstable model (no steady turn is reached)."""
    p = params or {}
    ev = poles(p)
    if ev is None or max(z.real for z in ev) >= 0:
        return None
    a = np.array([[p["a11"], p["a12"]], [p["a21"], p["a22"]]], dtype=float)
    b = np.array([p["b11"], p["b21"]], dtype=float)
    x = -np.linalg.solve(a, b * delta_deg)
    return float(x[1])


def offset_words(est: dict | None, params: dict | None) -> str:
    """What a rudder offset does to the ship, in numbers: the yaw acceleration it gives on a straight
    course (b21 x offset, deg/s^2) and, for a course-stable model, the steady turn it holds."""
    e, p = est or {}, params or {}
    off = e.get("offset_deg")
    if not isinstance(off, (int, float)):
        return ""
    side = "starboard" if off > 0 else "port"
    acc = p.get("b21") * off if isinstance(p.get("b21"), (int, float)) else None
    words = f"{num(abs(off), 2)} deg of rudder to {side}"
    if acc is not None:
        words += f", a yaw acceleration of {num(abs(acc), 2)} deg/s^2 on a straight course"
    rr = steady_turn(p, off)
    if rr is not None:
        words += (f"; with the rudder logged at zero the model turns steadily at {num(abs(rr), 2)} deg/s "
                  f"({num(abs(rr) * 60, 2)} deg per minute) to {side}")
    return words


# ------------------------------------------------------------------------------- tables
def ladder_rows(dg: dict) -> list[dict]:
    """The model ladder in the order it was climbed: step, model (in words), effects, validation and
    test MAE of psi (deg), and the test gain over the baseline with its 95 % interval.

    The stage's ``test_interval_95`` of a rung is the bootstrap interval of that rung's RELATIVE
    gain over the baseline on the test runs (pipeline/diagnose/core.py ``_honest_gain``: 0 for the
    baseline itself), not an interval of the MAE in deg; it is shown as such."""
    rows = []
    lad = dg.get("ladder") or []
    base_test = lad[0].get("test_mae_psi_deg") if lad else None
    for i, rung in enumerate(dg.get("ladder") or []):
        effs = [effect_label(e) for e in rung.get("effects") or []]
        name = str(rung.get("model") or "")
        if i == 0 or not effs:
            words = "linear baseline"
        elif name.startswith(("+", "-")):
            words = move_words(name)
        else:
            words = name
        tm = rung.get("test_mae_psi_deg")
        tg = (1.0 - tm / base_test) if isinstance(tm, (int, float)) and base_test else None
        rows.append({"step": i, "model": words, "effects": " + ".join(effs) or "none",
                     "validation MAE psi (deg)": rung.get("validation_mae_psi_deg"),
                     "test MAE psi (deg)": tm,
                     "test gain over baseline": gain_text(tg) if i else "",
                     "test gain 95 % interval": (interval(rung.get("test_interval_95")) or "n/a")
                     if i else ""})
    return rows


def move_words(name: str) -> str:
    """A ladder rung's moves in words: '+rudder_offset+speed_loss-rudder_lag' -> 'adds rudder offset and
    speed loss in turns; drops steering-gear lag' (the effects' labels, in the rung's order)."""
    moves = _split_moves(name)
    parts = []
    for sign, verb in (("+", "adds"), ("-", "drops")):
        labels = [effect_label(m[1:]) for m in moves if m[0] == sign]
        if labels:
            parts.append(f"{verb} " + (labels[0] if len(labels) == 1
                                       else ", ".join(labels[:-1]) + " and " + labels[-1]))
    return "; ".join(parts)


def _split_moves(name: str) -> list[str]:
    """'+rudder_offset-speed_loss' -> ['+rudder_offset', '-speed_loss'] (effect names hold no +/-)."""
    out, cur = [], ""
    for ch in name:
        if ch in "+-" and cur:
            out.append(cur)
            cur = ""
        cur += ch
    if cur:
        out.append(cur)
    return out


def signature_x(frame, effect: str):
    """(x values, axis label) of ``effect``'s signature (``Effect.signature_axis``) from the series
    table (columns time s, delta deg, r deg/s, v m/s, u m/s), or None when the columns are missing;
    "ddelta" is the rudder rate d(delta)/dt (deg/s) and "vr" the product v r (m/s x deg/s)."""
    e = _effect(effect)
    col, lab = e.signature_axis if e is not None else ("time", "time (s)")
    if col == "ddelta":
        parts = [np.gradient(g["delta"].to_numpy(), g["time"].to_numpy())
                 for _, g in frame.groupby("run_id", sort=False)]
        return np.concatenate(parts), lab
    if col == "vr":
        if "v" not in frame or frame["v"].isna().all():
            return None
        return (frame["v"] * frame["r"]).to_numpy(), lab
    if col not in frame or frame[col].isna().all():
        return None
    return frame[col].to_numpy(), lab


def binned(x, y, *, bins: int = 15):
    """Bin centres and mean y per bin over the range of x (bins with fewer than 5 points dropped):
    the trend a residual cloud shows against a signature."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 10 or np.ptp(x) == 0:
        return np.array([]), np.array([])
    edges = np.linspace(x.min(), x.max(), bins + 1)
    idx = np.clip(np.digitize(x, edges) - 1, 0, bins - 1)
    cs, ms = [], []
    for b in range(bins):
        m = idx == b
        if m.sum() >= 5:
            cs.append(0.5 * (edges[b] + edges[b + 1]))
            ms.append(float(y[m].mean()))
    return np.array(cs), np.array(ms)


# ------------------------------------------------------------------------------- baseline choice, adequacy
def baseline_choice_text(dg: dict) -> str:
    """Which linear fit is the baseline (with or without the ship-sign bounds), both fits' held-out MAE
    psi (deg), and the gain of the extended model against the other fit (diagnosis.json
    ``baseline.sign_bounds``, ``baseline.other_linear``, ``gain.against_other_linear``); "" when the
    stage wrote no other fit."""
    base = dg.get("baseline") or {}
    other = base.get("other_linear")
    if not isinstance(other, dict):
        return ""
    kept = "with the ship-sign bounds (a11, a12, a21, a22 <= 0)" if base.get("sign_bounds") else \
        "without sign bounds (unconstrained)"
    alt = "unconstrained" if base.get("sign_bounds") else "bounded"
    mine, theirs = pooled_baseline_mae(dg), other.get("validation_mae_psi_deg")
    worse = isinstance(mine, (int, float)) and isinstance(theirs, (int, float)) and theirs < mine
    text = (f"The baseline is the linear fit {kept}"
            + (f"; the {alt} fit predicts the selection's validation runs BETTER" if worse else
               ", the one that predicts the selection's validation runs better")
            + f": held-out MAE psi {num(mine, 3, 'deg')} against {num(theirs, 3, 'deg')} for the {alt} "
            "fit (each the mean over the folds of its validation runs' MAE)")
    if other.get("at_sign_bound"):
        text += f", which holds {', '.join(other['at_sign_bound'])} at its bound 0"
    text += "."
    ag = (dg.get("gain") or {}).get("against_other_linear")
    if isinstance(ag, dict) and (dg.get("extended") or {}).get("effects"):
        text += (f" Against the {alt} fit the extended model "
                 f"{gain_sentence(ag.get('mae_psi_relative_reduction'), ag.get('interval_95'))} on the runs "
                 f"no choice has seen (validation: {pct(ag.get('validation_mae_psi_relative_reduction'))}).")
    return text


#: the linear parameters every displacement ship has at or below 0 (the ship-sign bounds,
#: :func:`pipeline.diagnose.fit.sign_bound_text`)
SHIP_SIGNED = ("a11", "a12", "a21", "a22")


def unphysical_signs_text(dg: dict) -> str:
    """Where the baseline is the linear fit without sign bounds (diagnosis.json ``baseline.sign_bounds``
    false) and some of a11, a12, a21, a22 came out above 0 (``baseline.parameters``): one sentence
    naming them with their values, saying that the fit is the best linear predictor of these runs, not
    a physical model of the hull, and that its course stability is read from the poles of its whole
    matrix (``baseline.course_stable``); "" otherwise."""
    base = dg.get("baseline") or {}
    p = base.get("parameters") or {}
    if base.get("sign_bounds") is not False:
        return ""
    off = [(k, p[k]) for k in SHIP_SIGNED
           if isinstance(p.get(k), (int, float)) and not isinstance(p.get(k), bool) and p[k] > 0]
    if not off:
        return ""
    vals = " and ".join(f"{k} = +{num(v)}" for k, v in off)
    verb = "has" if len(off) == 1 else "have"
    stable = base.get("course_stable")
    poles = ("" if not isinstance(stable, bool) else
             f" Its course stability ({'stable' if stable else 'unstable'}) is that of the poles of its "
             "whole state matrix, not of any one coefficient's sign.")
    return (f"The unconstrained baseline's {vals} {verb} not a ship's sign (every displacement ship has "
            "a11, a12, a21, a22 <= 0): it is the linear model that best predicts these runs, its "
            "coefficients standing in for what the linear form lacks, not a physical model of the hull."
            + poles)


def pooled_baseline_mae(dg: dict) -> float | None:
    """The baseline's held-out MAE psi (deg), the mean over the folds of each fold's validation runs'
    MAE: the ladder's first rung, the number the selection judges by."""
    lad = dg.get("ladder") or []
    return lad[0].get("validation_mae_psi_deg") if lad else None


def adequacy_text(dg: dict) -> str:
    """A plain sentence when diagnosis.json says the linear baseline is inadequate (``baseline_adequate``
    false): its error against the stated multiple of the noise floor and the signatures its residual
    follows, in words; "" when it is adequate or the key is absent."""
    if dg.get("baseline_adequate") is not False:
        return ""
    a = dg.get("baseline_adequacy") or {}
    sig = ", ".join(f"{effect_label(s.get('effect'))} ({num(s.get('correlation'), 2)})"
                    for s in a.get("signatures") or [])
    text = (f"The linear model is inadequate for these runs: its held-out heading error "
            f"{num(a.get('mae_psi_deg'), 3, 'deg')} is above {num(a.get('floors'), 3)} noise floors "
            f"({num(a.get('threshold_deg'), 3, 'deg')}).")
    if dg.get("cause") == "none":
        text += (" 'None' here means no effect of the catalogue passed the tests, not that the linear model "
                 "fits.")
    if sig:
        text += (f" Its residual follows the signatures of {sig} (correlation with the yaw-acceleration "
                 "error).")
        if dg.get("cause") not in (None, "none"):
            # the correlations are of the linear model's residual, one effect at a time; the cause is
            # what the held-out selection found, and a reader must not take the two for one verdict
            text += (" These correlations point from the linear model's residual, one effect at a time; "
                     f"the cause is what the held-out selection found: {effect_label(dg['cause'])}.")
    return text


def reference_text(dg: dict) -> str:
    """The reference fit beside the selection (diagnosis.json ``reference``: the catalogue's terms told
    everything at once; said to be the selection's structure where ``extended`` has the same effects in
    the same forms, "not chosen" otherwise): its held-out MAE psi (deg) on the validation runs, the mean over
    the folds as the ladder's, against the baseline's and the selection's; with test runs its figure
    there too, and in the nested mode its figure under that protocol beside the honest gain's.  "" when
    the stage made none."""
    ref = dg.get("reference")
    if not isinstance(ref, dict) or not ref.get("computed"):
        return ""
    lad = dg.get("ladder") or []
    chosen = lad[-1].get("validation_mae_psi_deg") if lad else None
    terms = ", ".join(effect_label(e) for e in ref.get("effects") or [])
    ext = dg.get("extended") or {}
    # the selection took the reference's structure (the reference step) or not: said as it is
    in_model = set(ext.get("effects") or []) | set(ext.get("carried") or [])
    same = bool(ref.get("effects")) and in_model == set(ref["effects"]) and all(
        (ext.get("forms") or {}).get(e) == f for e, f in (ref.get("forms") or {}).items())
    status = "the structure the selection chose" if same else "not chosen"
    text = (f"Reference fit ({status}: the catalogue's terms told everything at once, {terms}): held-out "
            f"MAE psi {num(ref.get('validation_mae_psi_deg'), 3, 'deg')} on the validation runs (mean over "
            f"the folds, each fold's fit on its training runs), "
            f"{pct(ref.get('validation_mae_psi_relative_reduction'), signed=True)} against the baseline's "
            f"{num(pooled_baseline_mae(dg), 3, 'deg')}; the selected model: {num(chosen, 3, 'deg')}.")
    if isinstance(ref.get("test_mae_psi_deg"), (int, float)):
        text += (f" On the test runs, refitted on all selection runs: "
                 f"{num(ref['test_mae_psi_deg'], 3, 'deg')} "
                 f"against the baseline's {num(ref.get('test_baseline_mae_psi_deg'), 3, 'deg')}, "
                 f"{gain_sentence(ref.get('test_mae_psi_relative_reduction'), ref.get('test_interval_95'))}.")
    if isinstance(ref.get("nested_mae_psi_deg"), (int, float)):
        g = dg.get("gain") or {}
        cut = gain_sentence(ref.get("nested_mae_psi_relative_reduction"), ref.get("nested_interval_95"))
        text += (f" Under the honest gain's protocol (nested leave-one-run-out: refitted without each run "
                 f"and measured on it, {len(ref.get('nested_measured_on') or [])} runs), the reference {cut}"
                 f" ({num(ref.get('nested_baseline_mae_psi_deg'), 3, 'deg')} -> "
                 f"{num(ref['nested_mae_psi_deg'], 3, 'deg')}), where the selection's honest gain is "
                 f"{gain_text(g.get('mae_psi_relative_reduction'))}.")
    reading = reference_reading(dg)
    return text + (" " + reading if reading else "")


def reference_reading(dg: dict) -> str:
    """Where the verdict is none, the plain reading of the reference fit: where it does not beat the
    baseline by a material margin (diagnosis.json ``reference.material`` false), the catalogue's terms
    told everything at once do not carry what the linear model misses on these runs, with the
    reference's pooled held-out reduction against its threshold (``reference.material_threshold``) and
    the honest gain with its interval (:func:`honest_gain_text`); where it is material and its cut under
    the nested protocol is at least that threshold at 95 % (``reference.nested_interval_95``), they do
    carry it together, and none means the cause could not be named; "" otherwise."""
    ref = dg.get("reference")
    if dg.get("cause") != "none" or not isinstance(ref, dict):
        return ""
    iv = ref.get("nested_interval_95")
    if ref.get("material") is True and isinstance(iv, list) and len(iv) == 2 \
            and isinstance(iv[0], (int, float)) and iv[0] >= (ref.get("material_threshold") or 0.0):
        return (f"So the catalogue's terms, taken together, carry what the linear model lacks on these runs "
                f"(the reference's honest cut is at least {pct(iv[0])} at 95 %, above the "
                f"{pct(ref.get('material_threshold'))} a model change needs), but no effect or small group "
                f"of them passed the selection's tests on its own: the verdict none says that the cause "
                f"could not be named, not that the linear model will do.")
    if ref.get("material") is not False:
        return ""
    g = ref.get("validation_mae_psi_relative_reduction")
    how = (f"makes the baseline's held-out heading error worse by {pct(-g)}" if isinstance(g, (int, float))
           and g < 0 else f"cuts the baseline's held-out heading error by only {pct(g)}")
    text = (f"Not a term the selection missed: told every term of the catalogue at once, the reference "
            f"fit {how}, short of the {pct(ref.get('material_threshold'))} cut a model change needs, so "
            f"what the linear model lacks on these runs is not carried by the catalogue's hull and rudder "
            f"terms.")
    honest = honest_gain_text(dg)
    return text + (f" {honest}." if honest else "")


#: the two modes of the honest gain (diagnosis.json ``test_runs`` given or not)
TEST_MODE, NESTED_MODE = "test runs", "nested leave-one-run-out"


def gain_mode(dg: dict) -> str | None:
    """The mode the honest gain was measured in: :data:`TEST_MODE` when diagnosis.json lists test runs,
    :data:`NESTED_MODE` otherwise; None when it holds no honest gain (``gain.mae_psi_relative_reduction``
    absent)."""
    g = dg.get("gain") or {}
    if not isinstance(g.get("mae_psi_relative_reduction"), (int, float)) or isinstance(
            g.get("mae_psi_relative_reduction"), bool):
        return None
    return TEST_MODE if dg.get("test_runs") else NESTED_MODE


def honest_fits(dg: dict) -> tuple[str, str]:
    """(the baseline, the model compared with it) of the honest gain, in words that say which fit each
    is in the mode used: refitted on all selection runs (test runs), or fitted without the held-out run
    (nested leave-one-run-out)."""
    named = bool((dg.get("extended") or {}).get("effects"))
    if gain_mode(dg) == TEST_MODE:
        return ("the linear baseline refitted on all training and validation runs",
                "the extended model refitted on them" if named else
                "the model kept (that same linear baseline: no effect is named)")
    return ("the linear baseline fitted without the held-out run",
            "the model each selection chose without the held-out run")


def honest_mae_text(dg: dict) -> str:
    """'mean free-run MAE psi over the N runs no choice has seen (MODE): B deg for <baseline> -> E deg
    for <model>', from ``gain.baseline_mae_psi_deg`` / ``gain.extended_mae_psi_deg`` (each the mean over
    ``gain.measured_on`` of one run's MAE); "" without an honest gain."""
    g = dg.get("gain") or {}
    mode = gain_mode(dg)
    if mode is None:
        return ""
    base, model = honest_fits(dg)
    n = len(g.get("measured_on") or [])
    return (f"mean free-run MAE psi over the {n} run{'s' if n != 1 else ''} no choice has seen ({mode}): "
            f"{num(g.get('baseline_mae_psi_deg'), 4, 'deg')} for {base} -> "
            f"{num(g.get('extended_mae_psi_deg'), 4, 'deg')} for {model}")


def honest_gain_text(dg: dict) -> str:
    """The honest gain in one sentence, in the mode used: who gains, by how much with its 95 % interval
    (``gain.mae_psi_relative_reduction``, ``gain.interval_95``), and the two mean MAEs it is made of
    (:func:`honest_mae_text`); "" without an honest gain."""
    g = dg.get("gain") or {}
    if gain_mode(dg) is None:
        return ""
    _, model = honest_fits(dg)
    who = "the extended model" if gain_mode(dg) == TEST_MODE else "the model chosen without each run"
    if not (dg.get("extended") or {}).get("effects") and gain_mode(dg) == TEST_MODE:
        who = "the model kept"
    return (f"On the runs no choice has seen, {who} "
            f"{gain_sentence(g['mae_psi_relative_reduction'], g.get('interval_95'))} "
            f"({honest_mae_text(dg)})")


def headline(dg: dict) -> str:
    """The command line's one line: the cause and the honest gain with the MAEs (deg) it is computed
    from, the runs and the mode it is measured in, all from diagnosis.json's ``gain`` block (one set
    of numbers: the interval is that gain's own); without an honest gain, the validation MAEs pooled
    over the folds (the ladder's first and last rungs), said to be chosen on those runs."""
    g = dg.get("gain") or {}
    head = f"diagnosis: cause {dg.get('cause', 'none')}"
    if gain_mode(dg) is not None:
        ivt = interval(g.get("interval_95"))
        text = (f"{head}; honest gain {gain_text(g['mae_psi_relative_reduction'])}"
                + (f" (95 % interval {ivt})" if ivt else "") + f": {honest_mae_text(dg)}")
    else:
        lad = dg.get("ladder") or []
        first, last = (lad[0], lad[-1]) if lad else ({}, {})
        text = (f"{head}; validation MAE psi {num(first.get('validation_mae_psi_deg'), 4, 'deg')} -> "
                f"{num(last.get('validation_mae_psi_deg'), 4, 'deg')} (mean over the folds; chosen on these "
                "runs, no honest gain)")
    if dg.get("baseline_adequate") is False:
        text += "; the linear baseline is inadequate (see baseline_adequacy)"
    return text
