"""Non-dimensional Nomoto indices and trust flags for every identified or derived index set.

Non-dimensional indices (docs/indices.md#non-dimensional-indices), at model scale with the run's
approach speed U (m/s) and the model's length between perpendiculars Lpp (m):

    K' = K Lpp / U        (K in 1/s)          T' = T U / Lpp, also T1', T2', T3'   (T in s)

Froude scaling multiplies K by 1/sqrt(scale), T by sqrt(scale), U by sqrt(scale) and Lpp by scale,
so the primed indices are the same at model and full scale.  When Lpp or U is unknown the primed
values are None and the set carries a ``prime_unavailable`` flag saying which.

A flag is ``{"check", "subject", "value", "band", "reason"}``: the check that failed, the number it
is about, its value, the band it should lie in, and one sentence a naval architect can act on.
The checks and why each threshold (pipeline.config.IndicesConfig):

* ``relative_uncertainty``: one-sigma std / |value| above ``max_rel_std`` (0.5): the 95 % interval
  (about +-2 sigma) then reaches zero, so not even the size of the index is established.
* ``invalid_draws``: more than ``max_invalid_fraction`` (5 %) of the Monte Carlo draws from
  N(estimate, covariance) fall where the indices are not defined: a 95 % region of the parameters
  then reaches models without these indices, so the Gaussian bounds are local only.  Two conditions
  (:func:`pipeline.indices.uncertainty.draw_validity`): real positive T1, T2 for T1, T2, T3 (subject
  "T1, T2, T3"), and K > 0, T > 0 for the first-order K, T (subject "K, T").
* ``sign``: K <= 0 contradicts the sign convention of docs/contract.md#run-data (positive rudder
  gives positive yaw rate) or means a reversed rudder; T <= 0 is an unstable or non-physical
  first-order response.
* ``ill_conditioned``: a graphical (standard-method) T longer than the zigzag period: the response
  never approaches steady turning within a cycle, so the fit fixes only K/T and K, T separately are
  ill-conditioned (e.g. K = 8 1/s with T = 578 s).
* identify-side flags (mean NIS outside its chi-square band over the effectively independent steps,
  innovations not white, too little excitation, ...: pipeline/identify/consistency.py) come from
  ``estimates.json`` ``"flags"`` and are carried over unchanged; an estimates file without that key
  is checked here against its own ``consistency.nis_95_band``.
"""

from __future__ import annotations

import math
from typing import Any

from pipeline.config import IndicesConfig

TIME_NAMES = ("T1", "T2", "T3", "T")
PRIME = {"K": "K_prime", "T1": "T1_prime", "T2": "T2_prime", "T3": "T3_prime", "T": "T_prime"}


def flag(check: str, subject: str, value: Any, band: Any, reason: str) -> dict[str, Any]:
    return {"check": check, "subject": subject, "value": value, "band": band, "reason": reason}


def _finite(x: Any) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


# ------------------------------------------------------------------------------ non-dimensional
def length_and_speed(meta: dict[str, Any], index: dict[str, Any] | None = None
                     ) -> tuple[float | None, float | None, list[str]]:
    """(Lpp model m, U m/s, why-missing) from a run's metadata (``lpp``, ``approach_speed``), with
    the dataset's particulars in runs/index.json as the fallback for Lpp (docs/dataset.md)."""
    lpp = _finite(meta.get("lpp"))
    if lpp is None and index:
        part = index.get("particulars") if isinstance(index.get("particulars"), dict) else {}
        ship = index.get("ship") if isinstance(index.get("ship"), dict) else part.get("ship") or {}
        data = index.get("data") if isinstance(index.get("data"), dict) else part.get("data") or {}
        full = _finite((ship or {}).get("lpp_m") or part.get("lpp_m"))
        scale = _finite((data or {}).get("scale") or part.get("scale") or meta.get("model_scale"))
        if full and scale:
            lpp = full / scale
    u = _finite(meta.get("approach_speed"))
    why = []
    if lpp is None or lpp <= 0:
        lpp = None
        why.append("Lpp unknown (no 'lpp' in the run's metadata, no lpp_m and scale in dataset.toml)")
    if u is None or u <= 0:
        u = None
        why.append("approach speed unknown or not ahead (no positive 'approach_speed' in the run's metadata)")
    return lpp, u, why


