"""The control stage: designs from the indices, closed-loop runs over wave seeds, statistics.

Pure function :func:`run_control` takes the parsed ``indices/indices.json`` document (schema in
:mod:`pipeline.catalog`) and a :class:`pipeline.config.ControlConfig`, and returns the metrics document
and the time series frame that the command writes to ``control/metrics.json`` and
``control/timeseries.parquet``.

Designs (all with Tw = ``cfg.tw``):
* ``identified``: first-order CGSA from the identified K and T = T1 + T2 - T3 (the paper's choice);
* ``identified-2nd``: second-order CGSA from K, T1, T2, T3, made proper by the filter pole
  ``cfg.filter_tau``;
* ``graphical``: first-order CGSA from the graphical-method K and T (when the indices give it).
Plants: ``nomoto`` (the identified second-order Nomoto model, always) and ``kcs`` (the nonlinear
virtual-tank KCS, only when the runs are the built-in tank's, the indices' ``builtin_tank``
(:func:`pipeline.catalog.is_builtin_tank`), and :mod:`pipeline.tank` is present: a user's simulated
runs of another ship, provenance "virtual" too, are not the KCS).
Every (plant, design) pair is run on the same wave seeds (common random numbers), so the
identified-minus-graphical differences are paired.
"""

from __future__ import annotations

import sys
from dataclasses import asdict

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from pipeline import paper
from pipeline.config import ControlConfig
from pipeline.control.autopilot import PIDDesign, design_pid
from pipeline.control.design import (
    CGSADesign,
    bode_data,
    design_first_order,
    design_second_order,
    loop_analysis,
    nomoto_tf,
    open_loop,
    setpoint_response_tf,
)
from pipeline.control.disturbance import wave_sequence, wave_variance_theory, wind_from_config
from pipeline.control.metrics import WORST, course_metrics, seed_statistics
from pipeline.control.operating_point import operating_point
from pipeline.control.result import ControlMetrics, RefusedControl
from pipeline.control.robustness import nyquist_for
from pipeline.control.robustness import robustness as robustness_block
from pipeline.control.settings import KEYS as SETTING_KEYS
from pipeline.control.simulate import NomotoShip, kcs_available, make_kcs_ship, simulate_course
from pipeline.errors import InputError
from pipeline.progress import bar

PAPER_CONTROL = {
    **paper.CONTROL,
    "note": "Meng et al. (2024): Table 7 indices, Tw = 3 s, wind 2 deg, wave G(s); set course 0 -> 60 deg",
}


def _model(doc: dict, key: str, names: tuple[str, ...], source: str) -> dict:
    block = doc.get(key)
    if not isinstance(block, dict):
        raise InputError(f"'{key}' is missing or not an object", file=source, column=key)
    out = {"source": block.get("source")}
    for n in names:
        try:
            out[n] = float(block[n])
        except (KeyError, TypeError, ValueError):
            raise InputError(f"'{key}.{n}' is missing or not a number", file=source,
                             column=f"{key}.{n}") from None
        if not np.isfinite(out[n]):
            raise InputError(f"'{key}.{n}' is not finite", file=source, column=f"{key}.{n}")
    return out


def wave_seeds(cfg: ControlConfig) -> list[int]:
    """The wave seeds, drawn deterministically from ``cfg.seed`` (``cfg.seeds`` of them)."""
    if cfg.seeds < 1:
        raise InputError(f"ControlConfig.seeds = {cfg.seeds} must be >= 1")
    return [int(s) for s in np.random.SeedSequence(cfg.seed).generate_state(cfg.seeds)]


