"""Online identification of the sway-yaw model (docs/identification.md): pure functions on arrays and runs.

Conventions
-----------
* Data units of docs/contract.md#run-data throughout (v m/s, r deg/s, psi deg, delta deg, time s); the
  parameters are those of pipeline.model in the same units (paper Table 4).
* Sample 0 initialises the filter: x0 = (v0, r0, psi0 measured; theta0 from FilterConfig), P0 =
  diag(r_std^2 for the measured states, theta0_std^2).  Every later sample k is one time update
  with the rudder delta[k-1] and one measurement update with (v, r, psi)[k].
* A run without a usable sway-velocity column is identified from r and psi alone (measurement
  (r, psi), v starts at 0 with one-sigma FilterConfig.v0_std).  v is then a hidden state and the six
  parameters are not unique (a similarity transform of (v, r) leaves r and psi unchanged); b11 is
  pinned at 0 and a21 at its initial value (see :func:`initial_state`), the other four are
  identified, and the Nomoto indices, which fix the rudder-to-yaw transfer function, are unique.
* Trace row 0 holds the initial state; its prediction, innovation and NIS are NaN.
"""

from __future__ import annotations

import dataclasses
import time as _time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from pipeline.catalog import data_label, is_builtin_tank_run
from pipeline.config import FilterConfig
from pipeline.errors import FilterError, InputError, ModelError
from pipeline.identify import fast
from pipeline.identify.baseline import make_filter, run_ffm_ukf
from pipeline.identify.consistency import consistency as filter_consistency
from pipeline.identify.consistency import flags as consistency_flags
from pipeline.identify.fuzzy import CHANNELS, RULES, forgetting_factor
from pipeline.identify.srukf import StepModel, srukf_run_reference, ut_weights
from pipeline.io import Run
from pipeline.model import PARAM_NAMES, STATE_NAMES, nomoto_indices
from pipeline.results import Result, optional, spread

ALGORITHMS = ("srukf-ffm", "ffm-ukf")
STATE9 = STATE_NAMES + PARAM_NAMES

_FAIL_WHAT = {1: "time update (point 0 downdate)", 2: "innovation factor (point 0 downdate)",
              3: "measurement update downdate"}


@dataclass
class FilterOutput:
    """Per-step results of a filter run over N samples (innov has 3 columns, NaN when unmeasured)."""

    x_prior: np.ndarray
    x: np.ndarray
    std: np.ndarray
    innov: np.ndarray
    nis: np.ndarray
    f: np.ndarray
    x_final: np.ndarray
    P_final: np.ndarray
    seconds: float
    chol_failures: np.ndarray | None = None


def measured_indices(v: np.ndarray | None) -> np.ndarray:
    """Indices of the measured states among (v, r, psi).

    Parameters
    ----------
    v : ndarray or None
        The sway-velocity column (m/s), None where the run has none.

    Returns
    -------
    ndarray of int
        (0, 1, 2), or (1, 2) when ``v`` is absent or not finite everywhere.
    """
    if v is None or not np.all(np.isfinite(v)):
        return np.array([1, 2], dtype=np.int64)
    return np.array([0, 1, 2], dtype=np.int64)


def fuzzy_channel(cfg: FilterConfig, meas_idx) -> int:
    """Position in ``meas_idx`` of the innovation that feeds the fuzzy factor (-1: none)."""
    ch = cfg.fuzzy.channel
    if ch not in CHANNELS:
        raise InputError(f"fuzzy channel must be one of {CHANNELS}, got {ch!r}")
    if not cfg.use_fuzzy:
        return -1
    state = CHANNELS.index(ch)
    idx = list(np.asarray(meas_idx))
    return idx.index(state) if state in idx else -1


def initial_state(y0: np.ndarray, meas_idx, cfg: FilterConfig) -> tuple[np.ndarray, np.ndarray]:
    """The filter's initial state and covariance from the first measured sample (module docstring).

    Parameters
    ----------
    y0 : ndarray, shape (3,)
        The first sample's (v m/s, r deg/s, psi deg); v may be NaN.
    meas_idx : array of int
        The measured states (:func:`measured_indices`).
    cfg : FilterConfig
        ``r_std``, ``v0_std``, ``theta0``, ``theta0_std`` and ``pin_std`` are read.

    Returns
    -------
    x0 : ndarray, shape (9,)
        (v m/s, r deg/s, psi deg, then the six parameters in the units of pipeline.model).
    P0 : ndarray, shape (9, 9)
        Diagonal covariance in the squares of those units.
    """
    x0 = np.zeros(9)
    std = np.zeros(9)
    for i in range(3):
        if i in list(meas_idx):
            x0[i] = y0[i]
            std[i] = cfg.r_std[i]
        else:
            x0[i] = 0.0
            std[i] = cfg.v0_std
    x0[3:] = cfg.theta0
    std[3:] = cfg.theta0_std
    if 0 not in list(meas_idx):
        # v hidden: (v, r) -> (c v + d r, r) leaves r and psi unchanged, so two parameters are
        # unobservable and a free filter drifts along them until its covariance breaks down.  Pin
        # them: b11 = 0 and a21 = theta0's a21 (one-sigma cfg.pin_std, no process noise).  Every
        # rudder-to-yaw transfer function K (1 + T3 s) / ((1 + T1 s)(1 + T2 s)) stays reachable.
        x0[3 + 4] = 0.0
        std[3 + 4] = cfg.pin_std
        std[3 + 2] = cfg.pin_std
    return x0, np.diag(std ** 2)


