"""Run every case of tests/test_diagnose_generalise.py and print a table (for the lead).

    PYTHONPATH=$PWD .venv/bin/python tests/truths/run_cases.py [--only 03,14] [--no-kvlcc2] [-j 2]
        [--mariner-seeds 1350,2000 | all | none]

Columns: case, ship, truth, expected cause, got cause, extended effects, reported held-out gain,
estimate vs truth, CPU seconds of the diagnosis, PASS/FAIL with the reasons.  Then the KVLCC2
free-running check (overshoots vs SIMMAN 2008), its side-swap folds with the baseline and
extended held-out heading MAE, and the two scale-invariance checks.  Between them the Mariner
section (each form in both side-swap folds; ``--mariner-seeds``).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve()
sys.path.insert(0, str(HERE.parents[1]))       # tests/ (for ``truths`` and the test module)
sys.path.insert(0, str(HERE.parents[2]))       # the worktree (for ``pipeline``)


def _immaterial(fig: dict) -> str:
    shown, words = fig.get("demonstrable", (True, ""))
    return "" if shown else f" (immaterial in heading: {words})"


def _one(args):
    cid, folder = args
    import test_diagnose_generalise as tg

    from truths import cases as tc

    case = next(c for c in tg.CASES if c.cid == cid)
    t0 = time.process_time()
    try:
        rep, sec = tg.run_case(case, Path(folder) / cid)
    except Exception as exc:  # noqa: BLE001 - a crash is a FAIL row, with its message
        return cid, False, [f"crashed: {type(exc).__name__}: {exc}"], {}, time.process_time() - t0
    ok, why, fig = tc.judge(case, rep, tc.noise_mae_psi(case))
    fig["baseline_mae"] = rep.get("baseline", {}).get("validation", {}).get("mae_psi_deg")
    fig["extended_mae"] = rep.get("extended", {}).get("validation", {}).get("mae_psi_deg")
    return cid, ok, why, fig, sec


def _fmt(x, f="{:.2f}"):
    return "-" if x is None else f.format(x)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma-separated case ids")
    ap.add_argument("--no-kvlcc2", action="store_true")
    ap.add_argument("-j", type=int, default=1, help="worker processes")
    ap.add_argument("--oracle", action="store_true", help="also the independent linear/rich fit on KVLCC2")
    ap.add_argument("--only-kvlcc2", action="store_true")
    ap.add_argument("--mariner-seeds", default="",
                    help="comma-separated noise seeds of the Mariner section (default: make test's one; "
                         "'all': make generalise's seven; 'none': skip it)")
    a = ap.parse_args(argv)
    import test_diagnose_generalise as tg

    ids = [c.cid for c in tg.CASES if (not a.only or c.cid in a.only.split(",")) and not a.only_kvlcc2]
    folder = tempfile.mkdtemp(prefix="gen_cases_")
    jobs = [(cid, folder) for cid in ids]
    if a.j > 1:
        with ProcessPoolExecutor(a.j) as ex:
            results = list(ex.map(_one, jobs))
    else:
        results = [_one(j) for j in jobs]
    by = {c.cid: c for c in tg.CASES}
    print("| case | ship | truth | expected | got | extended | gain | MAE base/ext deg | estimate vs truth "
          "| s | result |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    npass = 0
    for cid, ok, why, fig, sec in results:
        c = by[cid]
        npass += ok
        est = ", ".join(f"{k} {g:.3g} vs {t if isinstance(t, str) else format(t, '.3g')}"
                        for k, (g, t) in fig.get("estimates", {}).items())
        exp = "/".join(c.accepted) if c.expected != c.accepted[0] or len(c.accepted) > 1 else c.expected
        print(f"| {cid} | {c.ship} | {c.truth} | {exp} | {fig.get('cause', '-')} | "
              f"{','.join(fig.get('extended', [])) or '-'} | {_fmt(fig.get('gain'))} | "
              f"{_fmt(fig.get('baseline_mae'))}/{_fmt(fig.get('extended_mae'))} | {est or '-'} | {sec:.1f} | "
              f"{'PASS' if ok else 'FAIL: ' + '; '.join(why)}{_immaterial(fig)} |")
    print(f"\n{npass}/{len(results)} cases pass")
    if a.mariner_seeds != "none" and not a.only_kvlcc2:
        _mariner(tg, Path(folder), a.mariner_seeds)
    if a.no_kvlcc2:
        return 0
    from truths import kvlcc2 as kv

    s = kv.KVLCC2()
    print(f"\nKVLCC2 MMG (Yasukawa & Yoshimura 2015), full scale, {s.u0_kn} kn, trimmed "
          f"{kv.trim_rps(s) * 60:.1f} rpm; published SIMMAN 2008 first overshoots: 10/10 ~8, 20/20 ~13 deg")
    for amp in (10, 20):
        for side in ("starboard", "port"):
            f = kv.simulate_zigzag(s, amp, amp, side, duration=tg.KV_DURATION, noise=False)
            m = kv.zigzag_metrics(f, amp)
            ov = ", ".join(f"{o:.1f}" for o in m["overshoots_deg"])
            low = m["lowest_speed_ratio"]
            print(f"  {amp}/{amp} {side:9s}: overshoots {ov} deg; lowest speed {low:.2f} U0")
    files = tg.write_kvlcc2(Path(folder) / "kvlcc2", seed=tg.SEED * 100)
    causes = {}
    for fold in (1, 2):
        t0 = time.process_time()
        rep = tg.kvlcc2_fold(files, fold)
        causes[fold] = rep["cause"]
        b = rep["baseline"]["validation"]["mae_psi_deg"]
        e = rep["extended"]["validation"]["mae_psi_deg"]
        g = rep["gain"]["mae_psi_relative_reduction"]
        ok = rep["cause"] != "none" and 1.0 - e / b >= tg.KV_MIN_GAIN  # test_kvlcc2_marin_side_swap
        print(f"  fold {fold} ({'train S, validate P' if fold == 1 else 'train P, validate S'}): cause "
              f"{rep['cause']}, extended {rep['extended']['effects']}, held-out MAE psi baseline {b:.2f} -> "
              f"extended {e:.2f} deg ({1.0 - e / b:.0%}) [{'PASS' if ok else 'FAIL'}], "
              f"honest gain (nested) {_fmt(g)} "
              f"({time.process_time() - t0:.0f} s)")
    if a.oracle:
        from truths import oracle

        for fold in (1, 2):
            tr, va = ("starboard", "port") if fold == 1 else ("port", "starboard")
            ftr = [tg.load(files[(amp, tr)], scale=tg.SCALE).frame for amp in (20, 10)]
            fva = [tg.load(files[(amp, va)], scale=tg.SCALE).frame for amp in (20, 10)]
            t0 = time.process_time()
            res = {}
            lin = oracle.fit(ftr, "linear")
            for model in ("linear", "rich", "rich+offset"):
                p = lin if model == "linear" else oracle.fit(ftr, model, start=lin)
                res[model] = oracle.heldout_mae_psi(p, fva)
            red = {m: 1 - res[m] / res["linear"] for m in res}
            print(f"  oracle fold {fold} (independent output-error fit, truths/oracle.py): held-out MAE psi "
                  + ", ".join(f"{m} {res[m]:.2f} deg ({red[m]:+.0%})" for m in res)
                  + f" ({time.process_time() - t0:.0f} s)")
    # full-scale files without --scale are refused by ingest
    # (test_kvlcc2_full_scale_files_without_scale_are_refused)
    for how in ("model",):
        t0 = time.process_time()
        c = tg.kvlcc2_fold(files, 1, how)["cause"]
        print(f"  scale invariance ({how}): cause {c} vs {causes[1]} with --scale "
              f"[{'PASS' if c == causes[1] else 'FAIL'}] ({time.process_time() - t0:.0f} s)")
    return 0


def _mariner(tg, folder: Path, seeds_arg: str) -> None:
    """The Mariner section: each form's verdict in both side-swap folds (test_mariner_*), without the
    nested honest gain."""
    from truths import mariner as mr

    if seeds_arg == "all":
        seeds = (tg.MR_SEED, *tg.MR_SEEDS)
    else:
        seeds = tuple(int(x) for x in seeds_arg.split(",")) if seeds_arg else (tg.MR_SEED,)
    print(f"\nMariner (Abkowitz model, Chislett & Stroem-Tejsen 1965), full scale, --scale {tg.MR_SCALE:g}; "
          f"equivalent offset of Y_0, N_0 {mr.equivalent_offset_deg():.3f} deg; slow linear pole "
          f"{-1.0 / mr.linear_poles()[1]:.0f} s")
    forms = [("linear", "none"), ("offset", "rudder_offset"), ("full", "a cause, offset among the effects")]
    for seed in seeds:
        for form, expected in forms if seed == tg.MR_SEED else forms[2:]:
            for fold in (1, 2):
                t0 = time.process_time()
                rep = tg.mariner_fold(folder, form, fold, seed=seed)
                b = rep["baseline"]["validation"]["mae_psi_deg"]
                e = rep["extended"]["validation"]["mae_psi_deg"]
                off = next((f["estimate"]["offset_deg"] for f in rep["findings"]
                            if f["effect"] == "rudder_offset" and f["significant"]), None)
                print(f"  seed {seed} {form:6s} fold {fold}: expected {expected}; cause {rep['cause']}, "
                      f"extended {rep['extended']['effects']}, held-out MAE psi {b:.3f} -> {e:.3f} deg "
                      f"({1.0 - e / b:.0%})" + (f", offset {off:.3f} deg" if off is not None else "")
                      + f" ({time.process_time() - t0:.0f} s)")


if __name__ == "__main__":
    raise SystemExit(main())
