"""Study kind ``detection_power``: the smallest effect the diagnosis finds, and how often it names an
effect that is not there.

Cases (per plant): every effect of the diagnosis catalogue that this module can inject, at each
magnitude of the spec times ``seeds`` replicates, plus ``clean_seeds`` clean replicates.  Each case
simulates zigzags and runs the full diagnosis (:func:`pipeline.diagnose.diagnose`) on them: with
``runs_per_side = 2`` (default) the crossed design of the catalog and of tests/test_diagnose_cases.py
(train R/R starboard + R/2 port, validate R/R port + R/2 starboard: both sides, two amplitudes, two
folds); with 1, train on R/R starboard and validate on R/R port (one fold: cheaper, weaker).

Plants:

* ``truth``: the linear truth model (:mod:`pipeline.diagnose.truth`, continuous time, 8 sub-steps,
  seeded white noise; every catalogue effect injectable, each in a form of its own, not the
  candidate's: a servo lag, v|v| drag in sway only, v^2 r in yaw only, a tanh rudder stall); the
  ship is the paper's Table 4 with the hull block and the rudder block each scaled by a factor
  drawn in [0.85, 1.15] per case (from the case's seed), so the study does not measure one ship
  only.  Clean means exactly linear plus white noise: any significant effect there
  is a false positive.
* ``tank``: the virtual KCS (:mod:`pipeline.tank`, port/starboard-symmetric rudder, speed held),
  effects injected through TankConfig.  The KCS has effects of its own (``tank_own_effects``: its
  hull nonlinearity, which any hull effect may carry); those are not counted as false positives
  there, and not studied on it.

Per case: ``detected`` = the injected effect's finding is significant; ``named`` = it is the named
cause; ``false_positive`` = some other effect (not one of the plant's own) is significant; the
estimate of the effect's own parameter beside its true value in the same terms.

Summary (summary.json): per effect and plant, the detection rate at each magnitude with its
Clopper-Pearson interval; ``min_detectable_90``, the magnitude detected in 90 % of cases, from a
logistic fit of detection on log magnitude, with a percentile-bootstrap interval (cases resampled
within each magnitude; seeded from the study seed); per plant the ``false_positive_rate`` on clean
cases with its Clopper-Pearson interval; the estimate's bias and spread per magnitude.
"""

from __future__ import annotations

import dataclasses as dc
import html
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pipeline.config import DetectionPowerConfig, DiagnoseConfig, TankConfig
from pipeline.diagnose.effects.base import PLANTS
from pipeline.errors import InputError
from pipeline.study.kind import StudyKind
from pipeline.study.stats import clopper_pearson, logistic_level, rng_for


def catalogue_effects() -> tuple[str, ...]:
    """Effect names of the diagnosis catalogue (``pipeline.diagnose.effects.CATALOGUE``), read at run
    time so that an effect added there is studied without a change here."""
    from pipeline.diagnose.effects import CATALOGUE

    return tuple(e.name for e in CATALOGUE)


# ---------------------------------------------------------------- injection
# What a plant may inject and how, the estimate key and the magnitude's unit are the effect's own
# (pipeline.diagnose.effects.base.Effect: injection, inject, estimate_key, magnitude_unit).


def _effect(name: str):
    from pipeline.diagnose.effects import BY_NAME

    return BY_NAME[name]


def _truth_inject(effect: str, mag: float, cfg):
    """(truth config with the effect at magnitude ``mag``, true value in the estimate's terms)."""
    return _effect(effect).inject("truth", mag, cfg)


def _tank_inject(effect: str, mag: float, cfg: TankConfig, rudder_deg: float):
    """(tank config with the effect, true value in the estimate's terms); ``rudder_deg``: the
    largest rudder of the tank's zigzags (where the stall's estimate is read)."""
    return _effect(effect).inject("tank", mag, cfg, rudder_deg)


# ---------------------------------------------------------------- cases