def _check_cfg(cfg: FilterConfig) -> None:
    if len(cfg.q_std) != 9 or len(cfg.r_std) != 3 or len(cfg.theta0) != 6 or len(cfg.theta0_std) != 6:
        raise InputError("filter configuration: q_std needs 9 values, r_std 3, theta0 and theta0_std 6")
    if min(cfg.r_std) <= 0 or min(cfg.theta0_std) <= 0:
        raise InputError("filter configuration: r_std and theta0_std must be positive")


def step_model(cfg: FilterConfig, meas_idx, h: float) -> StepModel:
    """The filter's step settings from ``cfg``: Q (all nine states) and R (the measured channels
    ``meas_idx``) as diagonal square roots, the unscented weights, step ``h`` (s)."""
    meas_idx = np.asarray(meas_idx, dtype=np.int64)
    return StepModel(h=h, sq_q=np.diag(np.asarray(cfg.q_std, float)),
                     sq_r=np.diag(np.asarray(cfg.r_std, float)[meas_idx]), meas_idx=meas_idx,
                     weights=ut_weights(9, cfg.alpha, cfg.beta, cfg.kappa))


def kernel_settings(cfg: FilterConfig, meas_idx, h: float) -> fast.KernelSettings:
    """:func:`step_model` with the fuzzy forgetting settings, as the compiled kernels read them."""
    meas_idx = np.asarray(meas_idx, dtype=np.int64)
    fz = np.array([*cfg.fuzzy.e_domain, *cfg.fuzzy.de_domain, *cfg.fuzzy.f_range], dtype=float)
    return fast.KernelSettings(model=step_model(cfg, meas_idx, h), chan=fuzzy_channel(cfg, meas_idx),
                               fz=fz, rules=RULES)


def run_filter(algorithm: str, x0, P0, Y3: np.ndarray, delta_prev: np.ndarray, *, h: float,
               cfg: FilterConfig, meas_idx) -> FilterOutput:
    """Run one algorithm over a window.  Times the loop alone.

    Parameters
    ----------
    algorithm : str
        'srukf-ffm' or 'ffm-ukf'.
    x0, P0 : numpy.ndarray
        Initial posterior (9,), (9, 9) (v m/s, r deg/s, psi deg, the parameters in their units).
    Y3 : numpy.ndarray
        (N, 3) measured v m/s, r deg/s, psi deg; only the columns ``meas_idx`` are used.
    delta_prev : numpy.ndarray
        (N,) rudder over the step into each sample, deg.
    h : float
        Step, s.
    cfg : FilterConfig
        Filter settings.
    meas_idx : array of int
        The measured states among (v, r, psi) = (0, 1, 2).

    Returns
    -------
    FilterOutput
        Per-step results, final posterior and the loop's wall time (s).
    """
    _check_cfg(cfg)
    meas_idx = np.asarray(meas_idx, dtype=np.int64)
    Y = np.ascontiguousarray(Y3[:, meas_idx], dtype=float)
    dp = np.ascontiguousarray(delta_prev, dtype=float)
    n, m = Y.shape
    settings = kernel_settings(cfg, meas_idx, h)
    chan = settings.chan
    innov3 = np.full((n, 3), np.nan)
    if algorithm == "ffm-ukf":
        ukf, chol = make_filter(x0, P0, h=h, q_std=cfg.q_std, r_std=np.asarray(cfg.r_std, float)[meas_idx],
                                meas_idx=meas_idx, alpha=cfg.alpha, beta=cfg.beta, kappa=cfg.kappa)
        t0 = _time.perf_counter()
        out, xf, Pf = run_ffm_ukf(ukf, chol, Y, dp, fuzzy_cfg=cfg.fuzzy if chan >= 0 else None, chan=chan)
        secs = _time.perf_counter() - t0
        innov3[:, meas_idx] = out["innov"]
        return FilterOutput(out["x_prior"], out["x"], out["std"], innov3, out["nis"], out["f"], xf, Pf,
                            secs, out["chol_failures"])
    if algorithm != "srukf-ffm":
        raise InputError(f"unknown algorithm {algorithm!r} (choose {' or '.join(ALGORITHMS)})")
    try:
        S0 = np.linalg.cholesky(np.asarray(P0, float))
    except np.linalg.LinAlgError:
        raise FilterError("initial covariance is not positive definite") from None
    if cfg.fast:
        fast.run(x0, S0, Y[:1], dp[:1], settings)                  # compile / warm up
        t0 = _time.perf_counter()
        got = fast.run(x0, S0, Y, dp, settings)
        secs = _time.perf_counter() - t0
        if got.status != 0:
            raise FilterError(f"SR-UKF {_FAIL_WHAT[got.status]} failed at step {got.step}: covariance lost "
                              "positive definiteness")
        x_prior, x, std, innov, nis, f = got.x_prior, got.x_post, got.std, got.innov, got.nis, got.f
        xf, Sf = got.x, got.S
    else:
        def f_of(innov, prev):
            e = float(innov[chan])
            return forgetting_factor(e, e - prev, cfg.fuzzy), e

        t0 = _time.perf_counter()
        ref = srukf_run_reference(x0, S0, Y, dp, settings.model, f_of=f_of if chan >= 0 else None)
        secs = _time.perf_counter() - t0
        x_prior, x, innov, nis, f = ref["x_prior"], ref["x"], ref["innov"], ref["nis"], ref["f"]
        std = np.sqrt(np.einsum("kij,kij->ki", ref["S"], ref["S"]))
        xf, Sf = ref["x"][-1] if n else np.asarray(x0, float), ref["S"][-1] if n else S0
    innov3[:, meas_idx] = innov
    return FilterOutput(x_prior, x, std, innov3, nis, f, np.array(xf), Sf @ Sf.T, secs)


