"""Non-dimensional indices and trust flags (docs/indices.md#trust-flags).

The scale test runs the real stages twice on the same virtual-tank runs: once as model-scale files,
once Froude-scaled to full scale (a truth not written with the indices' own formulas: the raw files
differ in every number) and ingested with ``--scale``.  The flag tests use the numbers the issue
measured (T1 = 27 +- 51 s, 39 % invalid draws, mean NIS 18 and 0.12, a graphical K = 8 1/s with
T = 578 s, K < 0) and check that the autopilot never uses a flagged set without saying so.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from pipeline.cli import main
from pipeline.config import ControlConfig, IndicesConfig, TankConfig
from pipeline.control.stage import run_control
from pipeline.indices import trust
from pipeline.indices.stage import choose_control_model
from pipeline.io import read_json

SCALE = 37.89          # KCS, SIMMAN 2020
PRIMES = ("K_prime", "T1_prime", "T2_prime", "T3_prime", "T_prime")


def test_prime_formula_is_froude_invariant():
    """K' and T' from model-scale numbers equal those from the Froude-scaled full-scale numbers."""
    lam, lpp, u, k, t = 45.7, 7.0, 1.18, 0.3, 14.0
    model = trust.primes({"K": k, "T": t}, lpp, u)
    full = trust.primes({"K": k / math.sqrt(lam), "T": t * math.sqrt(lam)}, lpp * lam, u * math.sqrt(lam))
    assert model["K_prime"] == pytest.approx(k * lpp / u) and model["T_prime"] == pytest.approx(t * u / lpp)
    for key in model:
        assert full[key] == pytest.approx(model[key], rel=1e-12)


def test_unknown_length_gives_null_and_a_flag():
    lpp, u, why = trust.length_and_speed({"approach_speed": 2.0}, {})
    assert lpp is None and u == 2.0
    assert trust.primes({"K": 0.3, "T": 4.0}, lpp, u) == {"K_prime": None, "T_prime": None}
    (f,) = trust.prime_flags(why)
    assert f["check"] == "prime_unavailable" and "Lpp unknown" in f["reason"]
    # dataset.toml particulars (full-scale lpp_m and the scale) stand in for the run's own Lpp
    lpp, _, why = trust.length_and_speed({"approach_speed": 2.0}, {"ship": {"lpp_m": 320.0},
                                                                    "data": {"scale": 45.7}})
    assert lpp == pytest.approx(7.0, rel=1e-3) and not why


def _full_scale_csv(src, dest, lam, lpp_full):
    """Froude-scale a model-scale canonical CSV of the virtual tank to full scale, as a user's file of
    full-scale values: its header states the ship and its full-scale Lpp, and none of the model-scale
    lines (model Lpp, model scale, logging step) of the tank's file."""
    lines = src.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#")
            and not ln.lower().startswith(("# lpp", "# dt", "# scale"))] + [f"# Lpp: {lpp_full:g}"]
    df = pd.read_csv(src, comment="#")
    s = math.sqrt(lam)
    df["time"] *= s
    for c in ("x0", "y0"):
        df[c] *= lam
    for c in ("u", "v"):
        df[c] *= s
    df["r"] /= s
    df["rpm"] /= s
    dest.write_text("\n".join(head) + "\n" + df.to_csv(index=False, float_format="%.12g"))


