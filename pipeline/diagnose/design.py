"""The catalog design of the diagnosis: which runs of a dataset train, validate and test
(docs/diagnosis.md, "Design").

A stated rule over a runs index (``runs/index.json``: ``run_id``, ``kind``, ``rudder_deg``,
``heading_deg`` in deg, ``first_side``, ``approach_speed`` in m/s), never a choice by hand:

* :func:`roles_design` -- the dataset description's own ``[roles]``, when it gives them;
* :func:`one_speed` -- the runs at one approach speed (a linear model holds at one speed);
* :func:`pick_catalog_runs` -- zigzags by :func:`pick_zigzags`, then turning circles, in twins
  crossed over training and validation; every other run a test run;
* :func:`extrapolated` -- test runs outside the selection's amplitudes.

Example
-------
>>> from pipeline.diagnose.design import pick_catalog_runs
>>> runs = [{"run_id": f"z{a}{s[0]}", "kind": "zigzag", "rudder_deg": a, "heading_deg": a,
...          "first_side": s} for a in (10, 20) for s in ("starboard", "port")]
>>> pick_catalog_runs(runs)
(['z20s', 'z10p'], ['z20p', 'z10s'], [])
"""

from __future__ import annotations

import itertools

from pipeline.config import DiagnoseConfig
from pipeline.errors import InputError

__all__ = ["extrapolated", "is_zigzag", "one_speed", "pick_catalog_runs", "pick_zigzags", "roles_design"]


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


def is_zigzag(e: dict) -> bool:
    """A runs-index entry of a zigzag (an entry without a kind is taken as one)."""
    return str(e.get("kind", "zigzag")).startswith("zig")


def _twin(a: dict, b: dict, tol: float) -> bool:
    """Rudder amplitudes (deg, keys ``rudder``) within the relative tolerance ``tol``."""
    x, y = a["rudder"], b["rudder"]
    return abs(x - y) <= tol * max(x, y, 1e-9)


def pick_catalog_runs(entries: list[dict], *, twin_tolerance: float | None = None
                      ) -> tuple[list[str], list[str], list[str]]:
    """Training, validation and test run ids from a runs index, by a stated rule (all runs used):
    the zigzags by :func:`pick_zigzags`, then the turning circles.

    6. Turning circles (``kind`` "turning"; with zigzags beside them) in twins (rudder amplitudes
       within ``twin_tolerance``, a pair to both sides preferred) join the SELECTION, crossed: of each
       twin, largest rudder first, one trains and one validates, starboard to training for the first
       twin and then alternately, so the diagnosis's reverse fold swaps them.  Reason: a steady turn
       holds drift and rate no zigzag reaches, so a model chosen on zigzags alone extrapolates there
       (docs/diagnosis.md, the virtual KCS's turning circles).
       A turning circle without a twin is a test run: no choice sees it, and unless a selection twin
       is a turning circle it is named extrapolated (:func:`extrapolated`).
    """
    tol = DiagnoseConfig().twin_tolerance if twin_tolerance is None else twin_tolerance
    zz = [e for e in entries if is_zigzag(e)]
    tc = [e for e in entries if e.get("kind") == "turning"]
    if not zz:
        return pick_zigzags(entries, twin_tolerance=tol)
    train, val, test = pick_zigzags(zz, twin_tolerance=tol)
    circles = [{"id": e["run_id"], "rudder": abs(float(e.get("rudder_deg") or 0.0)),
                "side": e.get("first_side")} for e in tc]
    circles.sort(key=lambda r: (-r["rudder"], r["side"] != "starboard", r["id"]))
    first = True
    while circles:
        a = circles.pop(0)
        mates = [b for b in circles if _twin(a, b, tol)]
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


def pick_zigzags(entries: list[dict], *, twin_tolerance: float | None = None
                 ) -> tuple[list[str], list[str], list[str]]:
    """Training, validation and test run ids of the zigzags of a runs index (all of them used).

    Design rule (any dataset folder, pairs or not; amplitudes from the index's ``rudder_deg`` and
    ``heading_deg``, a missing one read as 0):

    1. The selection runs are made of TWINS: two runs whose rudder amplitudes agree within
       ``twin_tolerance`` (default :attr:`pipeline.config.DiagnoseConfig.twin_tolerance`); one
       goes to training, one to validation, so every selection amplitude is on both sides and the
       diagnosis can swap the roles (its reverse fold).  A pair (one test run to
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
    zz = [e for e in entries if is_zigzag(e)] or list(entries)
    tol = DiagnoseConfig().twin_tolerance if twin_tolerance is None else twin_tolerance
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
        ((a, b) for i, a in enumerate(runs) for b in runs[i + 1 :] if _twin(a, b, tol)), key=rank
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
                if r[axis] == v or (axis == "rudder" and _twin({"rudder": v}, r, tol))}

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
    best = max(groups, key=lambda g: (len(g), sum(map(is_zigzag, g)), float(g[0]["approach_speed"])))
    chosen = {id(e) for e in best}
    used = [e for e in entries if id(e) in chosen or not e.get("approach_speed")]
    return used, [e for e in entries if id(e) not in chosen and e.get("approach_speed")]


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