def _effects(cfg: DetectionPowerConfig) -> tuple[str, ...]:
    cat = catalogue_effects()
    if cfg.effects:
        unknown = [e for e in cfg.effects if e not in cat]
        if unknown:
            raise InputError(f"effect {unknown[0]!r} is not in the diagnosis catalogue ({', '.join(cat)})")
        return tuple(cfg.effects)
    return cat


def check(cfg: DetectionPowerConfig) -> None:
    """Refuse settings no case could run with, naming the key (the spec's ``check``)."""
    cat = catalogue_effects()
    t = "detection_power"
    for key in ("effects", "tank_own_effects"):
        for e in getattr(cfg, key):
            if e not in cat:
                raise InputError(f"key '{t}.{key}': unknown effect {e!r} (known: {', '.join(cat)})")
    for e, mags in cfg.magnitudes.items():
        if e not in cat:
            raise InputError(f"key '{t}.magnitudes.{e}': unknown effect {e!r} (known: {', '.join(cat)})")
        for m in mags:
            if not m > 0:             # a magnitude is the size of an effect that is there
                raise InputError(f"key '{t}.magnitudes.{e}': magnitudes must be > 0, got {m}")
    for p in cfg.plants:
        if p not in PLANTS:
            raise InputError(f"key '{t}.plants': unknown plant {p!r} (known: {', '.join(PLANTS)})")
    if not cfg.duration_s > 0:
        raise InputError(f"key '{t}.duration_s': a run lasts > 0 s, got {cfg.duration_s}")
    for key in ("rudder_deg", "tank_rudder_deg"):    # a zigzag needs a rudder order, within hard over
        if not 0 < getattr(cfg, key) <= 35.0:
            raise InputError(f"key '{t}.{key}': must be in (0, 35] deg, got {getattr(cfg, key)}")
    if cfg.runs_per_side not in (1, 2):
        raise InputError(f"key '{t}.runs_per_side': must be 1 or 2, got {cfg.runs_per_side}")
    for key in ("seeds", "clean_seeds"):
        if getattr(cfg, key) < 0:
            raise InputError(f"key '{t}.{key}': must be 0 or more, got {getattr(cfg, key)}")
    for key in ("level", "confidence"):              # probabilities
        if not 0 < getattr(cfg, key) < 1:
            raise InputError(f"key '{t}.{key}': must be in (0, 1), got {getattr(cfg, key)}")
    if cfg.bootstrap < 1:
        raise InputError(f"key '{t}.bootstrap': must be at least 1, got {cfg.bootstrap}")


def not_studied(cfg: DetectionPowerConfig) -> dict[str, dict[str, str]]:
    """{plant: {effect: reason}} for effects of the study that a plant cannot take."""
    out: dict[str, dict[str, str]] = {}
    for plant in cfg.plants:
        for e in _effects(cfg):
            if e not in cfg.magnitudes or not cfg.magnitudes[e]:
                why = "no magnitudes given in the spec"
            elif plant == "tank" and e in cfg.tank_own_effects:
                why = "the KCS has this effect itself (it is part of the clean ship)"
            elif plant not in _effect(e).injection.plants:
                why = _effect(e).injection.reason_not(plant, e)
            else:
                continue
            out.setdefault(plant, {})[e] = why
    return out


def cases(cfg: DetectionPowerConfig) -> list[dict[str, Any]]:
    check(cfg)
    skip = not_studied(cfg)
    out = []
    for plant in cfg.plants:
        for rep in range(cfg.clean_seeds):
            out.append({"plant": plant, "effect": "none", "magnitude": 0.0, "replicate": rep})
        for e in _effects(cfg):
            if e in skip.get(plant, {}):
                continue
            for m in cfg.magnitudes[e]:
                for rep in range(cfg.seeds):
                    out.append({"plant": plant, "effect": e, "magnitude": float(m), "replicate": rep})
    return out


# ---------------------------------------------------------------- one case