@dataclass
class Identification:
    """Result of identifying one run with one algorithm."""

    algorithm: str
    samples: int
    dt: float
    parameters: dict[str, float]
    covariance: np.ndarray
    indices: dict[str, float] | None
    indices_error: str | None
    timing: dict[str, float]
    trace: pd.DataFrame
    x_final: np.ndarray
    P_final: np.ndarray
    measured: list[str]
    consistency: dict[str, Any] = field(default_factory=dict)
    filterpy_failures: int | None = None
    flags: list[dict[str, Any]] = field(default_factory=list)
    window: str | None = None


def _arrays(run: Run) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = run.col("time")
    d = run.col("delta")
    v = run.frame["v"].to_numpy(dtype=float) if "v" in run.frame.columns else np.full(t.size, np.nan)
    Y3 = np.column_stack([v, run.col("r"), run.col("psi")])
    for j, name in enumerate(STATE_NAMES):
        if j > 0 and not np.all(np.isfinite(Y3[:, j])):
            row = int(np.flatnonzero(~np.isfinite(Y3[:, j]))[0])
            raise InputError("NaN or infinite value in the run", file=run.name, row=row + 1, column=name)
    if not np.all(np.isfinite(d)):
        row = int(np.flatnonzero(~np.isfinite(d))[0])
        raise InputError("NaN or infinite value in the run", file=run.name, row=row + 1, column="delta")
    return t, d, Y3