def build_designs(control_model: dict, graphical_model: dict | None,
                  cfg: ControlConfig) -> dict[str, CGSADesign]:
    """First-order identified (always), second-order identified (when T3 > 0, else the controller
    would be unstable: skipped), graphical (when given)."""
    cm = control_model
    if primary_name(cm) == "graphical":        # the indices stage fell back: one design, named so
        return {"graphical": design_first_order(cm["K"], cm["T"], cfg.tw, name="graphical")}
    designs = {"identified": design_first_order(cm["K"], cm["T"], cfg.tw, name="identified")}
    second_ok = (cm.get("second_order") or {}).get("ok", True)
    if cm["T3"] > 0 and second_ok:
        designs["identified-2nd"] = design_second_order(cm["K"], cm["T1"], cm["T2"], cm["T3"], cfg.tw,
                                                        cfg.filter_tau, name="identified-2nd")
    if graphical_model is not None:
        designs["graphical"] = design_first_order(graphical_model["K"], graphical_model["T"], cfg.tw,
                                                  name="graphical")
    return designs


def primary_name(control_model: dict) -> str:
    """'identified' unless the indices stage chose the graphical model (its source says so)."""
    return "graphical" if str(control_model.get("source", "")).startswith("first-order graphical") \
        else "identified"


def _identified_indices(indices: dict) -> dict | None:
    """K, T1, T2, T3, T of the SR-UKF-FFM identified indices when they make a valid second-order plant."""
    block = (indices.get("identified") or {}).get("srukf-ffm") or {}
    try:
        vals = {n: float(block[n]["value"]) for n in ("K", "T1", "T2", "T3", "T")}
    except (KeyError, TypeError, ValueError):
        return None
    ok = all(np.isfinite(v) for v in vals.values()) and vals["K"] > 0 and vals["T1"] > 0 and vals["T2"] > 0
    return vals if ok else None


def _design_model_block(choice: dict | None, control_model: dict) -> dict:
    """docs/control.md ``design_model``: the model designed from, its indices, the rule and both errors."""
    out = {"chosen": primary_name(control_model), "source": control_model.get("source"),
           "indices": {n: control_model[n] for n in ("K", "T1", "T2", "T3", "T")}}
    if choice is None:
        out.update({"rule": "the indices stage's control_model (no held-out comparison was run)"})
    else:
        out.update({k: v for k, v in choice.items() if k != "chosen"})
    return out


def _flagged_identified(indices: dict) -> dict | None:
    """K, T of the SR-UKF-FFM identified indices when usable for a comparison design (K, T > 0)."""
    block = (indices.get("identified") or {}).get("srukf-ffm") or {}
    try:
        k, t = float(block["K"]["value"]), float(block["T"]["value"])
    except (KeyError, TypeError, ValueError):
        return None
    return {"K": k, "T": t} if np.isfinite(k) and np.isfinite(t) and k > 0 and t > 0 else None


def design_basis(indices: dict) -> dict:
    """Which indices the autopilot is designed from and why (from indices.json control_model)."""
    cm = indices.get("control_model") or {}
    return {"source": cm.get("source"), "basis": cm.get("basis") or cm.get("source"),
            "flags": cm.get("flags") or [], "rejected": cm.get("rejected") or [],
            "second_order": cm.get("second_order"), "refused": bool(cm.get("refused")),
            "reason": cm.get("reason")}


def refused_document(indices: dict, cfg: ControlConfig) -> tuple[RefusedControl, pd.DataFrame]:
    """The control outputs when no index set can be trusted: no design, the reason, nothing simulated."""
    basis = design_basis(indices)
    doc = RefusedControl(
        dataset=indices.get("dataset"), provenance=indices.get("provenance", "unknown"),
        virtual=indices.get("provenance") == "virtual", builtin_tank=bool(indices.get("builtin_tank")),
        refused=True, reason=basis["reason"], design_basis=basis,
        notes=[f"autopilot not designed: {basis['reason']}"], config=asdict(cfg), designs={}, results=[],
        identification_value={}, paper=PAPER_CONTROL, plants={}, seeds=[])
    cols = ["plant", "design", "seed", "time", "psi_ref", "psi", "r", "delta_cmd", "delta", "wave", "wind"]
    ts = pd.DataFrame({c: pd.Series(dtype="object" if c in ("plant", "design") else "float64")
                       for c in cols})
    return doc, ts