def _runs(params: dict, seed: int, cfg: DetectionPowerConfig):
    rng = np.random.default_rng(seed)
    effect, mag = params["effect"], float(params["magnitude"])
    if cfg.runs_per_side not in (1, 2):
        raise InputError(f"detection_power.runs_per_side must be 1 or 2, got {cfg.runs_per_side}")
    # (amplitude fraction, side): training legs first, then validation legs
    legs = ([(1.0, "starboard"), (1.0, "port")] if cfg.runs_per_side == 1 else
            [(1.0, "starboard"), (0.5, "port"), (1.0, "port"), (0.5, "starboard")])
    if params["plant"] == "truth":
        from pipeline.diagnose.truth import TruthConfig, zigzag_truth
        from pipeline.model import PAPER_TABLE4

        theta = np.array(list(PAPER_TABLE4.values()))
        fa, fb = rng.uniform(0.85, 1.15, 2)
        theta[:4] *= fa
        theta[4:] *= fb
        tc = TruthConfig(theta=tuple(float(t) for t in theta), seed=int(rng.integers(1, 2**31)))
        truth_value = None
        if effect != "none":
            tc, truth_value = _truth_inject(effect, mag, tc)
        runs = [zigzag_truth(f * cfg.rudder_deg, f * cfg.rudder_deg, s, cfg.duration_s,
                             dc.replace(tc, seed=tc.seed + j)) for j, (f, s) in enumerate(legs)]
        return runs, truth_value, {"hull_factor": float(fa), "rudder_factor": float(fb)}
    import pipeline.tank as tank

    base = tank.KCSCoefficients()
    coeffs = dc.replace(base, gamma_minus=base.gamma_plus)
    tc = TankConfig(hold_speed=True, seed=int(rng.integers(1, 2**31)))
    truth_value = None
    if effect != "none":
        tc, truth_value = _tank_inject(effect, mag, tc, cfg.tank_rudder_deg)
    a = cfg.tank_rudder_deg
    runs = [tank.simulate(tank.zigzag(f * a, f * a, s, duration=cfg.duration_s), tc, coeffs=coeffs)
            for f, s in legs]
    return runs, truth_value, {}


def run_case(params: dict, seed: int, cfg: DetectionPowerConfig) -> dict[str, Any]:
    from pipeline.diagnose import diagnose

    runs, truth_value, extra = _runs(params, seed, cfg)
    dcfg = dc.replace(DiagnoseConfig(), **cfg.diagnose)
    half = len(runs) // 2
    rep = diagnose(runs[:half], runs[half:], cfg=dcfg).report
    own = set(cfg.tank_own_effects) if params["plant"] == "tank" else set()
    effect = params["effect"]
    sig = sorted(f["effect"] for f in rep["findings"] if f["significant"])
    others = [e for e in sig if e != effect and e not in own]
    out: dict[str, Any] = {
        "cause": rep["cause"],
        "significant_effects": ",".join(sig),
        "false_positive": bool(others),
        "baseline_mae_psi_deg": rep["baseline"]["validation"]["mae_psi_deg"],
        **extra,
    }
    if effect != "none":
        f = next((f for f in rep["findings"] if f["effect"] == effect), None)
        key = _effect(effect).estimate_key
        est = None
        if f is not None and f.get("estimate"):
            est = f["estimate"].get(key) if key in f["estimate"] else next(iter(f["estimate"].values()))
        out.update({
            "detected": bool(f is not None and f["significant"]),
            "named": rep["cause"] == effect,
            "validation_gain": None if f is None else f.get("validation_gain"),
            "z": None if f is None else f.get("z"),
            "estimate": None if est is None else float(est),
            "truth_value": truth_value,
            "estimate_error": None if est is None or truth_value is None else float(est) - truth_value,
        })
    return out


def warm(cfg: DetectionPowerConfig) -> None:
    """Compile the diagnosis (and tank) kernels on a worker: one small clean case per plant."""
    small = dc.replace(cfg, duration_s=20.0, diagnose={**cfg.diagnose, "max_nfev": 5, "two_fold": False})
    for plant in cfg.plants:
        try:
            run_case({"plant": plant, "effect": "none", "magnitude": 0.0, "replicate": 0}, 1, small)
        except Exception:  # noqa: BLE001 - the warm-up only compiles; a real case reports errors
            pass