def identify_arrays(time: np.ndarray, delta: np.ndarray, Y3: np.ndarray, cfg: FilterConfig, *,
                    algorithm: str | None = None, samples: int | None = None,
                    name: str = "run") -> Identification:
    """Identify the six parameters from the first ``samples`` samples.

    Parameters
    ----------
    time : ndarray, shape (N,)
        Uniform time, s.
    delta : ndarray, shape (N,)
        Rudder angle, deg.
    Y3 : ndarray, shape (N, 3)
        Measured v (m/s; a NaN column when absent), r (deg/s), psi (deg).
    cfg : FilterConfig
        The filter's settings.
    algorithm : str, optional
        ``"srukf-ffm"`` or ``"ffm-ukf"`` (the filterpy baseline); None: ``cfg.algorithm``.
    samples : int, optional
        Samples of the window (at least 3); None: ``cfg.samples``.
    name : str
        The run's name, for messages.

    Returns
    -------
    Identification
        Parameters (units of pipeline.model), their 6 x 6 covariance, the Nomoto indices (K 1/s, T1 T2
        T3 T s) and the per-sample trace.

    Raises
    ------
    InputError
        Too few samples, a non-positive time step or unusable columns (one line naming the run).
    """
    algorithm = algorithm or cfg.algorithm
    n_req = int(samples if samples is not None else cfg.samples)
    if n_req < 3:
        raise InputError(f"--samples must be at least 3, got {n_req}")
    n = min(n_req, len(time))
    if n < 10:
        raise InputError(f"too few samples to identify from ({len(time)})", file=name)
    time, delta, Y3 = time[:n], delta[:n], Y3[:n]
    h = float(time[1] - time[0])
    if not h > 0:
        raise InputError("time step is not positive", file=name, column="time")
    v = Y3[:, 0]
    fin = np.isfinite(v)
    if fin.any() and not fin.all():
        k = int(np.flatnonzero(~fin)[0])
        raise InputError(f"sway velocity has NaN or infinite values ({int((~fin).sum())} of {n} in the "
                         "window): refused rather than silently identified from r and psi only",
                         file=name, row=k + 1, column="v")
    meas_idx = measured_indices(Y3[:, 0])
    r_source = "paper setting (FilterConfig.r_std)"
    if cfg.measurement_noise == "data":
        r_std, r_source = measured_noise_std(Y3, meas_idx, cfg.r_std)
        cfg = dataclasses.replace(cfg, r_std=r_std)
    elif cfg.measurement_noise != "paper":
        raise InputError(f"measurement_noise must be 'paper' or 'data', got {cfg.measurement_noise!r}")
    x0, P0 = initial_state(Y3[0], meas_idx, cfg)
    q_estimate = None
    if cfg.process_noise == "data":
        q_estimate = estimate_process_noise(x0, P0, Y3[1:], delta[:-1], h=h, cfg=cfg, meas_idx=meas_idx)
        cfg = dataclasses.replace(cfg, q_std=tuple(q_estimate["q_std_all"]))
    elif cfg.process_noise != "paper":
        raise InputError(f"process_noise must be 'paper' or 'data', got {cfg.process_noise!r}")
    out = run_filter(algorithm, x0, P0, Y3[1:], delta[:-1], h=h, cfg=cfg, meas_idx=meas_idx)
    cov = out.P_final[3:, 3:]
    theta = out.x_final[3:]
    try:
        idx, idx_err = nomoto_indices(theta), None
    except ModelError as exc:
        idx, idx_err = None, str(exc)
    steps = n - 1
    trace = make_trace(time, delta, Y3, x0, np.sqrt(np.diag(P0)), out)
    names = [STATE_NAMES[i] for i in meas_idx]
    consistency = filter_consistency(out.nis, out.innov[:, meas_idx], names, level=cfg.consistency_level)
    consistency["innovation_rms"] = {STATE_NAMES[i]: float(np.sqrt(np.mean(out.innov[:, i] ** 2)))
                                     for i in meas_idx}
    consistency["f_mean"], consistency["f_min"] = float(np.mean(out.f)), float(np.min(out.f))
    consistency["r_std"] = {STATE_NAMES[i]: float(cfg.r_std[i]) for i in meas_idx}
    consistency["r_std_source"] = r_source
    consistency["q_std"] = {STATE_NAMES[i]: float(cfg.q_std[i]) for i in range(3)}
    consistency["q_std_source"] = (q_estimate["method"] if q_estimate is not None
                                   else "paper setting (FilterConfig.q_std)")
    if q_estimate is not None:
        consistency["noise_estimate"] = {k: v for k, v in q_estimate.items() if k != "q_std_all"}
    flags = trust_flags(consistency, idx, idx_err, delta, cfg)
    fails = int(out.chol_failures[-1]) if out.chol_failures is not None and steps else None
    return Identification(
        algorithm=algorithm, samples=n, dt=h,
        parameters=dict(zip(PARAM_NAMES, map(float, theta), strict=True)),
        covariance=cov, indices=idx, indices_error=idx_err,
        timing={"seconds_total": out.seconds, "seconds_per_step": out.seconds / max(steps, 1)},
        trace=trace, x_final=out.x_final, P_final=out.P_final,
        measured=[STATE_NAMES[i] for i in meas_idx], consistency=consistency, filterpy_failures=fails,
        flags=flags)


def measured_noise_std(Y3: np.ndarray, meas_idx, fallback) -> tuple[tuple[float, float, float], str]:
    """One-sigma measurement noise of v (m/s), r (deg/s), psi (deg) measured from the data.

    For y = s + e with white noise e of std sigma, the second difference y(k) - 2 y(k+1) + y(k+2) has
    the noise variance 6 sigma^2 plus the signal's s'' h^2, which for ship motions at a tank's logging
    step is far smaller (a 2 deg/s yaw-rate swing of 30 s period gives 6e-4 deg/s at 0.08 s against a
    logger's 0.05 deg/s noise x sqrt 6).  The spread is taken as 1.4826 x the median absolute deviation
    (the Gaussian std, robust to the few kinks at rudder executes).  A channel without measurable
    noise (zero spread: quantised or smoothed data, no evidence about the noise), or not measured,
    keeps ``fallback`` (the paper's setting): R must stay positive.
    """
    out = [float(x) for x in fallback]
    measured = []
    for i in meas_idx:
        d2 = np.diff(np.asarray(Y3[:, i], float), 2)
        d2 = d2[np.isfinite(d2)]
        if len(d2) < 10:
            continue
        sigma = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / np.sqrt(6.0)
        if sigma > 0:
            out[i] = sigma
            measured.append(STATE_NAMES[i])
    src = ("measured from the run (robust second differences)" + (f" for {', '.join(measured)}" if
           len(measured) < len(meas_idx) else "") if measured else "paper setting (no measurable noise)")
    return (out[0], out[1], out[2]), src


def _mean_nis(x0, P0, Y3, delta_prev, *, h: float, cfg: FilterConfig, meas_idx) -> float:
    """Mean NIS of the SR-UKF-FFM (compiled kernel) over the window; inf when the filter breaks down."""
    try:
        out = run_filter("srukf-ffm", x0, P0, Y3, delta_prev, h=h, cfg=dataclasses.replace(cfg, fast=True),
                         meas_idx=meas_idx)
    except FilterError:
        return float("inf")
    nis = out.nis[np.isfinite(out.nis)]
    return float(np.mean(nis)) if nis.size else float("inf")