@pytest.mark.slow
def test_same_runs_model_and_full_scale_give_the_same_primed_indices(tmp_path):
    from pipeline import tank

    model, full, root = tmp_path / "model", tmp_path / "full", tmp_path / "proc"
    model.mkdir()
    full.mkdir()
    for rud, stem in ((20, "zz_20_20_S"), (10, "zz_10_10_S")):
        run = tank.simulate(tank.zigzag(rud, rud, "starboard", duration=90.0))
        tank.write_csv(model / f"{stem}.csv", run)
        _full_scale_csv(model / f"{stem}.csv", full / f"{stem}.csv", SCALE, TankConfig().lpp * SCALE)
    for name, folder, extra in (("m", model, []), ("f", full, ["--scale", str(SCALE)])):
        files = sorted(map(str, folder.glob("*.csv")))
        assert main(["ingest", *files, "--out", str(root / name / "runs"), "--dataset", name, *extra]) == 0
        assert main(["identify", "--dataset", name, "--root", str(root), "--algorithm", "srukf-ffm"]) == 0
        assert main(["indices", "--dataset", name, "--root", str(root)]) == 0
    m = read_json(root / "m" / "indices" / "indices.json")
    f = read_json(root / "f" / "indices" / "indices.json")
    got = 0
    for key in PRIMES:
        a, b = m["identified"]["srukf-ffm"][key]["value"], f["identified"]["srukf-ffm"][key]["value"]
        assert a is not None and b == pytest.approx(a, rel=1e-3), key
        got += 1
    rows_m = {(g["run_id"], g["method"]): g for g in m["graphical"]}
    for g in f["graphical"]:
        for key in ("K_prime", "T_prime"):
            ref = rows_m[(g["run_id"], g["method"])][key]
            assert ref is not None and g[key] == pytest.approx(ref, rel=1e-3), (g["run_id"], key)
            got += 1
    assert got >= 5 + 2 * 4
    # and they are what the definition says with the model's Lpp and the run's approach speed
    entries = read_json(root / "m" / "runs" / "index.json")["runs"]
    entry = next(e for e in entries if e["run_id"] == "zz_20_20_S")
    k = m["identified"]["srukf-ffm"]["K"]["value"]
    assert m["identified"]["srukf-ffm"]["K_prime"]["value"] == pytest.approx(
        k * entry["lpp"] / entry["approach_speed"], rel=1e-9)
    # the full-scale files' header Lpp (230 m) became the model's Lpp through --scale
    runs_f = read_json(root / "f" / "runs" / "index.json")["runs"]
    entry_f = next(e for e in runs_f if e["run_id"] == "zz_20_20_S")
    # (the tank's header gives the model Lpp to 5 digits: 6.0702 m against 230 / 37.89 = 6.07020 m)
    assert entry_f["lpp"] == pytest.approx(entry["lpp"], rel=1e-5) and entry_f["scale_factor"] == SCALE


# ------------------------------------------------------------------------------------ flags
CFG = IndicesConfig()


def _vals(**kw):
    base = {"K": (0.38, 0.02), "T1": (27.3, 2.0), "T2": (1.6, 0.2), "T3": (3.6, 0.4), "T": (25.3, 2.0)}
    base.update(kw)
    return {n: {"value": v, "std": s} for n, (v, s) in base.items()}