# ---------------------------------------------------------------- summary


def summarise(frame: pd.DataFrame, cfg: DetectionPowerConfig, study_seed: int) -> dict[str, Any]:
    ok = frame[frame["status"] == "ok"]
    conf = cfg.confidence
    effects: dict[str, Any] = {}
    skipped = not_studied(cfg)
    for effect in _effects(cfg):
        entry: dict[str, Any] = {"magnitude_unit": _effect(effect).magnitude_unit,
                                 "min_detectable_90": {}, "detection": {}, "estimate": {}}
        for plant in cfg.plants:
            sub = ok[(ok["plant"] == plant) & (ok["effect"] == effect)]
            why = skipped.get(plant, {}).get(effect)
            if why is not None or sub.empty:
                # the contract holds min_detectable_90 for every catalogue effect: null, with the reason
                entry["min_detectable_90"][plant] = {
                    "value": None, "interval": [None, None], "method": "not studied",
                    "note": why or "no successful case",
                }
                continue
            mags = np.sort(sub["magnitude"].unique())
            rates = []
            est_rows = []
            for m in mags:
                g = sub[sub["magnitude"] == m]
                k, n = int(g["detected"].astype(bool).sum()), len(g)
                lo, hi = clopper_pearson(k, n, confidence=conf)
                named = int(g["named"].astype(bool).sum())
                # what the diagnosis named instead, when not this effect: in a zigzag the drift follows
                # the turn, so a hull effect may be carried by another (the rates stay strict)
                causes = g["cause"].value_counts()
                rates.append({"magnitude": float(m), "n": n, "detected": k, "rate": k / n,
                              "interval": [lo, hi], "named_rate": named / n,
                              "causes": {str(c): int(causes[c]) for c in sorted(causes.index)}})
                err = pd.to_numeric(g["estimate_error"], errors="coerce").dropna().to_numpy()
                tv = pd.to_numeric(g["truth_value"], errors="coerce").dropna().to_numpy()
                est_rows.append({
                    "magnitude": float(m), "n": int(err.size),
                    "truth_value_mean": float(np.mean(tv)) if tv.size else None,
                    "bias": float(np.mean(err)) if err.size else None,
                    "spread": float(np.std(err, ddof=1)) if err.size > 1 else None,
                    "relative_bias": (float(np.mean(err) / np.mean(tv))
                                      if err.size and tv.size and np.mean(tv) != 0 else None),
                })
            x = sub["magnitude"].to_numpy(float)
            y = sub["detected"].astype(bool).to_numpy()
            entry["min_detectable_90"][plant] = logistic_level(
                x, y, cfg.level, conf, cfg.bootstrap, rng_for(study_seed, f"{effect}/{plant}"))
            entry["detection"][plant] = rates
            entry["estimate"][plant] = est_rows
        effects[effect] = entry
    clean: dict[str, Any] = {"false_positive_rate": {}}
    for plant in cfg.plants:
        g = ok[(ok["plant"] == plant) & (ok["effect"] == "none")]
        if g.empty:
            continue
        k, n = int(g["false_positive"].astype(bool).sum()), len(g)
        lo, hi = clopper_pearson(k, n, confidence=conf)
        causes = g["cause"].value_counts().sort_index()
        clean["false_positive_rate"][plant] = {
            "value": k / n, "interval": [lo, hi], "false_positives": k, "n": n,
            "method": f"Clopper-Pearson {conf:.0%}",
            "counts_as_false": ("any significant effect" if plant == "truth" else
                                f"any significant effect other than the ship's own "
                                f"({', '.join(cfg.tank_own_effects)})"),
            "causes": {str(c): int(v) for c, v in causes.items()},
        }
    return {
        "definitions": {
            "detected": "the injected effect's finding is significant (docs/diagnosis.md criteria)",
            "min_detectable_90": (f"magnitude detected in {cfg.level:.0%} of cases: logistic fit of "
                                  f"detection on log magnitude; interval: {conf:.0%} percentile bootstrap "
                                  "over cases within each magnitude; null with a note when the level is "
                                  "not reached inside the magnitudes tried"),
            "false_positive_rate": "share of clean cases with a significant effect that is not there",
            "bias, spread": "mean and standard deviation of (estimate - true value) of the effect's own "
                            "parameter, in the estimate's units",
        },
        "plants": list(cfg.plants),
        "effects": effects,
        "clean": clean,
        "not_studied": not_studied(cfg),
        "virtual": "every case is simulated (linear truth model or virtual KCS tank), none is measured",
    }