def estimate_process_noise(x0, P0, Y3: np.ndarray, delta_prev: np.ndarray, *, h: float, cfg: FilterConfig,
                           meas_idx) -> dict[str, Any]:
    """Process noise Q of the motion states from the data: covariance matching of the mean NIS.

    Structure: q_i = c r_i for each measured state i (one-sigma per step, in its unit: v m/s, r deg/s,
    psi deg), r_i the measurement noise in ``cfg.r_std`` (measured from the run when
    ``measurement_noise = 'data'``); an unmeasured v takes c x ``cfg.q_std[0]`` (the paper's, scaled
    alike); the parameters keep ``cfg.q_std[3:]``.  The innovation covariance the filter predicts is
    right on average when the mean NIS equals m, the number of measured channels (Bar-Shalom, Li &
    Kirubarajan 2001, sec. 5.4); the mean NIS falls as c grows (more process noise, wider predicted
    innovations), so c is found by bisection on log c within ``cfg.process_scale_bracket`` until the
    mean NIS is within ``cfg.process_nis_tolerance`` of m (at most ``cfg.process_max_bisections``
    halvings).  When the bracket does not hold the crossing, the end nearer to it is taken and
    ``matched`` is False.

    Parameters
    ----------
    x0, P0 : initial posterior (9,), (9, 9) (units of the module docstring).
    Y3 : (N, 3) measured v m/s, r deg/s, psi deg after sample 0.  delta_prev : (N,) rudder, deg.
    h : step, s.  cfg : filter settings (R used as given).  meas_idx : measured states.

    Returns
    -------
    dict
        ``method`` (one line), ``scale`` c (-), ``q_std`` {state: one-sigma per step}, ``q_std_all``
        (the nine q_std), ``mean_nis`` at c, ``expected`` m, ``matched``, ``evaluations``, ``bracket``.
    """
    meas = [int(i) for i in np.asarray(meas_idx)]
    m = len(meas)
    base = np.array([cfg.r_std[i] if i in meas else cfg.q_std[i] for i in range(3)], dtype=float)

    def q_of(c: float) -> tuple[float, ...]:
        return (*(c * base), *cfg.q_std[3:])

    def nis_of(c: float) -> float:
        return _mean_nis(x0, P0, Y3, delta_prev, h=h, cfg=dataclasses.replace(cfg, q_std=q_of(c)),
                         meas_idx=meas_idx)

    lo, hi = (float(x) for x in cfg.process_scale_bracket)
    n_lo, n_hi = nis_of(lo), nis_of(hi)
    evals = 2
    matched = True
    if n_lo <= m:                        # even the least process noise leaves the filter under-confident
        c, nis, matched = lo, n_lo, abs(n_lo / m - 1) <= cfg.process_nis_tolerance
    elif n_hi >= m:                      # even the most leaves it over-confident
        c, nis, matched = hi, n_hi, abs(n_hi / m - 1) <= cfg.process_nis_tolerance
    else:
        c, nis = hi, n_hi
        for _ in range(cfg.process_max_bisections):
            c = float(np.sqrt(lo * hi))
            nis = nis_of(c)
            evals += 1
            if abs(nis / m - 1) <= cfg.process_nis_tolerance:
                break
            lo, hi = (c, hi) if nis > m else (lo, c)
        # the bisections ran out before the mean NIS came within the tolerance: not matched
        matched = abs(nis / m - 1) <= cfg.process_nis_tolerance
    q = q_of(c)
    return {"method": ("covariance matching of the mean NIS: q of each measured state = c x its "
                       "measurement noise, c by bisection so that the mean NIS of the identification "
                       f"window equals m = {m}"),
            "scale": c, "q_std": {STATE_NAMES[i]: float(q[i]) for i in range(3)},
            "q_std_all": [float(x) for x in q], "mean_nis": nis, "expected": float(m),
            "matched": bool(matched), "evaluations": evals,
            "bracket": [float(x) for x in cfg.process_scale_bracket]}


def trust_flags(consistency: dict[str, Any], indices: dict[str, float] | None, indices_error: str | None,
                delta: np.ndarray, cfg: FilterConfig) -> list[dict[str, Any]]:
    """Checks an identification result fails, each ``{"check", "value", "band", "reason"}``.

    - ``nis_mean``: mean NIS outside its chi-square band over the effectively independent steps, and
      ``innovation_whiteness``: lag-1 autocorrelation of an innovation outside its band
      (:mod:`pipeline.identify.consistency` says why each band).
    - ``nomoto_K``: K <= 0 (docs/contract.md#run-data: positive delta makes r positive, so K > 0 for any ship
      logged in the canonical sign): the run taught the filter nothing true about the rudder.
    - ``nomoto_indices``: no real positive time constants (indices_error).
    - ``rudder_range``: the rudder moved less than FilterConfig.min_rudder_range in the window
      (identify_run refuses this; identify_arrays only flags it).
    """
    flags: list[dict[str, Any]] = consistency_flags(consistency)
    if indices is not None and not indices.get("K", 0) > 0:
        flags.append({"check": "nomoto_K", "value": indices.get("K"), "band": [0.0, None],
                      "reason": "K <= 0: positive rudder must make the yaw rate positive "
                                "(docs/contract.md#run-data); "
                                "the run did not identify the rudder's effect (too little excitation, noise, "
                                "or a reversed rudder sign)"})
    if indices_error:
        flags.append({"check": "nomoto_indices", "value": None, "band": None,
                      "reason": f"no Nomoto indices: {indices_error}"})
    rng = float(np.ptp(delta)) if len(delta) else 0.0
    if rng < cfg.min_rudder_range:
        flags.append({"check": "rudder_range", "value": rng, "band": [cfg.min_rudder_range, None],
                      "reason": "the rudder hardly moves in the identification window: the rudder "
                                "coefficients are the prior's"})
    return flags


