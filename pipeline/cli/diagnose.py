"""``python -m pipeline diagnose``: SPEC section 7.

Explicit mode:  ``--train RUN [RUN ...] --validate RUN [RUN ...] --out DIR [--scale S]``, RUN a raw
file of any SPEC section 3 format or a processed Parquet run.
           ``[--test RUN ...]``: the gain is reported on the test runs (else nested cross-validation).
Catalog mode:   ``--dataset D`` uses every zigzag and turning circle of data/processed/D/runs/index.json
by the rule of :func:`pick_catalog_runs` (selection runs in twins spanning the rudder and heading
amplitudes, crossed by side; turning circles in twins crossed the same way; every other run a test run;
runs at another approach speed than the largest set that agrees within 15 % left out, with the reason,
in ``runs_not_used`` of diagnosis.json: :func:`one_speed`), or, when the dataset's description gives
``[roles]`` train and validate (SPEC section 9), by those roles (:func:`roles_design`);
writes data/processed/D/diagnose/.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
from pathlib import Path

from pipeline.cli._common import add_dataset_args, catalog
from pipeline.config import DiagnoseConfig
from pipeline.errors import InputError
from pipeline.io import Run, read_json, read_run


def load_run(path: str | Path, scale: float | None = None) -> Run:
    """A processed Parquet run, or a raw file read by the ingest stage."""
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", file=os.path.abspath(path))
    if path.suffix.lower() == ".parquet":
        return read_run(path)
    try:
        from pipeline.ingest import ingest_file
    except ImportError as exc:  # pragma: no cover - the ingest stage is part of the project
        raise InputError(f"cannot read raw files: ingest stage unavailable ({exc})", file=path) from None
    kw = {"fmt": None}
    if scale is not None:
        kw["scale"] = scale
    run = ingest_file(path, **kw)
    run.meta.setdefault("run_id", path.stem)
    return run


def roles_design(index: dict) -> tuple[list[str], list[str], list[str]] | None:
    """(train, validate, test) run ids from the ``[roles]`` of the dataset's description, as ingest
    recorded them in runs/index.json, or None when it gives neither train nor validate (the stated
    rule then designs).  Refused in one line naming the description: only one of train and validate,
    a run id the dataset has not, or a run in two roles."""
    roles = index.get("roles") or {}
    given = {k: list(roles.get(k) or []) for k in ("train", "validate", "test")}
    if not (given["train"] or given["validate"]):
        return None
    toml = (index.get("ship") or {}).get("dataset_toml") or "dataset.toml"
    if not (given["train"] and given["validate"]):
        has, lacks = ("train", "validate") if given["train"] else ("validate", "train")
        raise InputError(f"[roles] gives {has} but not {lacks}: the diagnosis needs both (or neither, for "
                         "its own design)", file=toml)
    known = {e["run_id"] for e in index.get("runs", [])}
    seen: dict[str, str] = {}
    for role, ids in given.items():
        for rid in ids:
            if rid not in known:
                raise InputError(f"[roles] {role} names run {rid!r}, which the dataset has not (its runs: "
                                 f"{', '.join(sorted(known))})", file=toml)
            if rid in seen:
                raise InputError(f"[roles] names run {rid!r} in both {seen[rid]} and {role}", file=toml)
            seen[rid] = role
    return given["train"], given["validate"], given["test"]


#: two runs are TWINS (the same manoeuvre for the purpose of swapping training and validation) when
#: their rudder amplitudes agree within this fraction: the tolerance at which the diagnosis itself
#: calls two sides the same manoeuvres and adds the reverse fold (pipeline.diagnose.core._exchangeable)
TWIN_TOL = 0.15


def _is_zigzag(e: dict) -> bool:
    """A runs-index entry of a zigzag (an entry without a kind is taken as one)."""
    return str(e.get("kind", "zigzag")).startswith("zig")


def _twin(a: dict, b: dict) -> bool:
    x, y = a["rudder"], b["rudder"]
    return abs(x - y) <= TWIN_TOL * max(x, y, 1e-9)


def pick_catalog_runs(entries: list[dict]) -> tuple[list[str], list[str], list[str]]:
    """Training, validation and test run ids from a runs index, by a stated rule (all runs used):
    the zigzags by :func:`pick_zigzags`, then the turning circles.

    6. Turning circles (``kind`` "turning"; with zigzags beside them) in twins (rudder amplitudes
       within :data:`TWIN_TOL`, a pair to both sides preferred) join the SELECTION, crossed: of each
       twin, largest rudder first, one trains and one validates, starboard to training for the first
       twin and then alternately, so the diagnosis's reverse fold swaps them.  Reason, measured on the
       virtual KCS tank (2026-11-25): chosen on its four zigzags alone, the extended model (offset,
       r|r| damping and cross terms) predicted the two 35 deg turning circles 28 times worse than
       the linear baseline (held-out gain -2776 %): a steady turn holds drift and rate no zigzag
       reaches (r 7.9 deg/s, speed down 59 %), so a model that never saw one is extrapolating there.
       A turning circle without a twin is a test run: no choice sees it, and unless a selection twin
       is a turning circle it is named extrapolated (:func:`extrapolated`).
    """
    zz = [e for e in entries if _is_zigzag(e)]
    tc = [e for e in entries if e.get("kind") == "turning"]
    if not zz:
        return pick_zigzags(entries)
    train, val, test = pick_zigzags(zz)
    circles = [{"id": e["run_id"], "rudder": abs(float(e.get("rudder_deg") or 0.0)),
                "side": e.get("first_side")} for e in tc]
    circles.sort(key=lambda r: (-r["rudder"], r["side"] != "starboard", r["id"]))
    first = True
    while circles:
        a = circles.pop(0)
        mates = [b for b in circles if _twin(a, b)]
        if not mates:
            test.append(a["id"])
            continue
        b = min(mates, key=lambda m: (m["side"] == a["side"], abs(m["rudder"] - a["rudder"]), m["id"]))
        circles.remove(b)
        star = b if b["side"] == "starboard" != a["side"] else a     # the starboard member of a pair
        other = b if star is a else a
        x, y = (star, other) if first else (other, star)
        train.append(x["id"])
        val.append(y["id"])
        first = not first
    return train, val, test


def pick_zigzags(entries: list[dict]) -> tuple[list[str], list[str], list[str]]:
    """Training, validation and test run ids of the zigzags of a runs index (all of them used).

    Design rule (any dataset folder, pairs or not; amplitudes from the index's ``rudder_deg`` and
    ``heading_deg``, a missing one read as 0):

    1. The selection runs are made of TWINS: two runs whose rudder amplitudes agree within
       :data:`TWIN_TOL`; one goes to training, one to validation, so every selection amplitude is on
       both sides and the diagnosis can swap the roles (its reverse fold).  A pair (one test run to
       both sides) is the preferred twin, then the least amplitude difference, then the smaller rudder
       amplitude.
    2. Crossed pairs: with two or more pairs, the pairs of the smallest and the largest rudder amplitude
       are selection twins.
    3. Span, on BOTH sides of the design: the selection then covers, in this order, the largest and
       the smallest rudder amplitude and the smallest and the largest heading amplitude among the runs
       that have a twin, each on the training AND the validation side, so that every fold (the design
       and its reverse) is judged on both ends of both ranges.  A twin holds one rudder amplitude, so
       one twin covers a rudder end on both sides; a heading end needs a twin with both members at it
       (a pair) or two twins with one member each (dealt to opposite sides, rule 4).  Twins of unused
       runs containing the end are added until both sides have it; when none is left before any side
       has it, the next amplitude inward.  So no test run is outside the selection's range unless its
       amplitude has no free twin (the rule names it extrapolated, e.g. HSVA's single 5 deg/1 deg
       zigzag below the 10 deg twins).
    4. Crossing: the twins, largest rudder amplitude first, give their first member (starboard of a
       pair; else the larger rudder, then the smaller heading amplitude) alternately to training and
       to validation; of all ways round of the twins the one is taken that puts the most ends of the
       ranges on both sides, then the most first sides (starboard, port) on both sides, then the fewest
       departures from that alternation: each side has both sides and both ends of the ranges.
    5. Every other zigzag is a TEST run: no choice sees it, the gain is reported on it; they lie
       between the selection runs in amplitude (interleaved).

    Without any twin: the runs at the extremes (smallest and largest rudder, smallest and largest
    heading amplitude) train, the others sorted by amplitude are dealt validate, test in turn (one
    fold, interpolation held out).
    """
    zz = [e for e in entries if _is_zigzag(e)] or list(entries)
    if len(zz) < 2:
        raise InputError("catalog mode needs at least two zigzag runs (one to train, one to validate)")
    runs = [
        {
            "id": e["run_id"],
            "rudder": abs(float(e.get("rudder_deg") or 0.0)),
            "heading": abs(float(e.get("heading_deg") or 0.0)),
            "side": e.get("first_side"),
        }
        for e in zz
    ]

    def is_pair(a, b):
        return (
            a["rudder"] == b["rudder"]
            and a["heading"] == b["heading"]
            and {a["side"], b["side"]} == {"starboard", "port"}
        )

    def rank(tw):  # preference among twins (rule 1)
        a, b = tw
        return (not is_pair(a, b), abs(a["rudder"] - b["rudder"]), min(a["rudder"], b["rudder"]),
                a["id"], b["id"])

    twins = sorted(
        ((a, b) for i, a in enumerate(runs) for b in runs[i + 1 :] if _twin(a, b)), key=rank
    )
    twinned = [r for r in runs if any(r is a or r is b for a, b in twins)]
    if not twinned:
        order = sorted(runs, key=lambda r: (r["rudder"], r["heading"], r["id"]))
        ext = {id(min(order, key=lambda r: (r["rudder"], r["heading"]))),
               id(max(order, key=lambda r: (r["rudder"], r["heading"]))),
               id(min(order, key=lambda r: (r["heading"], r["rudder"]))),
               id(max(order, key=lambda r: (r["heading"], r["rudder"])))}
        train = [r for r in order if id(r) in ext]
        rest = [r for r in order if id(r) not in ext]
        if not rest:  # two runs, both extremes: the larger trains, the smaller validates
            train, rest = order[1:], order[:1]
        return [r["id"] for r in train], [r["id"] for r in rest[0::2]], [r["id"] for r in rest[1::2]]

    chosen: list = []
    used: set = set()

    def take(tw):
        chosen.append(tw)
        used.update(id(r) for r in tw)

    def free(tw):
        return not (used & {id(tw[0]), id(tw[1])})

    by_amp = sorted((tw for tw in twins if is_pair(*tw)), key=lambda tw: (tw[0]["rudder"], tw[0]["heading"]))
    if by_amp:
        low = {id(r) for r in by_amp[0]}
        high = [tw for tw in by_amp if not low & {id(tw[0]), id(tw[1])}]
        if high:  # two pairs without a shared run
            take(by_amp[0])
            take(high[-1])
    def sides_at(axis, v):  # on how many sides of the design a chosen twin puts amplitude v (0..2)
        n = 0
        for tw in chosen:
            at = sum(r[axis] == v for r in tw)
            n += 2 if at and (axis == "rudder" or at == 2) else at  # a twin's rudders are one amplitude
        return min(n, 2)

    for axis, largest in (("rudder", True), ("rudder", False), ("heading", False), ("heading", True)):
        for v in sorted({r[axis] for r in twinned}, reverse=largest):
            while sides_at(axis, v) < 2:
                cands = [tw for tw in twins if free(tw) and any(r[axis] == v for r in tw)]
                if not cands:
                    break
                take(cands[0])
            if sides_at(axis, v):
                break

    def member_order(tw):
        a, b = tw
        if is_pair(a, b):
            return (a, b) if a["side"] == "starboard" else (b, a)
        return tuple(sorted(tw, key=lambda r: (-r["rudder"], r["heading"], r["id"])))

    sel = [r for tw in chosen for r in tw]
    ends = {("rudder", min(r["rudder"] for r in sel)), ("rudder", max(r["rudder"] for r in sel)),
            ("heading", min(r["heading"] for r in sel)), ("heading", max(r["heading"] for r in sel))}

    def marks(r):  # the ends of the amplitude ranges a run brings to its side of the design
        return {(axis, v) for axis, v in ends
                if r[axis] == v or (axis == "rudder" and _twin({"rudder": v}, r))}

    chosen.sort(key=lambda tw: (-max(r["rudder"] for r in tw), -max(r["heading"] for r in tw)))
    ordered = [member_order(tw) for tw in chosen]

    def score(flips):  # (ends on both sides, first sides on both sides, agreement with alternation)
        halves = (set(), set())
        for i, ((a, b), f) in enumerate(zip(ordered, flips, strict=True)):
            x, y = (a, b) if (i % 2 == 0) != f else (b, a)
            halves[0].update(marks(x) | {("side", x["side"])})
            halves[1].update(marks(y) | {("side", y["side"])})
        return (sum(m[0] != "side" for m in halves[0]) + sum(m[0] != "side" for m in halves[1]),
                sum(m[0] == "side" for m in halves[0]) + sum(m[0] == "side" for m in halves[1]),
                -sum(flips))

    # every orientation of the (few: at most two pairs and two twins per end) twins, the best by score
    best = max(itertools.product((False, True), repeat=len(ordered)), key=score)
    train, val = [], []
    for i, ((a, b), f) in enumerate(zip(ordered, best, strict=True)):
        x, y = (a, b) if (i % 2 == 0) != f else (b, a)
        train.append(x["id"])
        val.append(y["id"])
    test = sorted((r for r in runs if id(r) not in used), key=lambda r: (r["rudder"], r["heading"], r["id"]))
    return train, val, [r["id"] for r in test]


def one_speed(entries: list[dict], tol: float) -> tuple[list[dict], list[dict]]:
    """The runs of an index that the catalog design uses, and the others: the largest set whose
    approach speeds (the index's ``approach_speed``, m/s) agree within ``tol`` (the diagnosis's own
    rule, pipeline.diagnose.core.check_runs: a linear model's coefficients hold at one speed, so runs
    at another speed are not the same ship to it).  Ties: the set with more zigzags, then the faster
    (a campaign's extra runs are usually the slower ones).  Runs without a speed go with any set."""
    known = sorted((e for e in entries if e.get("approach_speed")), key=lambda e: float(e["approach_speed"]))
    if not known:
        return list(entries), []

    groups = []
    for i, lo in enumerate(known):
        top = (1.0 + tol) * float(lo["approach_speed"])
        groups.append([e for e in known[i:] if float(e["approach_speed"]) <= top])
    best = max(groups, key=lambda g: (len(g), sum(map(_is_zigzag, g)), float(g[0]["approach_speed"])))
    chosen = {id(e) for e in best}
    used = [e for e in entries if id(e) in chosen or not e.get("approach_speed")]
    return used, [e for e in entries if id(e) not in chosen and e.get("approach_speed")]


def _other_speed(e: dict, used: list[dict], tol: float) -> str:
    speeds = sorted(float(x["approach_speed"]) for x in used if x.get("approach_speed"))
    return (f"approach speed {float(e['approach_speed']):.3f} m/s, the design's "
            f"{speeds[0]:.3f}-{speeds[-1]:.3f} m/s: more than {tol:.0%} apart, and one linear model holds at "
            "one speed; diagnose it with --train/--validate")


def extrapolated(entries: list[dict], selection: list[str], test: list[str]) -> list[str]:
    """Test runs outside the range of rudder and heading amplitude of the selection runs of their
    kind (a turning circle is compared with the selection's turning circles; run ids)."""
    def turning(e):
        return e.get("kind") == "turning"

    by_id = {e["run_id"]: e for e in entries}
    out = []
    for rid in test:
        e = by_id[rid]
        sel = [by_id[r] for r in selection if turning(by_id[r]) == turning(e)]
        amps = [(abs(float(x.get("rudder_deg") or 0)), abs(float(x.get("heading_deg") or 0))) for x in sel]
        a, h = abs(float(e.get("rudder_deg") or 0)), abs(float(e.get("heading_deg") or 0))
        if not (amps and min(x for x, _ in amps) <= a <= max(x for x, _ in amps)
                and min(y for _, y in amps) <= h <= max(y for _, y in amps)):
            out.append(rid)
    return out


def run(args: argparse.Namespace) -> int:
    cfg = DiagnoseConfig()
    not_used: dict[str, str] = {}       # catalog mode: runs of the index left out, with the reason
    if args.train or args.validate:
        if not (args.train and args.validate and args.out):
            raise InputError("explicit mode needs --train, --validate and --out")
        train = [load_run(p, args.scale) for p in args.train]
        val = [load_run(p, args.scale) for p in args.validate]
        test = [load_run(p, args.scale) for p in (args.test or [])]
        out = Path(args.out)
    else:
        cat = catalog(args)
        index = read_json(cat.runs_index)
        roles = roles_design(index)
        if roles is not None:
            # the user's own design (SPEC section 9 [roles]): taken as given; the diagnosis itself
            # refuses runs of different approach speeds
            entries = index.get("runs", [])
            train_ids, val_ids, test_ids = roles
            placed = set(train_ids + val_ids + test_ids)
            not_used = {e["run_id"]: "in no [roles] of the dataset's description" for e in entries
                        if e["run_id"] not in placed}
        else:
            entries, other = one_speed(index.get("runs", []), cfg.speed_tolerance)
            not_used = {e["run_id"]: _other_speed(e, entries, cfg.speed_tolerance) for e in other}
            train_ids, val_ids, test_ids = pick_catalog_runs(entries)
            placed = set(train_ids + val_ids + test_ids)
            not_used.update({e["run_id"]: f"a test of kind '{e.get('kind')}': the design takes zigzags "
                                          "and turning circles"
                             for e in entries if e["run_id"] not in placed})
        if not_used:
            print("not used: " + "; ".join(f"{k} ({why})" for k, why in not_used.items()))
        outside = extrapolated(entries, train_ids + val_ids, test_ids)
        print(
            ("design (the dataset's [roles])" if roles is not None else "design")
            + f": train {', '.join(train_ids)}; validate {', '.join(val_ids)}; test "
            f"{', '.join(test_ids) or 'none (the honest gain by nested leave-one-run-out)'}"
            + (f"; outside the selection's amplitudes: {', '.join(outside)}" if outside else "")
        )
        files = {e["run_id"]: e.get("file", f"{e['run_id']}.parquet") for e in entries}

        def load(rid):
            f = Path(files[rid])
            return read_run(f if f.is_absolute() or f.exists() else cat.runs_dir / f.name)

        train = [load(r) for r in train_ids]
        val = [load(r) for r in val_ids]
        test = [load(r) for r in test_ids]
        out = Path(args.out) if args.out else cat.diagnose_dir

    from pipeline.diagnose import diagnose
    from pipeline.diagnose.output import write_outputs

    diag = diagnose(train, val, cfg=cfg, progress=True, test=test)
    diag.report["runs_not_used"] = not_used
    path = write_outputs(diag, out, plots=not args.no_plots)
    rep = diag.report
    from pipeline.report.diagnosis_text import headline

    print(f"{headline(rep)}; wrote {path}")
    for check in rep["data_checks"].values():
        if check["warning"]:
            print(f"warning: {check['warning']}", file=sys.stderr)
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "diagnose",
        help="what the linear model gets wrong, the cause, the extended model (SPEC 7)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--train", nargs="+", metavar="RUN", help="training runs (raw file or processed Parquet)")
    p.add_argument("--validate", nargs="+", metavar="RUN", help="validation runs")
    p.add_argument(
        "--test",
        nargs="+",
        metavar="RUN",
        help="test runs: the gain is reported on them (no choice "
        "sees them); without them, nested cross-validation",
    )
    p.add_argument("--out", type=Path, help="output directory (catalog mode: data/processed/D/diagnose)")
    p.add_argument("--scale", type=float, default=None, help="scale factor of full-scale raw files")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_dataset_args(p)
    p.set_defaults(func=run)
