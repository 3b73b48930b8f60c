"""The indices stage as pure functions: runs + estimates in, the three output documents out.

Files (pipeline/catalog.py): ``indices/indices.json``, ``indices/zigzag.json``, ``indices/table7.csv``.
Documented choices:

* a run whose analysis fails (e.g. a zigzag too short for two extrema) is kept in zigzag.json with
  an ``"error"`` line instead of stopping the stage; only the identification run must be analysable
  (its standard-method K and T are the ``graphical_model``);
* ``identified`` holds Eq. 6 at the estimate with one-sigma bounds (``uncertainty_method`` says
  how); ``uncertainty_check`` adds a seeded Monte Carlo of N(estimate, covariance): the fraction of
  draws with no real positive time constants and the 16/50/84 % percentiles of each index.  When
  that fraction is not small the Gaussian bounds are local only (the indices are ratios of
  parameters and become heavy-tailed), and the percentiles are the honest spread;
* ``control_model`` is the one design-model decision (``design_model`` in it): the identified model
  (SR-UKF-FFM, else FFM-UKF when SR-UKF-FFM has no real positive time constants) unless it loses to the
  first-order graphical model (T1 = T, T2 = T3 = 0) on the held-out runs
  (pipeline/indices/design_model.py); without held-out runs the trust flags decide; ``source`` always
  says which.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pipeline import paper
from pipeline.catalog import is_builtin_tank
from pipeline.config import ControlConfig, IndicesConfig
from pipeline.errors import InputError, PipelineError
from pipeline.indices import trust
from pipeline.indices.design_model import choose_design_model
from pipeline.indices.imo import imo_check
from pipeline.indices.nomoto_kt import graphical_kt, integral_kt
from pipeline.indices.result import (
    AmplitudeMean,
    ControlModel,
    GraphicalModel,
    IndexValue,
    IndicesDocument,
    KTRow,
    Nondimensional,
    RunMetrics,
    UncertaintyCheck,
    ZigzagDocument,
)
from pipeline.indices.turning import turning_metrics
from pipeline.indices.uncertainty import draw_validity, monte_carlo, propagate
from pipeline.indices.zigzag import zigzag_metrics
from pipeline.io import Run
from pipeline.model import INDEX_NAMES
from pipeline.progress import bar
from pipeline.runinfo import choose_runs, parse_test_name

UNITS = {"K": "1/s", "T1": "s", "T2": "s", "T3": "s", "T": "s", "K_prime": "-", "T_prime": "-",
         "T1_prime": "-", "T2_prime": "-", "T3_prime": "-"}
NONDIMENSIONAL_DEFINITION = ("K' = K Lpp/U, T' = T U/Lpp (Lpp model m, U approach speed m/s of the run the "
                             "indices come from)")
PAPER = {"table4": paper.TABLE4, "table7": paper.TABLE7, "graphical": paper.GRAPHICAL,
         "reference": f"{paper.REFERENCE}, Tables 4 and 7",
         "units": "K 1/s (deg/s per deg), T1 T2 T3 T s"}


def run_kind(run: Run) -> str:
    """The kind of manoeuvre a run is: its metadata's "kind", else read from its test name.

    Parameters
    ----------
    run : Run
        The run (``meta["kind"]`` or ``meta["test_name"]``).

    Returns
    -------
    str
        'zigzag', 'turning' or another kind :func:`pipeline.runinfo.parse_test_name` names.
    """
    kind = run.meta.get("kind")
    if kind:
        return str(kind)
    return parse_test_name(str(run.meta.get("test_name", "")))["kind"]


def analyse_run(run: Run, *, config: IndicesConfig | None = None) -> dict[str, Any]:
    """Zigzag or turning metrics, the IMO check and (zigzags) K, T by both methods for one run.

    Parameters
    ----------
    run : Run
        One run (units of docs/contract.md#run-data).
    config : IndicesConfig, optional
        The analysis settings.

    Returns
    -------
    dict
        {"run_id", "test_name", "kind", "metrics", "imo", "kt": {"standard", "integral"} (K 1/s,
        T s), "errors": [...], "nominal_rudder_deg", "nominal_heading_deg"}; ``errors`` lists what
        could not be computed and why.
    """
    cfg = config or IndicesConfig()
    kind = run_kind(run)
    out: dict[str, Any] = {"run_id": run.name, "test_name": run.meta.get("test_name"), "kind": kind,
                           "metrics": None, "imo": None, "kt": {}, "errors": [],
                           "nominal_rudder_deg": run.meta.get("rudder_deg"),
                           "nominal_heading_deg": run.meta.get("heading_deg")}
    try:
        if kind == "zigzag":
            out["metrics"] = zigzag_metrics(run, config=cfg)
        elif kind == "turning":
            out["metrics"] = turning_metrics(run, config=cfg)
        else:
            out["errors"].append(f"kind {kind!r}: neither zigzag nor turning circle, not analysed")
            return out
    except PipelineError as exc:
        out["errors"].append(f"{kind} analysis: {exc}")
        return out
    meta = dict(run.meta)
    out["imo"] = imo_check(kind, out["metrics"], meta, config=cfg)
    if kind == "zigzag":
        for name, fn in (("standard", lambda: graphical_kt(run, config=cfg, zigzag=out["metrics"])),
                         ("integral", lambda: integral_kt(run, config=cfg))):
            try:
                out["kt"][name] = fn()
            except PipelineError as exc:
                out["errors"].append(f"{name} K-T method: {exc}")
    return out


def identified(estimates: dict[str, Any], *, config: IndicesConfig | None = None) -> dict[str, Any]:
    """Indices with uncertainty from one estimates.json document (docs/indices.md).

    Parameters
    ----------
    estimates : dict
        An estimates.json document: "parameters" (a11 a12 a21 a22 in 1/s, b11 b21 in 1/s^2 as in
        docs/contract.md) and optionally "covariance" (6 x 6, the parameters' units squared).
    config : IndicesConfig, optional
        Propagation method, Monte Carlo samples and seed.

    Returns
    -------
    dict
        "indices": index name -> {"value", "std"} (K 1/s, T1 T2 T3 T s, std one sigma or None);
        "method": the propagation used; "check": the :class:`UncertaintyCheck` (None without a
        covariance).
    """
    cfg = config or IndicesConfig()
    if "parameters" not in estimates:
        raise InputError("estimates have no 'parameters'")
    cov = estimates.get("covariance")
    vals, used = propagate(estimates["parameters"], cov, method=cfg.uncertainty)
    check = None
    if cov is not None:
        mc = monte_carlo(estimates["parameters"], cov, samples=cfg.mc_samples, seed=cfg.seed)
        valid = draw_validity(estimates["parameters"], cov, samples=cfg.mc_samples, seed=cfg.seed)
        # the same draws: draw_validity gives the share of invalid ones and its causes
        check = UncertaintyCheck(
            samples=cfg.mc_samples, seed=cfg.seed, invalid_fraction=valid["invalid_fraction"],
            invalid_fraction_first_order=valid["invalid_fraction_first_order"],
            invalid_causes=valid["invalid_causes"],
            percentiles={n: (mc[n]["p16"], mc[n]["p50"], mc[n]["p84"]) for n in INDEX_NAMES})
    return {"indices": vals, "method": used, "check": check}


def _usable_identified(ident_out: dict[str, Any], ident_flags: dict[str, list],
                       estimates: dict[str, dict]) -> str | None:
    """The first algorithm (SR-UKF-FFM, then FFM-UKF) whose model can be designed from at all: indices
    defined, K, T > 0 and no sign flag on them (the consistency flags judge its uncertainty, not this)."""
    for alg in ("srukf-ffm", "ffm-ukf"):
        vals = ident_out.get(alg)
        if vals is None or not (estimates.get(alg) or {}).get("parameters"):
            continue
        k, t = vals["K"]["value"], vals["T"]["value"]
        signs = [f for f in ident_flags.get(alg, [])
                 if f.get("check") in ("sign", "nomoto_K", "nomoto_indices")]
        if k is not None and t is not None and k > 0 and t > 0 and not signs:
            return alg
    return None


def heldout_control_model(ident_out: dict[str, Any], *, ident_flags: dict[str, list],
                          failures: dict[str, str], graphical_model: dict[str, Any],
                          estimates: dict[str, dict], ident: str, lpp: float | None, u: float | None,
                          heldout: list[Run], rule: ControlConfig | None = None) -> ControlModel | None:
    """The control model chosen by the held-out rule (pipeline/indices/design_model.py), or None when
    neither candidate can be designed from (the caller then refuses, saying why).

    Candidates: the identified model of :func:`_usable_identified` and the first-order graphical model
    unless its own K, T are flagged (sign, ill-conditioned).  With both, the rule decides on the
    ``heldout`` runs; with one, it is taken and its held-out error still shown.  K 1/s, T s.
    """
    rule = rule or ControlConfig()
    alg = _usable_identified(ident_out, ident_flags, estimates)
    unusable = {a: failures[a] for a in ("srukf-ffm", "ffm-ukf") if a in failures and a != alg}
    gm = graphical_model
    g_block = trust.blocking(gm.get("flags", []), ("K", "T"))
    identified = None
    if alg is not None:
        identified = {"parameters": estimates[alg]["parameters"],
                      "indices": {n: ident_out[alg][n]["value"] for n in INDEX_NAMES}}
    if identified is None and g_block:
        return None
    choice = choose_design_model(identified, {"K": gm["K"], "T": gm["T"]}, heldout, rule)
    if g_block and identified is not None and choice["chosen"] != "identified":
        choice["chosen"] = "identified"
        choice["reason"] += "; but the graphical K, T are flagged (" + trust.reasons(g_block) + \
            "), so the identified model"
    if alg is not None:
        choice["algorithm"] = alg
    rejected = [{"candidate": f"identified {a}", "reasons": ident_flags_or_failure}
                for a, ident_flags_or_failure in unusable.items()]
    if choice["chosen"] == "identified":
        est_run = estimates[alg].get("run_id", ident)
        vals = {n: ident_out[alg][n]["value"] for n in INDEX_NAMES}
        second = trust.blocking(ident_flags.get(alg, []), ("T1", "T2", "T3"))
        second = [f for f in second if f.get("subject") != "filter"]   # the filter's own flags: reported
        rejected.append({"candidate": "graphical (standard method)", "reasons": choice["reason"]})
        return ControlModel(
            source=f"identified {alg}, Eq. 6 on run {est_run} (chosen by the design-model rule on held-out "
                   "runs)", indices=vals, primes=trust.primes(vals, lpp, u),
            basis=f"{choice['reason']} (rule: {choice['rule']})", rejected=tuple(rejected),
            flags=tuple(ident_flags.get(alg, [])),
            second_order={"ok": not second and vals["T2"] > 0 and vals["T3"] > 0,
                          "reason": trust.reasons(second) if second else
                          (None if vals["T2"] > 0 and vals["T3"] > 0 else "T2 or T3 not positive")},
            design_model=choice)
    vals = {"K": gm["K"], "T1": gm["T"], "T2": 0.0, "T3": 0.0, "T": gm["T"]}
    if alg is not None:
        rejected.append({"candidate": f"identified {alg}", "reasons": choice["reason"]})
    return ControlModel(
        source=f"first-order graphical model, standard method on run {gm.get('run_id')} (chosen by the "
               "design-model rule on held-out runs)",
        indices=vals, primes=trust.primes(vals, lpp, u),
        basis=f"{choice['reason']} (rule: {choice['rule']})", rejected=tuple(rejected),
        flags=tuple(gm.get("flags", [])), second_order={"ok": False, "reason": "first-order model"},
        design_model=choice)


def control_model(ident_out: dict[str, Any], *, ident_flags: dict[str, list], failures: dict[str, str],
                  graphical_model: dict[str, Any], estimates: dict[str, dict], ident: str,
                  lpp: float | None, u: float | None, heldout: list[Run] | None = None,
                  rule: ControlConfig | None = None) -> ControlModel:
    """The indices the autopilot is designed from, and why (never a flagged set without saying so).

    With ``heldout`` runs (the zigzags the validate stage holds out) the held-out rule decides
    (:func:`heldout_control_model`, the one decision the control stage and both reports read).
    Without them, candidates in order: SR-UKF-FFM identified, FFM-UKF identified, the first-order
    graphical model.  The first whose K and T (what the first-order CGSA design uses) carry no blocking flag
    (:func:`pipeline.indices.trust.blocking`) is taken; ``basis`` says which and why the others were
    not.  ``second_order`` says whether T1, T2, T3 are trustworthy enough for the second-order design.
    When every candidate is flagged the model is ``refused`` with the reasons, and the control
    stage designs nothing from it.

    Parameters
    ----------
    ident_out : dict
        Algorithm -> index name -> {"value", "std"} (K 1/s, T1 T2 T3 T s).
    ident_flags : dict
        Algorithm -> its trust flags.
    failures : dict
        Algorithm -> why its indices could not be computed.
    graphical_model : dict
        The standard-method K (1/s), T (s) with "run_id" and "flags".
    estimates : dict
        Algorithm -> its estimates.json document (for the run it was identified on).
    ident : str
        The identification run's id (when an estimate names none).
    lpp, u : float or None
        Length between perpendiculars (m) and approach speed (m/s) for K', T' (None: not computed).
    heldout : list of Run, optional
        The held-out runs the design-model rule judges on (none: the trust flags decide).
    rule : ControlConfig, optional
        The rule's thresholds (``design_rule_rel``, ``design_rule_abs_deg``).

    Returns
    -------
    ControlModel
        The chosen indices (K 1/s, T1 T2 T3 T s), their primed values and the reasons.
    """
    if heldout:
        got = heldout_control_model(ident_out, ident_flags=ident_flags, failures=failures,
                                    graphical_model=graphical_model,
                                    estimates=estimates, ident=ident, lpp=lpp, u=u, heldout=heldout,
                                    rule=rule)
        if got is not None:
            return got
    rejected = []
    for alg in ("srukf-ffm", "ffm-ukf"):
        if alg not in ident_out:
            if alg in failures:
                rejected.append({"candidate": f"identified {alg}", "reasons": failures[alg]})
            continue
        block = trust.blocking(ident_flags.get(alg, []), ("K", "T"))
        if block:
            rejected.append({"candidate": f"identified {alg}", "reasons": trust.reasons(block)})
            continue
        est_run = estimates[alg].get("run_id", ident)
        vals = {n: ident_out[alg][n]["value"] for n in INDEX_NAMES}
        second = trust.blocking(ident_flags.get(alg, []), ("T1", "T2", "T3"))
        basis = f"identified {alg} indices (Eq. 6 on run {est_run}): K and T carry no flag"
        if rejected:
            basis += "; not used: " + "; ".join(f"{r['candidate']} ({r['reasons']})" for r in rejected)
        return ControlModel(
            source=f"identified {alg}, Eq. 6 on run {est_run}", indices=vals,
            primes=trust.primes(vals, lpp, u), basis=basis, rejected=tuple(rejected),
            flags=tuple(ident_flags.get(alg, [])),
            second_order={"ok": not second, "reason": trust.reasons(second) if second else None})
    gm = graphical_model
    block = trust.blocking(gm.get("flags", []), ("K", "T"))
    vals = {"K": gm["K"], "T1": gm["T"], "T2": 0.0, "T3": 0.0, "T": gm["T"]}
    if not block:
        basis = (f"first-order graphical model (standard method on run {gm.get('run_id')}), because "
                 + "; ".join(f"{r['candidate']} is not usable: {r['reasons']}" for r in rejected))
        return ControlModel(
            source=f"first-order graphical model, standard method on run {gm.get('run_id')} "
                   "(identified indices flagged, see basis)",
            indices=vals, primes=trust.primes(vals, lpp, u), basis=basis, rejected=tuple(rejected),
            flags=tuple(gm.get("flags", [])), second_order={"ok": False, "reason": "first-order model"})
    rejected.append({"candidate": "graphical (standard method)", "reasons": trust.reasons(block)})
    reason = "no trustworthy indices to design an autopilot from: " + "; ".join(
        f"{r['candidate']}: {r['reasons']}" for r in rejected)
    best = next((a for a in ("srukf-ffm", "ffm-ukf") if a in ident_out), None)
    shown = {n: ident_out[best][n]["value"] for n in INDEX_NAMES} if best else vals
    return ControlModel(source="refused", refused=True, reason=reason, indices=shown, primes={},
                        basis=reason, rejected=tuple(rejected), flags=(),
                        second_order={"ok": False, "reason": "refused"})


def choose_control_model(ident_out: dict[str, Any], *, ident_flags: dict[str, list], failures: dict[str, str],
                         graphical_model: dict[str, Any], estimates: dict[str, dict], ident: str,
                         lpp: float | None, u: float | None) -> dict[str, Any]:
    """The ``control_model`` entry of indices.json: :func:`control_model` in its JSON form.

    Parameters
    ----------
    ident_out, ident_flags, failures, graphical_model, estimates, ident, lpp, u
        As :func:`control_model` (``lpp`` m, ``u`` m/s).

    Returns
    -------
    dict
        ``control_model(...).to_json()`` (K 1/s, T1 T2 T3 T s).
    """
    return control_model(ident_out, ident_flags=ident_flags, failures=failures,
                         graphical_model=graphical_model, estimates=estimates, ident=ident, lpp=lpp,
                         u=u).to_json()


def _amplitude_label(res: dict[str, Any]) -> str:
    """'20/20' from the nominal test (metadata), else from the measured rudder and trigger."""
    m = res["metrics"] or {}
    rud = res.get("nominal_rudder_deg") or m.get("rudder_deg")
    head = res.get("nominal_heading_deg") or m.get("heading_deg")
    return f"{round(rud):g}/{round(head):g}" if rud and head else "?"


def build(index: dict[str, Any], runs: dict[str, Run], estimates: dict[str, dict[str, Any]],
          config: IndicesConfig | None = None, *, identification: str | None = None,
          progress: bool = True) -> tuple[dict, dict, pd.DataFrame]:
    """The indices stage's three outputs in their file form (:func:`build_documents`, as JSON-ready dicts).

    Parameters
    ----------
    index, runs, estimates, config, identification, progress
        As for :func:`build_documents`: runs/index.json, the runs by id (units of
        docs/contract.md#run-data), the estimates.json documents by algorithm, the settings, the
        identification run's id and the progress bar.

    Returns
    -------
    indices : dict
        indices.json's content (K 1/s, T1 T2 T3 T s).
    zigzag : dict
        zigzag.json's content (overshoots deg, times s).
    table7 : pandas.DataFrame
        Table 7, one row an index.
    """
    ind, zz, table = build_documents(index, runs, estimates, config, identification=identification,
                                     progress=progress)
    return ind.to_json(), zz.to_json(), table


def build_documents(index: dict[str, Any], runs: dict[str, Run], estimates: dict[str, dict[str, Any]],
                    config: IndicesConfig | None = None, *, identification: str | None = None,
                    progress: bool = True) -> tuple[IndicesDocument, ZigzagDocument, pd.DataFrame]:
    """Compute the indices stage's results for one dataset.

    Parameters
    ----------
    index : dict
        runs/index.json (its "runs" entries, "dataset", "provenance").
    runs : dict
        run_id -> Run (units of docs/contract.md#run-data).
    estimates : dict
        Algorithm -> its estimates.json document ("srukf-ffm" required).
    config : IndicesConfig, optional
        Uncertainty propagation, Monte Carlo, K-T method and trust settings.
    identification : str, optional
        The identification run's id (default: the run srukf-ffm was identified on).
    progress : bool
        Show a progress bar over the runs.

    Returns
    -------
    IndicesDocument, ZigzagDocument, pandas.DataFrame
        indices.json, zigzag.json and Table 7 (one row an index: K 1/s, T1 T2 T3 T s).
    """
    cfg = config or IndicesConfig()
    entries = index.get("runs", [])
    if identification is None:
        # the run the filter was run on (estimates.json's run_id, as the validate stage reads it), so
        # that a dataset.toml's [roles] identify or identify --run-id is honoured here too
        identification = (estimates.get("srukf-ffm") or {}).get("run_id")
    try:
        ident, _ = choose_runs(entries, identification)
    except ValueError as exc:
        raise InputError(str(exc), file="runs/index.json") from None
    results = []
    for e in bar(entries, desc="indices: runs", progress=progress, leave=False):
        run = runs[e["run_id"]]
        for k, v in e.items():
            run.meta.setdefault(k, v)
        results.append(analyse_run(run, config=cfg))
    by_id = {r["run_id"]: r for r in results}

    ident_res = by_id.get(ident)
    if ident_res is None:
        raise InputError(f"identification run {ident}: not among the runs", file="runs/index.json")
    # the graphical reference: the identification run's own standard-method K, T; where that run is
    # no zigzag (a turning circle named in [roles] identify), the zigzag the default rule picks
    graph_id, graph_res, source = ident, ident_res, f"identification run {ident}"
    if "standard" not in ident_res["kt"] and ident_res["kind"] != "zigzag":
        try:
            graph_id, _ = choose_runs(entries, None)
        except ValueError:
            raise InputError(
                f"identification run {ident} is a {ident_res['kind']} run and the dataset has no zigzag: "
                "the graphical (Nomoto standard-method) K, T the indices are compared with, and the "
                "control stage designs on, need one", file="runs/index.json") from None
        graph_res = by_id[graph_id]
        source = f"zigzag {graph_id} (the identification run {ident} is a {ident_res['kind']} run)"
    if "standard" not in graph_res["kt"]:
        why = "; ".join(graph_res["errors"]) or "no standard-method result"
        raise InputError(f"run {graph_id}: standard-method K, T unavailable ({why})")
    gm = graph_res["kt"]["standard"]
    graphical_model = {"source": f"standard (graphical) method on {source}",
                       "run_id": graph_id, "K": gm["K"], "T": gm["T"]}

    ident_out: dict[str, Any] = {}
    methods: dict[str, str] = {}
    failures: dict[str, str] = {}
    checks: dict[str, Any] = {}
    ident_flags: dict[str, list] = {}
    nondim: dict[str, Any] = {}
    entry_by_id = {e["run_id"]: e for e in entries}
    for alg, est in estimates.items():
        try:
            got = identified(est, config=cfg)
        except PipelineError as exc:
            failures[alg] = str(exc)
            continue
        vals = got["indices"]
        rid = est.get("run_id", ident)
        lpp, u, why = trust.length_and_speed(entry_by_id.get(rid, {}), index)
        pv = trust.primes({n: vals[n]["value"] for n in INDEX_NAMES}, lpp, u)
        ps = trust.primes({n: vals[n]["std"] for n in INDEX_NAMES}, lpp, u)
        for n in INDEX_NAMES:
            key = trust.PRIME[n]
            vals[key] = {"value": pv[key], "std": None if ps[key] is None else abs(ps[key])}
        ident_out[alg] = vals
        methods[alg] = got["method"]
        checks[alg] = got["check"]
        check_doc = None if got["check"] is None else got["check"].to_json()
        ident_flags[alg] = trust.identified_flags({n: vals[n] for n in INDEX_NAMES}, check_doc, est, cfg) \
            + trust.prime_flags(why)
        nondim[alg] = Nondimensional(run_id=rid, lpp_m=lpp, approach_speed_m_s=u)

    period = {r["run_id"]: (r["metrics"] or {}).get("period_s") for r in results}
    lpp_g, u_g, why_g = trust.length_and_speed(entry_by_id.get(graph_id, {}), index)
    gm_flags = trust.graphical_flags(gm, period.get(graph_id)) + trust.prime_flags(why_g)
    graphical_model = GraphicalModel(
        source=graphical_model["source"], run_id=graph_id, K=gm["K"], T=gm["T"],
        primes=trust.primes({"K": gm["K"], "T": gm["T"]}, lpp_g, u_g), flags=tuple(gm_flags))
    lpp_i, u_i, _ = trust.length_and_speed(entry_by_id.get(ident, {}), index)
    _, held_ids = choose_runs(entries, ident)
    heldout = []
    for rid in held_ids:          # the validate stage's held-out runs (pipeline/runinfo.py)
        if rid in runs:
            run = runs[rid]
            run.meta["run_id"] = rid
            heldout.append(run)
    chosen = control_model(ident_out, ident_flags=ident_flags, failures=failures,
                           graphical_model=graphical_model.to_json(), estimates=estimates, ident=ident,
                           lpp=lpp_i, u=u_i, heldout=heldout)

    graphical: list[KTRow] = []
    for r in results:
        for meth in ("standard", "integral"):
            kt = r["kt"].get(meth)
            if kt is None:
                continue
            lpp, u, why = trust.length_and_speed(entry_by_id.get(r["run_id"], {}), index)
            primes = trust.primes({"K": kt["K"], "T": kt["T"]}, lpp, u)
            flags = trust.graphical_flags({"K": kt["K"], "T": kt["T"], **primes}, period.get(r["run_id"]))
            extra = {}
            if meth == "integral":
                extra = {"K_std": kt["K_std"], "T_std": kt["T_std"],
                         "rudder_offset_deg": kt["rudder_offset_deg"]}
                flags += trust.integral_uncertainty_flags({"K": kt["K"], "T": kt["T"], **extra}, cfg)
            graphical.append(KTRow(run_id=r["run_id"], method=meth, K=kt["K"], T=kt["T"],
                                   test=_amplitude_label(r), test_name=r["test_name"],
                                   first_side=(r["metrics"] or {}).get("first_side"), primes=primes,
                                   flags=tuple(flags + trust.prime_flags(why)), **extra))
    by_amp: dict[str, dict[str, Any]] = {}
    for g in graphical:
        d = by_amp.setdefault(g.test, {}).setdefault(g.method, {"K": [], "T": []})
        d["K"].append(g.K)
        d["T"].append(g.T)
    amp_summary = {a: {m: AmplitudeMean(K_mean=float(np.mean(v["K"])), T_mean=float(np.mean(v["T"])),
                                        runs=len(v["K"])) for m, v in d.items()} for a, d in by_amp.items()}

    prov = index.get("provenance")
    indices_doc = IndicesDocument(
        dataset=index.get("dataset"), provenance=prov, builtin_tank=is_builtin_tank(index),
        identification_run=ident,
        identified={a: {n: IndexValue(**v) for n, v in d.items()} for a, d in ident_out.items()},
        identified_flags={a: tuple(f) for a, f in ident_flags.items()}, nondimensional=nondim,
        uncertainty_method=methods, uncertainty_check=checks, identified_failures=failures,
        graphical=tuple(graphical), graphical_by_amplitude=amp_summary,
        control_model=chosen, graphical_model=graphical_model, paper=PAPER, units=UNITS,
        nondimensional_definition=NONDIMENSIONAL_DEFINITION)
    zig_doc = ZigzagDocument(
        dataset=index.get("dataset"), provenance=prov,
        runs=tuple(RunMetrics(run_id=r["run_id"], test_name=r["test_name"], kind=r["kind"],
                              metrics=r["metrics"], imo=r["imo"], errors=tuple(r["errors"]))
                   for r in results))

    ident_kt = graph_res["kt"]
    rows = []
    for n in INDEX_NAMES:
        row = {"index": n}
        for alg in cfg.algorithms:
            v = ident_out.get(alg, {}).get(n)
            row[alg] = v["value"] if v else None
            row[f"{alg}_std"] = v["std"] if v else None
        for meth in ("standard", "integral"):
            row[f"graphical_{meth}"] = ident_kt[meth][n] if (meth in ident_kt and n in ("K", "T")) else None
        row["paper_identified"] = paper.TABLE7[n]
        row["paper_graphical"] = paper.GRAPHICAL.get(n)
        rows.append(row)
    return indices_doc, zig_doc, pd.DataFrame(rows)


def resolve_run_path(runs_dir: Path, entry: dict[str, Any]) -> Path:
    """Where a runs/index.json entry's Parquet file is.

    Parameters
    ----------
    runs_dir : Path
        The dataset's runs/ folder.
    entry : dict
        One entry of runs/index.json ("file" as written, else "run_id").

    Returns
    -------
    Path
        The file named by the entry (as given, under ``runs_dir``, or by its name there), else
        ``<runs_dir>/<run_id>.parquet``.
    """
    f = entry.get("file")
    if f:
        p = Path(f)
        for cand in (p, runs_dir / p, runs_dir / p.name):
            if cand.is_file():
                return cand
    return runs_dir / f"{entry['run_id']}.parquet"