def loop_flags(loop: dict, cfg: ControlConfig) -> list[dict]:
    """Control-side trust flag: a phase margin below ``cfg.min_phase_margin`` (see its comment)."""
    pm = loop.get("phase_margin_deg")
    if pm is None or not np.isfinite(pm) or pm >= cfg.min_phase_margin:
        return []
    return [{"check": "phase_margin", "subject": "loop", "value": float(pm),
             "band": [cfg.min_phase_margin, 180.0],
             "reason": f"phase margin {pm:.3g} deg below {cfg.min_phase_margin:g} deg on the Nomoto plant: "
                       "the loop rings and amplifies disturbances"}]


def design_table(designs: dict[str, CGSADesign | PIDDesign], control_model: dict, cfg: ControlConfig) -> dict:
    """Gains and loop figures of each design, on its own model and on the identified Nomoto plant."""
    cm = control_model
    plant = nomoto_tf(cm["K"], T1=cm["T1"], T2=cm["T2"], T3=cm["T3"])
    out = {}
    for name, d in designs.items():
        if isinstance(d, PIDDesign):
            out[name] = {**d.summary(), "flags": []}
            continue
        loop_plant = open_loop(d, plant)
        step_tf = setpoint_response_tf(d, plant, derivative_on="measurement")
        out[name] = {
            **d.summary(),
            "loop_design_model": loop_analysis(open_loop(d)),
            "loop_nomoto_plant": loop_analysis(loop_plant),
            "setpoint_dc_gain_nomoto": float(np.real(step_tf(0.0))) if np.isfinite(step_tf(1e-9)) else None,
            "bode_nomoto_plant": bode_data(loop_plant, n=cfg.bode_points),
        }
        out[name]["flags"] = loop_flags(out[name]["loop_nomoto_plant"], cfg)
    return out


def _identified_control_model(indices: dict, choice: dict) -> dict:
    """The identified indices as the control model, when the design-model rule chose them."""
    ind = choice["identified"]
    flags = (indices.get("identified_flags") or {}).get("srukf-ffm") or []
    second = [f for f in flags if {x.strip() for x in str(f.get("subject", "")).split(",")}
              & {"T1", "T2", "T3"}]
    ok = bool(ind.get("T2", 0) > 0 and ind.get("T3", 0) > 0 and not second)
    return {"source": "identified srukf-ffm (chosen by the design-model rule on held-out runs)",
            **{n: float(ind[n]) for n in ("K", "T1", "T2", "T3", "T")},
            "second_order": {"ok": ok, "reason": None if ok else
                             "; ".join(f.get("reason", "") for f in second) or "T2 or T3 not positive"}}


def _graphical_control_model(gm: dict) -> dict:
    return {"source": "first-order graphical model (chosen by the design-model rule on held-out runs)",
            "K": gm["K"], "T1": gm["T"], "T2": 0.0, "T3": 0.0, "T": gm["T"],
            "second_order": {"ok": False, "reason": "first-order model"}}


def plant_label(control_model: dict) -> str:
    """What the linear 'nomoto' plant is, named for what it is."""
    if control_model["T2"] == 0 and control_model["T3"] == 0:
        what = ("first-order graphical Nomoto model" if primary_name(control_model) == "graphical"
                else "first-order Nomoto model")
    else:
        what = "identified second-order Nomoto model"
    return f"{what} (the design model: {control_model.get('source')}), linear, servo angle and rate limits"