def test_flags_of_the_issue_numbers():
    checks = lambda fl: {(f["check"], f["subject"]) for f in fl}   # noqa: E731
    fl = trust.identified_flags(_vals(T1=(27.0, 51.0)), None, {}, CFG)
    assert checks(fl) == {("relative_uncertainty", "T1")}
    assert "T1 = 27 +- 51 s" in fl[0]["reason"]
    fl = trust.identified_flags(_vals(), {"invalid_fraction": 0.39, "samples": 20000}, {}, CFG)
    assert checks(fl) == {("invalid_draws", "K, T1, T2, T3, T")} and "39%" in fl[0]["reason"]
    # with the first-order share (indices stage): the second-order condition concerns T1, T2, T3 only
    chk = {"invalid_fraction": 0.32, "invalid_fraction_first_order": 0.021, "samples": 20000,
           "invalid_causes": {"D <= 0": 0.274, "unstable": 0.0, "complex": 0.048}}
    fl = trust.identified_flags(_vals(), chk, {}, CFG)
    assert checks(fl) == {("invalid_draws", "T1, T2, T3")} and "D <= 0 27%" in fl[0]["reason"]
    assert trust.blocking(fl, ("K", "T")) == [] and trust.blocking(fl, ("T1", "T2", "T3")) == fl
    fl = trust.identified_flags(_vals(), {**chk, "invalid_fraction_first_order": 0.21}, {}, CFG)
    assert checks(fl) == {("invalid_draws", "T1, T2, T3"), ("invalid_draws", "K, T")}
    assert len(trust.blocking(fl, ("K", "T"))) == 1
    for nis in (18.0, 0.12):
        est = {"consistency": {"nis_mean": nis, "nis_95_band": [2.80, 3.20]}}
        fl = trust.identified_flags(_vals(), None, est, CFG)
        assert checks(fl) == {("nis", "filter")}, nis
    assert trust.identified_flags(_vals(), None, {"consistency": {"nis_mean": 3.0,
                                                                  "nis_95_band": [2.8, 3.2]}}, CFG) == []
    # the identify stage's own flags are carried over as they are
    own = {"check": "excitation", "value": 0.0, "band": [1.0, None], "reason": "no rudder motion"}
    fl = trust.identified_flags(_vals(), None, {"flags": [own]}, CFG)
    assert fl[0]["reason"] == "no rudder motion" and fl[0]["source"] == "identify"
    fl = trust.identified_flags(_vals(K=(-0.30, 0.01)), None, {}, CFG)
    assert checks(fl) == {("sign", "K")}
    fl = trust.graphical_flags({"K": 8.0, "T": 578.0}, period_s=60.0)
    assert checks(fl) == {("ill_conditioned", "T")} and "578 s" in fl[0]["reason"]
    assert trust.graphical_flags({"K": 0.3, "T": 14.0}, period_s=31.0) == []


def _choose(srukf_flags, ffm_flags, graphical_flags):
    ident = {a: {**_vals(), **{p: {"value": 1.0, "std": 0.1} for p in PRIMES}}
             for a in ("srukf-ffm", "ffm-ukf")}
    flags = {"srukf-ffm": srukf_flags, "ffm-ukf": ffm_flags}
    gm = {"source": "standard", "run_id": "z20", "K": 0.3, "T": 14.0, "flags": graphical_flags}
    return choose_control_model(ident, ident_flags=flags, failures={}, graphical_model=gm,
                                estimates={"srukf-ffm": {}, "ffm-ukf": {}}, ident="z20", lpp=7.0, u=1.18)


def test_autopilot_falls_back_visibly_and_refuses_when_nothing_is_trusted():
    nis = trust.flag("nis", "filter", 18.0, [2.8, 3.2], "mean NIS 18 outside its band")
    ill = trust.flag("ill_conditioned", "T", 578.0, [0, 60], "T longer than the period")
    t2 = trust.flag("relative_uncertainty", "T2", 1.7, [0, 0.5], "T2 uncertain")
    cm = _choose([], [], [])
    assert cm["source"].startswith("identified srukf-ffm") and cm["second_order"]["ok"]
    cm = _choose([t2], [], [])        # a flagged T2 keeps the first-order design, not the second-order
    assert cm["source"].startswith("identified srukf-ffm") and not cm["second_order"]["ok"]
    cm = _choose([nis], [], [])
    assert cm["source"].startswith("identified ffm-ukf") and "mean NIS 18" in cm["basis"]
    cm = _choose([nis], [nis], [])
    assert cm["source"].startswith("first-order graphical") and cm["K"] == 0.3 and cm["T2"] == 0.0
    assert "mean NIS 18" in cm["basis"]
    cm = _choose([nis], [nis], [ill])
    assert cm["refused"] and "T longer than the period" in cm["reason"] and "mean NIS 18" in cm["reason"]
    # the control stage designs nothing from a refused model and says why
    doc, ts = run_control({"dataset": "d", "provenance": "measured", "control_model": cm,
                           "graphical_model": None}, ControlConfig(seeds=1), progress=False)
    assert doc["refused"] and doc["designs"] == {} and ts.empty
    assert "no trustworthy indices" in doc["notes"][0]