def primes(values: dict[str, float | None], lpp: float | None, u: float | None) -> dict[str, float | None]:
    """K' = K Lpp/U, T' = T U/Lpp for the names present in ``values`` (None where unknown)."""
    out: dict[str, float | None] = {}
    for name, key in PRIME.items():
        if name not in values:
            continue
        v = _finite(values[name])
        if v is None or lpp is None or u is None:
            out[key] = None
        else:
            out[key] = v * lpp / u if name == "K" else v * u / lpp
    return out


def prime_flags(why: list[str]) -> list[dict[str, Any]]:
    return [flag("prime_unavailable", "K', T'", None, None, "non-dimensional indices not computed: "
                 + "; ".join(why))] if why else []


# -------------------------------------------------------------------------------------- checks
def identified_flags(vals: dict[str, dict[str, float | None]], check: dict | None,
                     estimates: dict[str, Any], cfg: IndicesConfig) -> list[dict[str, Any]]:
    """Flags of one identified index set (Eq. 6 values with stds, the Monte Carlo check, estimates)."""
    out = list(identify_side_flags(estimates))
    for name, d in vals.items():
        v, s = _finite(d.get("value")), _finite(d.get("std"))
        if v is not None and s is not None and v != 0 and s / abs(v) > cfg.max_rel_std:
            unit = "1/s" if name == "K" else "s"
            out.append(flag("relative_uncertainty", name, s / abs(v), [0.0, cfg.max_rel_std],
                            f"{name} = {v:.3g} +- {s:.2g} {unit}: one-sigma uncertainty {s / abs(v):.0%} of "
                            f"the value (above {cfg.max_rel_std:.0%}), its 95 % interval reaches zero"))
    out += sign_flags({n: d.get("value") for n, d in vals.items()})
    if check and _finite(check.get("invalid_fraction")) is not None:
        lim = cfg.max_invalid_fraction
        n = check.get("samples")
        frac = float(check["invalid_fraction"])
        first = _finite(check.get("invalid_fraction_first_order"))
        # second-order validity (real positive T1, T2) concerns T1, T2, T3; K and T have their own
        # condition (K > 0, T > 0, pipeline.indices.uncertainty.draw_validity).  A check without the
        # first-order share (older indices.json) holds the whole set to the second-order condition.
        subject = "T1, T2, T3" if first is not None else "K, T1, T2, T3, T"
        if frac > lim:
            causes = check.get("invalid_causes") or {}
            why = ", ".join(f"{k} {v:.0%}" for k, v in causes.items() if v > 0)
            out.append(flag("invalid_draws", subject, frac, [0.0, lim],
                            f"{frac:.0%} of {n} parameter draws from the filter covariance give no real "
                            f"positive time constants T1, T2 (above {lim:.0%}"
                            + (f"; {why}" if why else "") + "): the second-order model is near the edge "
                            "of its valid region and the one-sigma bounds of T1, T2, T3 are local only"))
        if first is not None and first > lim:
            out.append(flag("invalid_draws", "K, T", first, [0.0, lim],
                            f"{first:.0%} of {n} parameter draws from the filter covariance give K <= 0 "
                            f"or T <= 0 (above {lim:.0%}): not even the sign of the first-order "
                            "response is established"))
    return out


def sign_flags(values: dict[str, Any]) -> list[dict[str, Any]]:
    out = []
    k = _finite(values.get("K"))
    if k is not None and k <= 0:
        out.append(flag("sign", "K", k, "> 0", f"K = {k:.3g} 1/s is not positive: against the "
                        "sign convention of docs/contract.md#run-data (positive rudder gives positive yaw "
                        "rate), a reversed rudder sign or no real rudder response"))
    t = _finite(values.get("T"))
    if t is not None and t <= 0:
        out.append(flag("sign", "T", t, "> 0", f"T = {t:.3g} s is not positive: an unstable or "
                        "non-physical first-order response"))
    return out