def paper_case(per: dict, plant: str, design: str, kp: float, wind: float) -> dict:
    """The paper's configuration beside its reported steady MAE, and why a PD cannot reach it."""
    rows = per.get((plant, design)) or []
    mae = np.array([r["steady_mae"] for r in rows], dtype=float)
    floor = abs(wind) / kp if kp > 0 else float("nan")
    return {
        "plant": plant, "design": design, "seeds": len(rows),
        "steady_mae_mean": float(np.mean(mae)) if mae.size else None,
        "steady_mae_std": float(np.std(mae, ddof=1)) if mae.size > 1 else None,
        "paper_steady_mae": PAPER_CONTROL["steady_mae"], "Kp": kp, "wind_rudder_deg": wind,
        "pd_steady_offset_deg": floor,
        "why": (f"a PD (no integral action) holds a constant equivalent wind rudder of {wind:g} deg only "
                f"with a steady heading error |wind|/Kp = {floor:.3g} deg (Kp = {kp:.3g} deg/deg); waves add "
                "to it, so "
                f"the paper's {PAPER_CONTROL['steady_mae']:g} deg cannot follow from its own stated set-up"),
    }


def run_control(indices: dict, cfg: ControlConfig | None = None, *, source: str = "indices.json",
                plants: tuple[str, ...] | None = None, progress: bool = True,
                design_choice: dict | None = None,
                robustness: dict | None = None) -> tuple[dict, pd.DataFrame]:
    """:func:`control_result` with the metrics in their JSON form (the content of metrics.json).

    Parameters
    ----------
    indices : dict
        The parsed indices document ("control_model" K 1/s, T1 T2 T3 T s; "provenance").
    cfg : ControlConfig, optional
        Control settings; None: the defaults.
    source : str
        File name used in error messages.
    plants : tuple of str, optional
        Which plants to run (default: 'nomoto', plus 'kcs' for virtual data).
    progress : bool
        Show a progress bar over the runs.
    design_choice, robustness : dict, optional
        As for :func:`control_result`.

    Returns
    -------
    metrics : dict
        metrics.json's content (docs/contract.md).
    series : pandas.DataFrame
        Plant, design, seed, time (s), psi_ref, psi (deg), r (deg/s), delta_cmd, delta, wave, wind (deg).
    """
    result, ts = control_result(indices, cfg, source=source, plants=plants, progress=progress,
                                design_choice=design_choice, robustness=robustness)
    return result.to_json(), ts


def control_result(indices: dict, cfg: ControlConfig | None = None, *, source: str = "indices.json",
                   plants: tuple[str, ...] | None = None, progress: bool = True,
                   design_choice: dict | None = None,
                   robustness: dict | None = None) -> tuple[ControlMetrics | RefusedControl, pd.DataFrame]:
    """Designs, simulations over seeds and statistics for one dataset.

    BLAS runs on one thread here (threadpoolctl): every matrix of the stage is at most about ten by
    ten (plant discretisations, loop responses), where a second OpenBLAS thread only spins against a
    busy core; scipy's matrix exponential of a 4 x 4 took 20 ms with two threads on the loaded 2-core
    machine and 0.03 ms with one (docs/control.md, "Speed").

    Parameters
    ----------
    indices : the parsed indices document (needs "control_model" K, T1, T2, T3, T; "graphical_model"
        K, T is optional; "provenance").
    cfg : control settings.  source : file name used in error messages.
    plants : which plants to run (default: 'nomoto', plus 'kcs' for virtual data when available).
    progress : show a tqdm bar over the runs.
    design_choice : a ``design_model`` block of :func:`pipeline.indices.design_model.choose_design_model`
        to design by instead of the indices' own (``control_model.design_model``, decided by the indices
        stage on held-out runs; without either, the indices' control_model as it is).
    robustness : extra inputs of the robustness block (:func:`pipeline.control.robustness.robustness`):
        "parameters" and "covariance" of the identified model, "linearised" K, T1, T2, T3 of the ship
        straight ahead; None: margins on the design model only.

    Returns
    -------
    ControlMetrics or RefusedControl, pandas.DataFrame
        The metrics (``to_json()`` is metrics.json) and the time series frame with plant, design,
        seed, time (s), psi_ref, psi (deg), r (deg/s), delta_cmd, delta, wave, wind (deg).
    """
    with threadpool_limits(limits=1, user_api="blas"):
        return _run_control(indices, cfg, source=source, plants=plants, progress=progress,
                            design_choice=design_choice, robustness=robustness)


