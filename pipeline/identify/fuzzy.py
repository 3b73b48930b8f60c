"""Fuzzy fading memory: the forgetting factor f from the innovation (paper Table 1).

Decisions the paper leaves open (docs/identification.md#the-fuzzy-forgetting-factor), made here and
tested in tests/test_fuzzy.py:

* **Inputs.** e is the yaw-rate innovation (measured minus predicted r, deg/s) of the current
  step and de = e(k) - e(k-1) its change over one step (deg/s per step).  The yaw rate is the
  channel that carries the yaw dynamics being identified, and its innovation is of the size of the
  paper's domain [-0.5, 0.5] (heading innovations are h times smaller, sway ones are in m/s).
  ``FuzzyConfig.channel`` can select 'v' or 'psi' instead.  Inputs outside their domain are
  clipped to its ends (the end terms NB and PB act as shoulders).
* **Membership shapes.** Five triangular terms NB, NM, ZO, PM, PB with peaks equally spaced over
  the domain (ends, quarter points, centre), each reaching zero at its neighbours' peaks: a
  partition of unity (memberships sum to 1 everywhere in the domain).
* **Inference.** Sugeno (zero-order Takagi-Sugeno): rule strength = product of the two
  memberships, each output term a singleton at its natural centre (LL 0.95, LM 0.9625, M 0.975,
  BM 0.9875, BB 1.0 for f in [0.95, 1]), output = strength-weighted mean.  Because the strengths
  are non-negative and sum to 1, f is a convex combination of the centres: always in the f range.
  At a pair of term peaks the output is exactly that rule's singleton, so the rule table can be
  checked directly.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from pipeline.config import FuzzyConfig

TERMS_IN = ("NB", "NM", "ZO", "PM", "PB")
TERMS_OUT = ("LL", "LM", "M", "BM", "BB")

#: Table 1 of the paper, rows de (NB..PB), columns e (NB..PB); entries index TERMS_OUT.
_T = {name: i for i, name in enumerate(TERMS_OUT)}
RULE_TABLE_TEXT = (
    ("LL", "LM", "BM", "BM", "M"),
    ("LM", "LM", "BM", "M", "M"),
    ("LM", "M", "BB", "M", "LM"),
    ("M", "M", "BM", "LM", "LM"),
    ("M", "BM", "BM", "LM", "LL"),
)
RULES = np.array([[_T[c] for c in row] for row in RULE_TABLE_TEXT], dtype=np.int64)

CHANNELS = ("v", "r", "psi")


@njit(cache=True)
def _memberships(x, lo, hi, out):
    """Triangular partition of five terms with peaks at lo, lo+w, ..., hi (w = (hi-lo)/4)."""
    w = (hi - lo) / 4.0
    if x < lo:
        x = lo
    if x > hi:
        x = hi
    for i in range(5):
        d = abs(x - (lo + i * w))
        # 1 - d / w > 0 exactly when d < w (d / w rounds to at most 1 then): the same numbers as
        # max(1 - d / w, 0), with the division only for the two terms that are not zero
        out[i] = 1.0 - d / w if d < w else 0.0


@njit(cache=True)
def fuzzy_factor_nb(e, de, fz, rules):
    """Forgetting factor f in [f_lo, f_hi] from e and de (see module docstring).  Numba-compiled.

    ``fz`` = (e_lo, e_hi, de_lo, de_hi, f_lo, f_hi): the domains of e and de (the channel's unit,
    deg/s for the yaw rate) and the range of f; ``rules`` the (5, 5) table :data:`RULES`."""
    return fuzzy_factor_ws(e, de, fz, rules, np.empty(5), np.empty(5))


@njit(cache=True)
def fuzzy_factor_ws(e, de, fz, rules, me, md):
    """:func:`fuzzy_factor_nb` with caller-owned work arrays ``me``, ``md`` (5,): no allocation, for
    the filter kernel's inner loop (pipeline.identify.fast)."""
    e_lo, e_hi, de_lo, de_hi, f_lo, f_hi = fz[0], fz[1], fz[2], fz[3], fz[4], fz[5]
    _memberships(e, e_lo, e_hi, me)
    _memberships(de, de_lo, de_hi, md)
    step = (f_hi - f_lo) / 4.0
    num = 0.0
    den = 0.0
    for i in range(5):          # de term (row)
        if md[i] == 0.0:
            continue
        for j in range(5):      # e term (column)
            wgt = md[i] * me[j]
            if wgt == 0.0:
                continue
            num += wgt * (f_lo + rules[i, j] * step)
            den += wgt
    if den <= 0.0:              # cannot happen for a partition of unity; keep memory (f = f_hi)
        return f_hi
    f = num / den
    if f < f_lo:                # guard against round-off
        f = f_lo
    if f > f_hi:
        f = f_hi
    return f


def memberships(x: float, domain: tuple[float, float]) -> np.ndarray:
    """Membership degrees of ``x`` in NB, NM, ZO, PM, PB over ``domain`` (sum to 1)."""
    out = np.empty(5)
    _memberships(float(x), float(domain[0]), float(domain[1]), out)
    return out


def forgetting_factor(e: float, de: float, cfg: FuzzyConfig | None = None) -> float:
    """The fuzzy forgetting factor f for innovation ``e`` and its one-step change ``de``.

    Units: those of the innovation channel (deg/s for the default yaw-rate channel).  Returns f in
    ``cfg.f_range`` (paper: [0.95, 1]); f = 1 keeps all memory, smaller f forgets faster.
    """
    cfg = cfg or FuzzyConfig()
    if not (np.isfinite(e) and np.isfinite(de)):
        return float(cfg.f_range[1])
    fz = np.array([*cfg.e_domain, *cfg.de_domain, *cfg.f_range], dtype=float)
    return float(fuzzy_factor_nb(float(e), float(de), fz, RULES))
