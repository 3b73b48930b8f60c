"""What a run is: parse test names, choose identification and validation runs.

Test names come from file headers in many spellings: ``zigzag 20/20 starboard`` (virtual tank),
``Zig-zag manoeuvring for KVLCC2 : 20 / -20`` (MARIN), ``Z20°/10° starting to port`` (HSVA),
``turning circle 35 port``.  :func:`parse_test_name` turns them into a small dict.
"""

from __future__ import annotations

import re
from typing import Any

from pipeline import paper

_ZIGZAG = re.compile(
    r"(?:zig[\s-]*zag|^\s*z)(?:.*?[^\w.])??(?P<rud>\d+(?:\.\d+)?)[^\d/\n]{0,5}/\s*-?\s*(?P<head>\d+(?:\.\d+)?)",
    re.IGNORECASE,
)
# Between the number and the slash: a degree sign in any code page ('°' Latin-1, 'ø' read from
# cp437, 'Â°' UTF-8 read as Latin-1, '¡' Mac Roman), 'deg' or blanks: up to 5 characters that are
# neither digits nor the slash.
_TURN = re.compile(r"turn(?:ing)?", re.IGNORECASE)
# A number standing alone (not part of a word such as 'KVLCC2' or 'KCS-2'), with an optional sign.
_ALONE_NUMBER = re.compile(r"(?<![\w.])(?P<sign>[+-])?\s?(?P<num>\d+(?:\.\d+)?)(?![\w.]|-\w)")
_DEG_AFTER = re.compile(r"^\s*(?:°|deg|\(deg\)|\[deg\])", re.IGNORECASE)


def _turn_rudder(text: str, start: int) -> float | None:
    """Rudder angle of a turning-circle title: after 'turn', the number marked in degrees, else the
    last standalone number (ship names with digits, such as KVLCC2, are words, not numbers)."""
    tail = text[start:]
    nums = list(_ALONE_NUMBER.finditer(tail))
    if not nums:
        return None
    marked = [m for m in nums if _DEG_AFTER.match(tail[m.end():])]
    m = (marked or nums)[-1]
    return float(m["num"])


def _side(text: str) -> str | None:
    t = text.lower()
    if re.search(r"\b(port|ps|p)\b", t) or t.rstrip().endswith("_p"):
        return "port"
    if re.search(r"\b(starboard|stbd|sb|s)\b", t) or t.rstrip().endswith("_s"):
        return "starboard"
    return None


def parse_test_name(text: str) -> dict[str, Any]:
    """Parse a test description (module docstring for the spellings read).

    ``rudder_deg`` is the magnitude; the side comes from words (port, starboard, ps, sb, ...), not from
    a sign, whose convention differs between tanks.

    Parameters
    ----------
    text : str
        The test name or file header line.

    Returns
    -------
    dict
        {"kind": "zigzag"|"turning"|"other", "rudder_deg": float|None (deg), "heading_deg":
        float|None (deg), "first_side": "port"|"starboard"|None}.
    """
    text = text or ""
    m = _ZIGZAG.search(text)
    if m:
        return {"kind": "zigzag", "rudder_deg": float(m["rud"]), "heading_deg": float(m["head"]),
                "first_side": _side(text)}
    m = _TURN.search(text)
    if m:
        return {"kind": "turning", "rudder_deg": _turn_rudder(text, m.end()), "heading_deg": None,
                "first_side": _side(text)}
    return {"kind": "other", "rudder_deg": None, "heading_deg": None, "first_side": _side(text)}


def choose_runs(runs: list[dict[str, Any]], identification: str | None = None) -> tuple[str, list[str]]:
    """Pick the identification run and the validation runs from a runs index.

    Default rule (the paper's): the 20/20 zigzag starting to starboard; failing that, the zigzag
    with rudder closest to 20 deg and the largest heading trigger (starboard first, then name).
    Validation: every other zigzag.

    Parameters
    ----------
    runs : list of dict
        The entries of ``runs/index.json`` (each with ``run_id``, ``kind``, ``rudder_deg`` and
        ``heading_deg`` in deg, ``first_side``).
    identification : str, optional
        A run_id to use instead of the default rule.

    Returns
    -------
    tuple of (str, list of str)
        The identification run_id and the validation run_ids.

    Raises
    ------
    ValueError
        When there is no zigzag, or ``identification`` names no listed run.
    """
    zig = [r for r in runs if r.get("kind") == "zigzag"]
    if identification is not None:
        ids = [r["run_id"] for r in runs]
        if identification not in ids:
            raise ValueError(f"identification run {identification!r} is not among the runs {ids}")
        ident = identification
    else:
        if not zig:
            raise ValueError("no zigzag run to identify from (the default rule takes a zigzag; name "
                             "another run in dataset.toml [roles] identify, or identify --run-id)")

        def key(r):
            return (abs((r.get("rudder_deg") or 0) - paper.IDENT_ZIGZAG_DEG), -(r.get("heading_deg") or 0),
                    0 if r.get("first_side") == "starboard" else 1, r["run_id"])

        ident = sorted(zig, key=key)[0]["run_id"]
    val = [r["run_id"] for r in zig if r["run_id"] != ident]
    return ident, val