def identify_side_flags(estimates: dict[str, Any]) -> list[dict[str, Any]]:
    """The identify stage's own flags (estimates.json "flags"), marked with where they came from.

    An estimates file from before that key existed is checked here for the one identify-side
    number it does hold: the mean NIS against its ``consistency.nis_95_band``.
    """
    if isinstance(estimates.get("flags"), list):
        return [{"subject": "filter", **f, "source": "identify"} for f in estimates["flags"]
                if isinstance(f, dict)]
    cons = estimates.get("consistency") or {}
    nis, band = _finite(cons.get("nis_mean")), cons.get("nis_95_band")
    if nis is None or not (isinstance(band, list) and len(band) == 2):
        return []
    lo, hi = float(band[0]), float(band[1])
    if lo <= nis <= hi:
        return []
    side = "too large: the filter's noise model is too optimistic" if nis > hi else \
        "too small: the filter's noise model is too pessimistic"
    return [flag("nis", "filter", nis, [lo, hi],
                 f"mean NIS {nis:.3g} outside its 95 % chi-square band [{lo:.3g}, {hi:.3g}] ({side}), "
                 "so the parameter covariance and every bound derived from it are not to be trusted")]


def graphical_flags(row: dict[str, Any], period_s: float | None) -> list[dict[str, Any]]:
    """Flags of one graphical/integral K, T row (sign; T longer than the zigzag period; integral
    method's relative uncertainty uses its own least-squares stds)."""
    out = sign_flags(row)
    t = _finite(row.get("T"))
    if t is not None and period_s and t > period_s:
        out.append(flag("ill_conditioned", "T", t, [0.0, period_s],
                        f"T = {t:.3g} s is longer than the zigzag period {period_s:.3g} s: the response "
                        f"never approaches steady turning, so only K/T is determined and K = "
                        f"{_finite(row.get('K')) or float('nan'):.3g} 1/s, T separately are ill-conditioned"))
    return out


def integral_uncertainty_flags(row: dict[str, Any], cfg: IndicesConfig) -> list[dict[str, Any]]:
    out = []
    for name in ("K", "T"):
        v, s = _finite(row.get(name)), _finite(row.get(f"{name}_std"))
        if v and s is not None and s / abs(v) > cfg.max_rel_std:
            out.append(flag("relative_uncertainty", name, s / abs(v), [0.0, cfg.max_rel_std],
                            f"{name} one-sigma uncertainty {s / abs(v):.0%} of the value "
                            f"(above {cfg.max_rel_std:.0%})"))
    return out


def nis_low(f: dict[str, Any]) -> bool:
    """A mean-NIS flag below its band: the filter over-states its uncertainty (the fading memory inflates
    P by design), which makes its bounds conservative, not its estimates wrong."""
    if f.get("check") not in ("nis_mean", "nis"):
        return False
    v, band = _finite(f.get("value")), f.get("band")
    return v is not None and isinstance(band, list) and len(band) == 2 and _finite(band[0]) is not None \
        and v < float(band[0])


def blocking(flags: list[dict[str, Any]], names: tuple[str, ...]) -> list[dict[str, Any]]:
    """The flags that forbid designing from indices ``names``: any flag whose subject (one name or a
    comma-separated list) names one of them, or about the filter (NIS above its band, whiteness,
    excitation ...).  Missing primes and a NIS below its band (:func:`nis_low`) do not."""
    out = []
    for f in flags:
        if f.get("check") == "prime_unavailable" or nis_low(f):
            continue
        subj = str(f.get("subject", ""))
        if subj == "filter" or {s.strip() for s in subj.split(",")} & set(names):
            out.append(f)
    return out


def reasons(flags: list[dict[str, Any]]) -> str:
    return "; ".join(f["reason"] for f in flags)