def identification_window(run: Run, cfg: FilterConfig, *, samples: int | None = None) -> tuple[int, str]:
    """Number of samples to identify from, and how it was chosen (scale-free when configured).

    ``samples`` (the --samples option) wins; else ``cfg.window_s`` seconds; else
    ``cfg.window_half_periods`` zigzag half-periods after the first rudder execute (executes: the
    rudder crossing half its largest angle toward the new side); else ``cfg.samples`` (585, the
    paper's setting: 46.8 s at 0.08 s, 3.4 half-periods of the virtual tank's KCS 20/20 zigzag at model
    scale, but 2.4 of the HSVA KVLCC2 20/10 one: a fixed number of samples is not scale-free, so a
    dataset sets its window in its dataset.toml ``[identify]``).
    """
    t = run.col("time")
    dt = float(t[1] - t[0]) if len(t) > 1 else cfg.dt
    if samples is not None:
        return int(samples), f"{int(samples)} samples (option)"
    if cfg.window_s is not None:
        n = int(round(cfg.window_s / dt)) + 1
        return n, f"{cfg.window_s:g} s at the run's scale ({n} samples)"
    if cfg.window_half_periods is not None:
        from pipeline.ingest.checks import rudder_phases

        ph = rudder_phases(t, run.col("delta"))
        starts = [a for a, _, _ in ph]
        k = int(np.ceil(cfg.window_half_periods))
        if len(starts) < k + 1:
            raise InputError(f"the run has {max(len(starts) - 1, 0)} zigzag half-periods after its first "
                             f"execute, the identification window needs {cfg.window_half_periods:g}",
                             file=run.name, column="delta")
        frac = cfg.window_half_periods - (k - 1)
        t_end = t[starts[k - 1]] + frac * (t[starts[k]] - t[starts[k - 1]])
        n = int(np.searchsorted(t, t_end)) + 1
        return n, f"{cfg.window_half_periods:g} zigzag half-periods ({n} samples, {t[n - 1]:.3g} s)"
    paper = int(cfg.samples) == FilterConfig.samples
    return int(cfg.samples), f"{int(cfg.samples)} samples" + (" (paper setting)" if paper else "")


def make_trace(time, delta, Y3, x0, std0, out: FilterOutput) -> pd.DataFrame:
    """The per-step trace of catalog.py (row 0 = initial state)."""
    n = len(time)
    cols: dict[str, Any] = {"time": time, "delta": delta, "v": Y3[:, 0], "r": Y3[:, 1], "psi": Y3[:, 2]}
    x_prior = np.vstack([np.full(9, np.nan), out.x_prior])
    x = np.vstack([x0, out.x])
    std = np.vstack([std0, out.std])
    for i, s in enumerate(STATE_NAMES):
        cols[f"{s}_pred"] = x_prior[:, i]
    for i, s in enumerate(STATE_NAMES):
        cols[f"{s}_est"] = x[:, i]
    for i, p in enumerate(PARAM_NAMES):
        cols[p] = x[:, 3 + i]
    for i, p in enumerate(PARAM_NAMES):
        cols[f"{p}_std"] = std[:, 3 + i]
    cols["f"] = np.concatenate([[1.0], out.f])
    innov = np.vstack([np.full(3, np.nan), out.innov])
    for i, s in enumerate(STATE_NAMES):
        cols[f"innov_{s}"] = innov[:, i]
    cols["nis"] = np.concatenate([[np.nan], out.nis])
    if out.chol_failures is not None:
        cols["chol_failures"] = np.concatenate([[0], out.chol_failures]).astype(np.int64)
    assert all(len(c) == n for c in cols.values())
    return pd.DataFrame(cols)