def test_control_says_what_it_was_designed_from():
    nis = trust.flag("nis", "filter", 18.0, [2.8, 3.2], "mean NIS 18 outside its band")
    cm = _choose([nis], [nis], [])
    doc, _ = run_control({"dataset": "d", "provenance": "measured", "control_model": cm,
                          "graphical_model": {"source": "standard", "K": 0.3, "T": 14.0}},
                         ControlConfig(seeds=1), progress=False)
    assert set(doc["designs"]) == {"graphical", "autopilot"}  # no "identified" design from flagged indices
    assert doc["design_basis"]["source"].startswith("first-order graphical")
    assert any(n.startswith("designed from: first-order graphical") for n in doc["notes"])
    assert np.isfinite(doc["results"][0]["stats"]["rise_time"]["mean"])
    # with the flagged identified indices at hand they are simulated beside it, labelled as such
    ident = {"srukf-ffm": {"K": {"value": 0.38, "std": 0.6}, "T": {"value": 25.0, "std": 49.0}}}
    doc, _ = run_control({"dataset": "d", "provenance": "measured", "control_model": cm, "identified": ident,
                          "graphical_model": {"source": "standard", "K": 0.3, "T": 14.0}},
                         ControlConfig(seeds=1), progress=False)
    assert set(doc["designs"]) == {"graphical", "identified-flagged", "autopilot"}
    assert any("for comparison only" in n for n in doc["notes"])
    assert doc["design_basis"]["source"].startswith("first-order graphical")


def test_phase_margin_below_the_floor_is_flagged():
    from pipeline.control.stage import loop_flags

    cfg = ControlConfig()
    (f,) = loop_flags({"phase_margin_deg": 20.0}, cfg)
    assert f["check"] == "phase_margin" and "20 deg below 30 deg" in f["reason"]
    assert loop_flags({"phase_margin_deg": 45.0}, cfg) == []
    assert loop_flags({"phase_margin_deg": None}, cfg) == []


def test_report_marks_a_set_flag_only_on_the_indices_it_names():
    from pipeline.report import nb

    fl = [trust.flag("invalid_draws", "T1, T2, T3", 0.25, [0, 0.05], "draws"),
          trust.flag("relative_uncertainty", "T2", 1.2, [0, 0.5], "wide")]
    assert nb.flag_marks(fl, "K") == "" and nb.flag_marks(fl, "T") == ""
    assert nb.flag_marks(fl, "T1") == "invalid draws"
    assert nb.flag_marks(fl, "T2") == "invalid draws, uncertain"
    fl.append({"check": "innovation_whiteness", "subject": "filter", "reason": "lag-1"})
    assert nb.flag_marks(fl, "K") == "innovations not white"


def test_nis_below_its_band_reads_as_over_stated_uncertainty_and_does_not_block():
    """A mean NIS below its band (the filter over-states its uncertainty, as the fading memory does by
    design) is reported but does not forbid a design; above its band (over-confidence) it does."""
    import numpy as np

    from pipeline.identify import consistency as cons
    from pipeline.indices.trust import blocking, nis_low

    nu = np.random.default_rng(5).standard_normal((585, 3))
    low = cons.flags(cons.consistency((nu ** 2).sum(1) / 3, nu, ["v", "r", "psi"]))
    high = cons.flags(cons.consistency((nu ** 2).sum(1) * 3, nu, ["v", "r", "psi"]))
    assert low[0]["reading"] == "over-stated uncertainty" and "conservative" in low[0]["reason"]
    assert high[0]["reading"] == "over-confident" and "not to be trusted" in high[0]["reason"]
    as_indices = [{"subject": "filter", **f} for f in low + high]
    assert [nis_low(f) for f in as_indices] == [True, False]
    assert blocking(as_indices, ("K", "T")) == [as_indices[1]]