def _run_control(indices: dict, cfg: ControlConfig | None, *, source: str, plants: tuple[str, ...] | None,
                 progress: bool, design_choice: dict | None,
                 robustness: dict | None) -> tuple[ControlMetrics | RefusedControl, pd.DataFrame]:
    cfg = ControlConfig() if cfg is None else cfg
    if not isinstance(indices, dict):
        raise InputError("indices document is not a JSON object", file=source)
    if (indices.get("control_model") or {}).get("refused"):
        return refused_document(indices, cfg)
    control_model = _model(indices, "control_model", ("K", "T1", "T2", "T3", "T"), source)
    control_model["second_order"] = (indices.get("control_model") or {}).get("second_order")
    graphical_model = (_model(indices, "graphical_model", ("K", "T"), source)
                       if indices.get("graphical_model") is not None else None)
    provenance = indices.get("provenance", "unknown")
    if design_choice is None:       # the one decision, made by the indices stage on held-out runs
        design_choice = (indices.get("control_model") or {}).get("design_model")
    if design_choice is not None:
        chosen = design_choice.get("chosen")
        if chosen == "identified" and design_choice.get("identified"):
            control_model = _identified_control_model(indices, design_choice)
        elif chosen == "graphical" and graphical_model is not None:
            control_model = _graphical_control_model(graphical_model)
    designs = build_designs(control_model, graphical_model, cfg)
    base = designs["graphical" if primary_name(control_model) == "graphical" else "identified"]
    lin = (robustness or {}).get("linearised") or {}
    straight = next((m for share, m in lin.items() if float(share) == 1.0), None)
    op = operating_point(control_model, indices, cfg, straight_ahead=straight)
    op_model = op["models"][op["used"]]
    designs["autopilot"] = design_pid(op_model["K"], op_model["T"], cfg.tw, rudder_max=cfg.rudder_max,
                                      zeta=cfg.pid_zeta, ki_ratio=cfg.pid_ki_ratio,
                                      ref_wn_ratio=cfg.ref_wn_ratio, ref_zeta=cfg.ref_zeta,
                                      ref_rate_share=cfg.ref_rate_share)
    notes = [f"autopilot (PID) designed from the {op['used'].replace('_', '-')} model "
             f"(K {op_model['K']:.4g} 1/s, T {op_model['T']:.4g} s): {op['why']}"]
    flagged = _flagged_identified(indices)
    if primary_name(control_model) == "graphical" and flagged is not None:
        # shown beside the autopilot for comparison (the paper's identified-vs-graphical figures),
        # never as the autopilot: its name and the note say so
        designs["identified-flagged"] = design_first_order(flagged["K"], flagged["T"], cfg.tw,
                                                           name="identified-flagged")
        why = (f"not designed from: {design_choice.get('reason')}" if design_choice is not None
               else "flagged by the indices stage")
        notes.append("identified-flagged: first-order CGSA from the SR-UKF-FFM indices "
                     f"(K = {flagged['K']:.4g} 1/s, T = {flagged['T']:.4g} s; {why}), simulated for "
                     "comparison only; it is not the autopilot")
    table = design_table(designs, control_model, cfg)

    basis = design_basis(indices)
    if design_choice is not None:
        notes.append(f"designed from: {control_model['source']}; {design_choice.get('reason')} "
                     f"(rule: {design_choice.get('rule')})")
    elif basis["basis"]:
        notes.append(f"designed from: {basis['basis']}")
    so = control_model.get("second_order") or {}
    if primary_name(control_model) != "graphical" and not so.get("ok", True):
        notes.append(f"second-order CGSA skipped: T1, T2, T3 flagged ({so.get('reason')})")
    elif primary_name(control_model) != "graphical" and "identified-2nd" not in designs:
        why = ("the control model is first order (T2 = T3 = 0)" if control_model["T2"] == 0
               else "its controller would be unstable")
        notes.append(f"T3 = {control_model['T3']:.4g} s <= 0: second-order CGSA skipped ({why})")
    if plants is None:
        plants = ("nomoto",)
        if indices.get("builtin_tank"):
            if kcs_available():
                plants = ("nomoto", "kcs")
            else:
                notes.append("virtual dataset, but pipeline.tank.KCSShip is not available: KCS plant skipped")
    elif "kcs" in plants and not kcs_available():
        raise InputError("the KCS plant was requested but pipeline.tank.KCSShip is not available")

    seeds = wave_seeds(cfg)
    wind = wind_from_config(cfg)
    n = int(round(cfg.duration / cfg.dt)) + 1
    waves = {s: (wave_sequence(n, cfg.dt, s, num=cfg.wave_num, den=cfg.wave_den) if cfg.wave else np.zeros(n))
             for s in seeds}

    # the paper's case: a CGSA from the identified K, T run on the identified (second-order) model
    ident_vals = _identified_indices(indices)
    paper_design = next((n for n in ("identified", "identified-flagged") if n in designs), None)
    paper_plant = None
    if paper_design is not None and ident_vals is not None:
        same = control_model["T2"] > 0 and all(
            abs(control_model[n] - ident_vals[n]) <= 1e-12 * abs(ident_vals[n])
            for n in ("K", "T1", "T2", "T3"))
        paper_plant = "nomoto" if same and "nomoto" in plants else "identified"
    jobs = [(p, d, s) for p in plants for d in designs for s in seeds]
    if paper_plant == "identified":
        jobs += [("identified", paper_design, s) for s in seeds]

    def make_ship(plant):
        if plant == "kcs":
            return make_kcs_ship(cfg.rudder_max, cfg.rudder_rate, dead_time=cfg.dead_time,
                                 servo_time_constant=cfg.servo_time_constant)
        m = control_model if plant == "nomoto" else ident_vals
        return NomotoShip(m["K"], m["T1"], m["T2"], m["T3"], rudder_max=cfg.rudder_max,
                          rudder_rate=cfg.rudder_rate, servo_time_constant=cfg.servo_time_constant,
                          dead_time=cfg.dead_time)

    frames, per = [], {}
    for plant, dname, seed in bar(jobs, desc="control", unit="run", progress=progress):
        ship = make_ship(plant)
        fr = simulate_course(designs[dname], ship, setpoint=cfg.setpoint, duration=cfg.duration, dt=cfg.dt,
                             rudder_max=cfg.rudder_max, wind=wind, wave=waves[seed])
        m = course_metrics(fr["time"], fr["psi"], fr["delta"], cfg.setpoint, band=cfg.settle_band,
                           steady_start=cfg.steady_start, reversal_threshold=cfg.reversal_threshold)
        m["max_rate"] = float(np.max(np.abs(np.diff(fr["delta"].to_numpy(), prepend=0.0))) / cfg.dt)
        per.setdefault((plant, dname), []).append({"seed": seed, **m})
        fr.insert(0, "seed", seed)
        fr.insert(0, "design", dname)
        fr.insert(0, "plant", plant)
        frames.append(fr)

    results = []
    for (plant, dname), rows in per.items():
        stats = seed_statistics([{k: v for k, v in r.items() if k != "seed"} for r in rows])
        results.append({"plant": plant, "design": dname, "seeds": len(rows), "stats": stats,
                        "per_seed": rows})

    value = {}
    ident_name = next((n for n in ("identified", "identified-flagged") if n in designs), None)
    if ident_name and "graphical" in designs:
        for plant in plants:
            a = {r["seed"]: r for r in per[(plant, ident_name)]}
            b = {r["seed"]: r for r in per[(plant, "graphical")]}
            diff = {}
            for name in WORST:
                d = np.array([a[s][name] - b[s][name] for s in seeds], dtype=float)
                d = d[np.isfinite(d)]
                diff[name] = {"mean": float(np.mean(d)) if d.size else float("nan"),
                              "std": float(np.std(d, ddof=1)) if d.size > 1 else 0.0}
            value[plant] = {"difference": f"{ident_name} minus graphical, paired over seeds", "metrics": diff}

    doc = dict(
        dataset=indices.get("dataset"),
        provenance=provenance,
        virtual=provenance == "virtual",
        builtin_tank=bool(indices.get("builtin_tank")),
        plants={
            "nomoto": {"used": "nomoto" in plants, "description": plant_label(control_model)},
            "identified": {"used": paper_plant == "identified",
                           "description": "identified second-order Nomoto model (SR-UKF-FFM, Eq. 6), linear, "
                                          "servo angle and rate limits: the plant of the paper's case"},
            "kcs": {"used": "kcs" in plants,
                    "description": "nonlinear 3-DOF MMG KCS of the virtual tank (pipeline.tank.KCSShip); "
                                   "used only for virtual-tank data"},
        },
        notes=notes,
        design_basis=basis,
        config=asdict(cfg),
        wind_rudder_deg=wind,
        wave_variance_theory_deg2=wave_variance_theory(num=cfg.wave_num, den=cfg.wave_den),
        seeds=seeds,
        models={"control_model": control_model, "graphical_model": graphical_model},
        definitions={
            "rise_time": f"first time |psi - set| <= {cfg.settle_band:g} x step (s)",
            "rise_time_10_90": "10 % to 90 % of the step (s)",
            "reach_time": "first time psi reaches the set course (s)",
            "max_deviation": "max |psi - set| after the set course is first reached (from the rise time "
                             "when never reached) (deg)",
            "steady_mae": f"mean |psi - set| for t >= {cfg.steady_start:g} s (deg)",
            "max_rudder": "max |delta| over the run (deg)",
            "steady_rudder_min/max, mean_rudder": f"actual rudder for t >= {cfg.steady_start:g} s (deg)",
            "rudder_energy": "integral of delta^2 dt in the steady window (deg^2 s)",
            "rudder_reversals": ("direction reversals in the steady window, swings >= "
                                 f"{cfg.reversal_threshold:g} deg"),
            "max_rate": "largest rudder rate over the run (deg/s)",
            "worst": WORST,
            "gain_margin": "absolute; null in JSON means infinite (the phase never reaches -180 deg)",
            "bandwidth": "half-power (-3.01 dB) frequency of the complementary sensitivity (rad/s)",
            "Ms": "max |1/(1 + L(j w))| on 1e-4..1e3 rad/s",
        },
        designs=table,
        results=results,
        identification_value=value,
        paper=PAPER_CONTROL,
        paper_case=(paper_case(per, paper_plant, paper_design, designs[paper_design].Kp, wind)
                    if paper_plant else None),
        design_model=_design_model_block(design_choice, control_model),
        settings={k: getattr(cfg, f) for k, (f, _, _) in SETTING_KEYS.items()},
        operating_point=op,
    )
    rob = robustness_block(designs, control_model, cfg, robustness or {})
    for name, row in rob.pop("designs").items():     # docs/control.md: the margins belong to each design
        doc["designs"][name]["sampled_loop"] = row
    doc["robustness"] = rob
    extra = robustness or {}
    if cfg.adaptive and "kcs" in plants and extra.get("parameters") is not None and \
            extra.get("covariance") is not None:
        from pipeline.control.adaptive import adaptive_block

        doc["adaptive"], secs = adaptive_block(extra["parameters"], extra["covariance"], base.K, base.T,
                                               seeds[:cfg.adaptive_seeds], cfg, q_std=extra.get("q_std"),
                                               pid_start=(op_model["K"], op_model["T"]))
        print(f"control: adaptive in-loop run, {len(seeds[:cfg.adaptive_seeds])} seeds x 2; streaming "
              f"identification {secs:.2f} s", file=sys.stderr)
    doc["robustness"]["nyquist"] = nyquist_for(designs, control_model, cfg, n=cfg.bode_points)
    ts = pd.concat(frames, ignore_index=True)
    return ControlMetrics(**doc), ts