# ---------------------------------------------------------------- figures and page


def render(frame: pd.DataFrame, summary: dict, out: Path) -> None:
    """power_curves.png (rate vs magnitude per effect, plant, intervals, fitted curve) and index.html."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    from pipeline.io import atomic_path

    effects = [e for e, v in summary["effects"].items() if v["detection"]]
    n = max(1, len(effects))
    cols = min(2, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(6.0 * cols, 3.8 * rows), squeeze=False)
    markers = {"truth": "o", "tank": "s"}
    for ax, effect in zip(axes.ravel(), effects, strict=False):
        entry = summary["effects"][effect]
        nplants = len(entry["detection"])
        for j, (plant, rates) in enumerate(entry["detection"].items()):
            m = np.array([r["magnitude"] for r in rates])
            p = np.array([r["rate"] for r in rates])
            lo = np.array([r["interval"][0] for r in rates])
            hi = np.array([r["interval"][1] for r in rates])
            # plants side by side at each magnitude (4 % apart on the log axis): equal rates would
            # otherwise hide one plant's markers under the other's
            dodge = 1.0 + 0.04 * (j - (nplants - 1) / 2.0)
            line = ax.errorbar(m * dodge, p, yerr=[p - lo, hi - p], fmt=markers.get(plant, "^"), capsize=3,
                               label=f"{plant} (Clopper-Pearson)")
            fit = entry["min_detectable_90"].get(plant, {})
            if fit.get("intercept") is not None:
                xx = np.geomspace(m.min() * 0.7, m.max() * 1.3, 100)
                yy = 1 / (1 + np.exp(-(fit["intercept"] + fit["slope"] * np.log(xx))))
                ax.plot(xx, yy, color=line[0].get_color(), lw=1)
            if fit.get("value") is not None:
                ax.axvline(fit["value"], color=line[0].get_color(), ls="--", lw=0.8)
            elif None not in (fit.get("interval") or [None]):
                ax.axvspan(*fit["interval"], color=line[0].get_color(), alpha=0.12, lw=0)  # 90 % inside
        ax.axhline(0.9, color="0.6", lw=0.6)
        ax.set_xscale("log")
        ticks = sorted({r["magnitude"] for rates in entry["detection"].values() for r in rates})
        ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_ylim(-0.03, 1.03)
        ax.set_xlabel(f"magnitude ({entry['magnitude_unit']})")
        ax.set_ylabel("detection rate")
        ax.set_title(effect)
        ax.legend(fontsize=7, loc="best")
    for ax in axes.ravel()[len(effects):]:
        ax.axis("off")
    fig.suptitle(f"Detection power: {summary['study']['name']} (simulated cases)")
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - 0.4 / fig.get_figheight()))  # 0.4 in for the title
    with atomic_path(out / "power_curves.png", suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110, metadata={"Software": None})
    plt.close(fig)
    with atomic_path(out / "index.html", suffix=".html") as tmp:
        tmp.write_text(_page(summary))


def _fmt(x, nd=3):
    if x is None:
        return "n/a"
    return f"{x:.{nd}g}"


def _page(summary: dict) -> str:
    e = html.escape
    st = summary["study"]
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>{e(st['name'])}: detection power</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto}"
        "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}"
        "th{background:#eee}.l{text-align:left}</style></head><body>",
        f"<h1>Detection power of the diagnosis: {e(st['name'])}</h1>",
        f"<p>{e(summary['virtual'])}. {st['cases']} cases, {st['ok']} done, {st['failed']} failed.</p>",
        "<img src='power_curves.png' alt='detection rate against magnitude' style='max-width:100%'>",
        "<h2>Smallest magnitude found in 90 % of cases</h2><table><tr><th class=l>effect</th>"
        "<th class=l>plant</th><th>min detectable</th><th>interval</th><th class=l>unit</th>"
        "<th class=l>note</th></tr>",
    ]
    for effect, entry in summary["effects"].items():
        for plant, fit in entry["min_detectable_90"].items():
            iv = fit.get("interval") or [None, None]
            parts.append(
                f"<tr><td class=l>{e(effect)}</td><td class=l>{e(plant)}</td>"
                f"<td>{_fmt(fit.get('value'))}</td>"
                f"<td>[{_fmt(iv[0])}, {_fmt(iv[1])}]</td><td class=l>{e(entry['magnitude_unit'])}</td>"
                f"<td class=l>{e(fit.get('note') or '')}</td></tr>")
    parts.append("</table><h2>Detected, and what was named, per magnitude</h2><table><tr>"
                 "<th class=l>effect</th><th class=l>plant</th><th>magnitude</th><th>detected</th>"
                 "<th class=l>cause named (cases)</th></tr>")
    for effect, entry in summary["effects"].items():
        for plant, rates in entry["detection"].items():
            for r in rates:
                named = ", ".join(f"{c} {k}" for c, k in (r.get("causes") or {}).items())
                parts.append(f"<tr><td class=l>{e(effect)}</td><td class=l>{e(plant)}</td>"
                             f"<td>{_fmt(r['magnitude'])}</td><td>{r['detected']}/{r['n']}</td>"
                             f"<td class=l>{e(named)}</td></tr>")
    parts.append("</table><h2>False positives on clean data</h2><table><tr><th class=l>plant</th>"
                 "<th>rate</th><th>interval</th><th>cases</th><th class=l>counts as false</th></tr>")
    for plant, fp in summary["clean"]["false_positive_rate"].items():
        parts.append(f"<tr><td class=l>{e(plant)}</td><td>{_fmt(fp['value'])}</td>"
                     f"<td>[{_fmt(fp['interval'][0])}, {_fmt(fp['interval'][1])}]</td><td>{fp['n']}</td>"
                     f"<td class=l>{e(fp['counts_as_false'])}</td></tr>")
    parts.append("</table><h2>Estimate against truth</h2><table><tr><th class=l>effect</th>"
                 "<th class=l>plant</th><th>magnitude</th><th>true value</th><th>bias</th><th>spread</th>"
                 "<th>n</th></tr>")
    for effect, entry in summary["effects"].items():
        for plant, rows in entry["estimate"].items():
            for r in rows:
                parts.append(f"<tr><td class=l>{e(effect)}</td><td class=l>{e(plant)}</td>"
                             f"<td>{_fmt(r['magnitude'])}</td><td>{_fmt(r['truth_value_mean'])}</td>"
                             f"<td>{_fmt(r['bias'])}</td><td>{_fmt(r['spread'])}</td><td>{r['n']}</td></tr>")
    parts.append("</table>")
    if summary["not_studied"]:
        parts.append("<h2>Not studied</h2><ul>")
        for plant, d in summary["not_studied"].items():
            for effect, why in d.items():
                parts.append(f"<li>{e(plant)} / {e(effect)}: {e(why)}</li>")
        parts.append("</ul>")
    if summary["failures"]:
        parts.append("<h2>Failed cases</h2><ul>")
        for f in summary["failures"]:
            parts.append(f"<li><code>{e(f['case_id'])}</code> {e(str(f['params']))}: "
                         f"{e(str(f['error']))}</li>")
        parts.append("</ul>")
    parts.append("</body></html>\n")
    return "\n".join(parts)


KIND = StudyKind(name="detection_power", config=DetectionPowerConfig, cases=cases, run_case=run_case,
                 summarise=summarise, render=render, warm=warm, check=check,
                 summary_only=("level", "confidence", "bootstrap"),
                 grid=("effects", "magnitudes", "plants", "seeds", "clean_seeds"))