def identify_run(run: Run, cfg: FilterConfig | None = None, *, algorithm: str | None = None,
                 samples: int | None = None) -> Identification:
    """Identify a processed run (docs/contract.md#run-data columns) from its identification window.

    Parameters
    ----------
    run : Run
        A processed run: time s, delta deg, r deg/s, psi deg, and v m/s where measured.
    cfg : FilterConfig, optional
        The filter's settings; None: the defaults (the paper's).
    algorithm : str, optional
        ``"srukf-ffm"`` or ``"ffm-ukf"``; None: ``cfg.algorithm``.
    samples : int, optional
        The window's length in samples; None: :func:`identification_window` chooses it.

    Returns
    -------
    Identification
        Parameters (units of pipeline.model), covariance, Nomoto indices (K 1/s, T1 T2 T3 T s), trace;
        results that fail a check carry ``flags`` (:func:`trust_flags`), ``window`` says how the window
        was chosen.

    Raises
    ------
    InputError
        One line naming the run: a window of fewer than ``cfg.min_samples`` samples, a rudder that
        moves less than ``cfg.min_rudder_range`` deg in it (nothing to learn the rudder coefficients
        from), a sway velocity with NaN values.
    """
    cfg = cfg or FilterConfig()
    t, d, Y3 = _arrays(run)
    n, how = identification_window(run, cfg, samples=samples)
    n_eff = min(n, len(t))
    if n_eff < cfg.min_samples:
        raise InputError(f"too few samples to identify from: {n_eff} (need at least {cfg.min_samples}: "
                         "3 states and 6 parameters cannot be fixed by fewer)", file=run.name)
    rng = float(np.ptp(d[:n_eff]))
    if rng < cfg.min_rudder_range:
        raise InputError(f"no rudder excitation: the rudder moves {rng:.3g} deg within the identification "
                         f"window (at least {cfg.min_rudder_range:g} deg needed to learn its effect)",
                         file=run.name, column="delta")
    ident = identify_arrays(t, d, Y3, cfg, algorithm=algorithm, samples=n, name=run.name)
    ident.window = how
    return ident


@dataclass(frozen=True)
class FilterState(Result):
    """The filter's final posterior: state names, x (9,) and P (9, 9) in the units of the module
    docstring (v m/s, r deg/s, psi deg, then the six parameters)."""

    names: list[str]
    x: list[float]
    P: list[list[float]]


@dataclass(frozen=True)
class FilterSettings(Result):
    """The filter settings an identification ran with (docs/contract.md#identifyalgorithm-identify):
    q_std (9,) the Q used (estimated or the paper's, one-sigma per step in each state's unit), r_std
    (3,) the R used (v m/s, r deg/s, psi deg), the unscented-transform alpha, beta, kappa (-), the prior
    theta0 and its one-sigma, the fuzzy forgetting settings, and whether the numba kernel ran."""

    q_std: list[float]
    alpha: float
    beta: float
    measurement_noise: str
    process_noise: str
    r_std: list[float]
    kappa: float
    theta0: list[float]
    theta0_std: list[float]
    use_fuzzy: bool
    fuzzy: dict[str, Any]
    fast_path: bool


@dataclass(frozen=True)
class Estimates(Result):
    """``identify/<algorithm>/estimates.json`` (keys, units: docs/contract.md#identifyalgorithm-identify).

    ``parameters`` and ``parameters_std`` map a11 .. b21 to their value and one-sigma (units of
    pipeline.model); ``covariance`` is their 6 x 6 covariance; ``indices`` the Nomoto indices (K 1/s,
    T's s) or None with ``indices_error``; ``dt`` the step (s); ``timing`` names the file holding the
    seconds.  Keys left out when None: indices_error, window, filterpy_failures, note.
    """

    algorithm: str
    samples: int
    parameters: dict[str, float]
    covariance: list[list[float]]
    indices: dict[str, float] | None
    timing: dict[str, str]
    run_id: str | None
    dataset: str | None
    provenance: str | None
    source_file: str | None
    test_name: str | None
    parameters_std: dict[str, float]
    measured: list[str]
    dt: float
    consistency: dict[str, Any]
    filter_state: FilterState
    settings: FilterSettings
    indices_error: str | None = optional()
    flags: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    noise_estimate: dict[str, Any] = dataclasses.field(default_factory=dict)
    window: str | None = optional()
    filterpy_failures: int | None = optional()
    note: str | None = optional()
    label: dict[str, str] = spread()


def estimates(ident: Identification, meta: dict[str, Any], cfg: FilterConfig, *,
              dataset: str | None = None) -> Estimates:
    """The typed content of estimates.json for one identification.

    Parameters
    ----------
    ident : Identification
        The result of :func:`identify_run` or :func:`identify_arrays`.
    meta : dict
        The run's metadata (run_id, provenance, source_file, test_name).
    cfg : FilterConfig
        The settings it ran with.
    dataset : str, optional
        The dataset's name.

    Returns
    -------
    Estimates
        ``.to_json()`` is the file's content.
    """
    std = np.sqrt(np.maximum(np.diag(ident.covariance), 0.0))
    cons = ident.consistency
    settings = FilterSettings(
        q_std=[(cons.get("q_std") or {}).get(n, cfg.q_std[i]) if i < 3 else cfg.q_std[i]
               for i, n in enumerate(STATE9)],            # the Q used (estimated or paper)
        alpha=cfg.alpha, beta=cfg.beta,
        measurement_noise=cfg.measurement_noise, process_noise=cfg.process_noise,
        r_std=[(cons.get("r_std") or {}).get(n, cfg.r_std[i])
               for i, n in enumerate(STATE_NAMES)],      # the R used (measured or paper)
        kappa=cfg.kappa, theta0=list(cfg.theta0), theta0_std=list(cfg.theta0_std),
        use_fuzzy=cfg.use_fuzzy, fuzzy={"e_domain": list(cfg.fuzzy.e_domain),
                                        "de_domain": list(cfg.fuzzy.de_domain),
                                        "f_range": list(cfg.fuzzy.f_range), "channel": cfg.fuzzy.channel},
        fast_path=bool(cfg.fast) if ident.algorithm == "srukf-ffm" else False)
    return Estimates(
        algorithm=ident.algorithm, samples=ident.samples, parameters=ident.parameters,
        covariance=ident.covariance.tolist(), indices=ident.indices,
        # the filter loop's seconds differ run to run: they go to timing.json beside this file (written
        # by the identify command), so the result's bytes do not (docs/operations.md)
        timing={"file": "timing.json"},
        run_id=meta.get("run_id"), dataset=dataset, provenance=meta.get("provenance", "measured"),
        source_file=meta.get("source_file"), test_name=meta.get("test_name"),
        parameters_std=dict(zip(PARAM_NAMES, map(float, std), strict=True)),
        measured=ident.measured, dt=ident.dt, consistency=cons,
        filter_state=FilterState(names=list(STATE9), x=ident.x_final.tolist(), P=ident.P_final.tolist()),
        settings=settings,
        indices_error=ident.indices_error or None,
        flags=ident.flags,
        noise_estimate={      # docs/identification.md#process-noise-from-the-data
            "R": {"method": cons.get("r_std_source"), "std": cons.get("r_std")},
            "Q": {"method": cons.get("q_std_source"), "std": cons.get("q_std"),
                  **{k: v for k, v in (cons.get("noise_estimate") or {}).items() if k != "q_std"}},
        },
        window=ident.window or None,
        filterpy_failures=ident.filterpy_failures,
        note=(None if "v" in ident.measured else
              "run has no sway-velocity column: identified from r and psi only; the six "
              "parameters are not unique, the Nomoto indices are"),
        label=data_label(is_builtin_tank_run(meta), meta.get("provenance")))


def estimates_json(ident: Identification, meta: dict[str, Any], cfg: FilterConfig, *,
                   dataset: str | None = None) -> dict[str, Any]:
    """estimates.json content (docs/contract.md#identifyalgorithm-identify): :func:`estimates` as JSON.

    Parameters
    ----------
    ident : Identification
        The identification of one run.
    meta : dict
        The run's metadata (provenance, scale).
    cfg : FilterConfig
        The settings it ran with (written into the file).
    dataset : str, optional
        The dataset's name, written beside the run's.

    Returns
    -------
    dict
        JSON-ready, keys of docs/contract.md (parameters in the units of pipeline.model, indices K 1/s,
        T1 T2 T3 T s).
    """
    return estimates(ident, meta, cfg, dataset=dataset).to_json()


def identify_batch(Y3: np.ndarray, delta: np.ndarray, h: float, cfg: FilterConfig | None = None, *,
                   parallel: bool = False):
    """SR-UKF-FFM (numba kernel) on R runs of equal length at once.

    Parameters
    ----------
    Y3 : ndarray, shape (R, N, 3)
        Measured v (m/s), r (deg/s), psi (deg) of each run; all three measured.
    delta : ndarray, shape (R, N)
        Rudder angle, deg.
    h : float
        Sample step, s.
    cfg : FilterConfig, optional
        The filter's settings; None: the defaults.
    parallel : bool
        Split the runs into blocks over numba's threads (every core; each run's numbers are the serial
        ones).

    Returns
    -------
    theta : ndarray, shape (R, 6)
        The parameters at the last sample (units of pipeline.model).
    P_theta : ndarray, shape (R, 6, 6)
        Their covariance.
    status : ndarray of int, shape (R,)
        0 = ok, else the kernel's status code (pipeline.identify.fast).
    seconds : float
        Wall time of the filter loop alone, s.
    """
    cfg = cfg or FilterConfig()
    _check_cfg(cfg)
    Y3 = np.ascontiguousarray(Y3, dtype=float)
    delta = np.ascontiguousarray(delta, dtype=float)
    nr, n, _ = Y3.shape
    meas_idx = np.array([0, 1, 2], dtype=np.int64)
    x0s = np.empty((nr, 9))
    P0 = None
    for r in range(nr):
        x0s[r], P0 = initial_state(Y3[r, 0], meas_idx, cfg)
    S0 = np.linalg.cholesky(P0)
    settings = kernel_settings(cfg, meas_idx, h)
    Yk, dk = np.ascontiguousarray(Y3[:, 1:]), np.ascontiguousarray(delta[:, :-1])
    chunks = None
    if parallel:
        import numba

        chunks = max(1, min(nr, 4 * numba.get_num_threads()))
    fast.run_batch(x0s[:1], S0, Y3[:1, 1:3], delta[:1, :2], settings,
                   chunks=None if chunks is None else 1)                  # compile / warm up
    t0 = _time.perf_counter()
    xf, Sf, st = fast.run_batch(x0s, S0, Yk, dk, settings, chunks=chunks)
    secs = _time.perf_counter() - t0
    P = np.einsum("rij,rkj->rik", Sf, Sf)
    return xf[:, 3:], P[:, 3:, 3:], st, secs


