"""The effect object of the diagnosis catalogue (docs/diagnosis.md) and what an effect may use.

An effect is a small object (one module per effect, registered in
:data:`pipeline.diagnose.effects.CATALOGUE`):

- ``name`` (docs/diagnosis.md) and ``forms``: one or more parameterisations (e.g. Norrbin r^3 or r|r|);
  the fit tries every form and keeps the one of least TRAINING cost;
- every form's :class:`Param` list: name with unit suffix, null value (the effect absent), bounds,
  start, unit;
- its contribution to the equations of motion, in one of two kinds:
  * terms linear in the parameters added to dv/dt or dr/dt (``Param.feature`` = (feature code,
    equation)); the features are the functions of (v, r) in :data:`FEATURES`;
  * a transformation of the effective rudder, or of the coefficients with speed, set through
    :meth:`Effect.apply` on :class:`Terms` (offset, dead time, servo lag, saturation, asymmetry,
    speed exponent);
  * or no term at all but a reading of the runs: a bias of the sway velocity the files give
    (``Terms.v_bias_m_s``), for a sensor effect (heading misalignment);
- ``signature``: what it leaves in the residuals of a model without it (words, and
  :meth:`Effect.signature_series` for the residual-structure table);
- its materiality floor (:meth:`Effect.material`) with the physical reason (``floor_reason``);
- :meth:`Effect.physical`: one sentence a naval architect would accept;
- how it reads and draws in the report: ``label`` (its name in words), ``signature_axis`` (the series
  column its residual signature is drawn against) and ``signature_residual`` (the residual it shows in);
- what the detection-power study may inject and how (``injection``, :meth:`Effect.inject`), the
  estimate key holding its size in the injected terms (``estimate_key``) and that size's unit
  (``magnitude_unit``).

Everything about one effect lives on its object (docs/diagnosis.md, "Adding an effect").

Units: v m/s, r deg/s, psi deg, delta deg, time s, u m/s (docs/contract.md#run-data).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np

#: feature codes of the numba kernel: f(v m/s, r deg/s, s); s is the kernel's speed factor (u/U)^n
#: (docs/diagnosis.md: 1 without speed_loss, u/U with its exponent at 1), by which the cubic terms of
#: the non-dimensional form are divided (Y = rho/2 L^2 u^2 Y'_vvr v'^2 r' gives dv/dt ~ v^2 r / u)
FEATURES = {
    0: "r^3",
    1: "r|r|",
    2: "v|v|",
    3: "v^2 r",
    4: "v r^2",
    5: "v|r|",
    6: "|v| r",
    7: "v^3",
    8: "v^2 r / s",
    9: "v r^2 / s",
    10: "r^3 / s",
}
#: equation index of a feature term: 0 adds to dv/dt (m/s^2), 1 to dr/dt (deg/s^2)
V_EQ, R_EQ = 0, 1


def feature_value(code: int, v, r, s=1.0):
    """Reference (numpy) value of feature ``code`` at (v m/s, r deg/s, speed factor s > 0); the
    kernel's copy is held to this by tests/test_diagnose_effects.py."""
    v = np.asarray(v, dtype=float)
    r = np.asarray(r, dtype=float)
    s = np.asarray(s, dtype=float)
    return {
        0: lambda: r**3,
        1: lambda: r * np.abs(r),
        2: lambda: v * np.abs(v),
        3: lambda: v * v * r,
        4: lambda: v * r * r,
        5: lambda: v * np.abs(r),
        6: lambda: np.abs(v) * r,
        7: lambda: v**3,
        8: lambda: v * v * r / s,
        9: lambda: v * r * r / s,
        10: lambda: r**3 / s,
    }[code]()


@dataclass(frozen=True)
class Param:
    """One parameter of an effect.  ``lo``/``hi``/``start`` are in ``unit`` unless ``time_scaled`` or
    ``speed_scaled``, in which case they are multiples of the ship's time scale T_ship (s) or of its
    approach speed U_ref (m/s), so that bounds do not depend on the scale of the data."""

    name: str
    null: float
    lo: float
    hi: float
    start: float
    unit: str
    feature: tuple[int, int] | None = None  # (feature code, equation) for a term linear in the parameter
    time_scaled: bool = False
    speed_scaled: bool = False
    #: a damping coefficient of a hull term (contract signs (docs/contract.md#run-data): negative damps).
    #: Held <= 0 in the anchored form of an extension (fit.Layout.bounds, docs/diagnosis.md "Sound at every
    #: amplitude"): there the linear part is the small-motion model and the term is the growth of damping with
    #: amplitude
    damping: bool = False

    def _scale(self, ctx: Context) -> float:
        if self.speed_scaled:
            return float(ctx.u_ref or 1.0)
        return ctx.t_ship if self.time_scaled else 1.0

    def bounds(self, ctx: Context, signed: bool = False) -> tuple[float, float]:
        """(lower, upper) bound in ``unit``; ``signed``: a damping parameter's upper bound held at 0."""
        k = self._scale(ctx)
        lo, hi = self.lo * k, self.hi * k
        if signed and self.damping:
            hi = min(hi, 0.0)
        return lo, hi

    @property
    def hull_term(self) -> bool:
        """A term of the hull force in (v, r), vanishing at v = r = 0 (a feature term)."""
        return self.feature is not None

    def start_value(self, ctx: Context) -> float:
        return self.start * self._scale(ctx)


@dataclass(frozen=True)
class Form:
    name: str
    params: tuple[Param, ...]


@dataclass
class Terms:
    """Everything the simulation kernel needs beyond the six linear parameters (null = no effect)."""

    feat_code: list = field(default_factory=list)
    feat_eq: list = field(default_factory=list)
    feat_coef: list = field(default_factory=list)
    offset_deg: float = 0.0
    delay_s: float = 0.0
    lag_s: float = 0.0
    rudder_cubic_per_deg2: float = 0.0
    asymmetry: float = 0.0
    speed_exponent: float = 0.0
    #: m/s at the reference speed U_ref: the sway velocity a run gives is the ship's plus
    #: v_bias_m_s (u/U_ref) (constant without u).  A reading, not a force: the model's states are the
    #: ship's, its initial states and outputs are readings (pipeline.diagnose.extended)
    v_bias_m_s: float = 0.0


@dataclass(frozen=True)
class Context:
    """What the data say about the ship, for bounds, floors and physical readings (training runs).

    t_ship s: the ship's own time scale (first-order Nomoto |T| from equation error); h s: sample step;
    d_max deg, r_max deg/s, v_max m/s: largest |delta|, |r|, |v| (99.5th percentile); u_ref m/s:
    approach speed (None without u); u_min_ratio: lowest u/u_ref; lpp_m: model length if the metadata
    has it.
    """

    t_ship: float
    h: float
    d_max: float
    r_max: float
    v_max: float
    u_ref: float | None = None
    u_min_ratio: float | None = None
    lpp_m: float | None = None
    #: False when no training run measures the sway velocity v: v is then a latent state of the model
    #: (its scale held by a convention, fit.Layout.bounds) and terms in v are not tried
    v_measured: bool = True
    #: deg: median drift angle of the runs' straight approaches as read (atan2(v, u) before the first
    #: rudder execute; pipeline.diagnose.datacheck.approach_drift), None when no run has an approach
    approach_drift_deg: float | None = None


#: the plants of the detection-power study (pipeline.study.detection_power): the linear truth model
#: (pipeline.diagnose.truth.TruthConfig) and the virtual KCS tank (pipeline.config.TankConfig)
PLANTS = ("truth", "tank")


@dataclass(frozen=True)
class Injection:
    """How the detection-power study injects an effect at a magnitude (:meth:`Effect.inject`).

    Attributes
    ----------
    plants : tuple of str
        The plants of :data:`PLANTS` that can take the effect.
    direct : bool
        The magnitude is the setting of the effect's own name in TruthConfig and TankConfig, in the
        estimate's own terms (``Effect.estimate_key``).
    solver : str
        Else, on the truth plant: the function of :mod:`pipeline.diagnose.truth` that gives the
        coefficient from the magnitude, ``solver(magnitude, cfg)``.
    field : str
        The TruthConfig field the solved coefficient sets.
    estimate_is_coefficient : bool
        The estimate is the solved coefficient itself (else the magnitude).
    why_not : tuple of (str, str)
        (plant, reason) for a plant that cannot take the effect.
    """

    plants: tuple[str, ...] = ()
    direct: bool = False
    solver: str = ""
    field: str = ""
    estimate_is_coefficient: bool = True
    why_not: tuple[tuple[str, str], ...] = ()

    def reason_not(self, plant: str, effect: str) -> str:
        """Why ``plant`` cannot take the effect (its stated reason, else a plain one)."""
        return dict(self.why_not).get(plant, f"no injection of {effect} into the {plant} plant yet")


@functools.lru_cache(maxsize=256)
def _solved(solver: str, magnitude: float, cfg_items: tuple) -> float:
    from pipeline.diagnose import truth

    return getattr(truth, solver)(magnitude, truth.TruthConfig(**dict(cfg_items)))


def solved_coefficient(solver: str, magnitude: float, cfg) -> float:
    """``pipeline.diagnose.truth.<solver>(magnitude, cfg)``, cached on the content of ``cfg`` (a solver
    simulates the truth to meet the magnitude; a study asks the same one many times)."""
    return _solved(solver, float(magnitude), tuple(sorted(dataclasses.asdict(cfg).items())))


class Effect:
    """Base class; a concrete effect sets the class attributes and overrides what it needs."""

    name: str = ""
    forms: tuple[Form, ...] = ()
    words: str = ""  # short noun phrase
    term: str = ""  # its contribution to the equations of motion
    signature: str = ""  # what it leaves in the residuals of a model without it
    floor_reason: str = ""  # the physical reason of the materiality floor
    needs_u: bool = False
    needs_v: bool = False  # a term in the sway velocity v: tried only where v is measured
    #: its name in words for a reader ("" : the name with spaces)
    label: str = ""
    #: (series column, axis label) its residual signature is drawn against in the report: a column of
    #: diagnosis's series table (time s, delta deg, r deg/s, v m/s, u m/s), or "ddelta" (the rudder rate
    #: d(delta)/dt, deg/s) or "vr" (v r, m/s x deg/s), both derived by the report
    signature_axis: tuple[str, str] = ("time", "time (s)")
    #: (series column, axis label, unit) of the held-out residual its signature shows in
    signature_residual: tuple[str, str, str] = ("r", "r error (deg/s)", "deg/s")
    #: the key of its estimate holding its size in the terms the studies inject it in ("": the first)
    estimate_key: str = ""
    #: the unit (in words) of the magnitude the detection-power study injects
    magnitude_unit: str = "effect's own unit"
    #: what the detection-power study may inject, and how
    injection: Injection = Injection()

    def reader_label(self) -> str:
        """Its name in words for a reader: ``label``, else the name with spaces."""
        return self.label or self.name.replace("_", " ")

    def inject(self, plant: str, magnitude: float, cfg, rudder_deg: float = 20.0):
        """(``cfg`` with the effect injected at ``magnitude`` (``magnitude_unit``), its true value in the
        terms of ``estimate_key``).  ``plant``: one of :data:`PLANTS`, ``cfg`` its config (TruthConfig or
        TankConfig); ``rudder_deg`` (deg): the largest rudder of the plant's zigzags.  KeyError for a
        plant that cannot take it (:attr:`Injection.plants`)."""
        inj = self.injection
        if plant not in inj.plants:
            raise KeyError(f"{self.name}: {inj.reason_not(plant, self.name)}")
        if inj.direct:
            return dataclasses.replace(cfg, **{self.name: magnitude}), magnitude
        if plant == "truth" and inj.solver:
            c = solved_coefficient(inj.solver, magnitude, cfg)
            true_value = c if inj.estimate_is_coefficient else magnitude
            return dataclasses.replace(cfg, **{inj.field: c}), true_value
        raise KeyError(f"{self.name}: no injection into the {plant} plant")

    def form(self, name: str | None = None) -> Form:
        if name is None:
            return self.forms[0]
        return next(f for f in self.forms if f.name == name)

    def applicable(self, ctx: Context) -> str | None:
        """None when the effect can be tried on these data, else the reason it cannot."""
        if self.needs_u and ctx.u_ref is None:
            return "the runs have no surge speed u"
        if self.needs_v and not ctx.v_measured:
            return ("the runs have no sway velocity v: without it v is a latent state of unknown scale, "
                    "so a term in v has no physical reading")
        return None

    def apply(self, form: Form, values: dict, terms: Terms) -> None:
        """Add the effect to ``terms``: feature terms by default; input effects override."""
        for p in form.params:
            if p.feature is not None:
                terms.feat_code.append(p.feature[0])
                terms.feat_eq.append(p.feature[1])
                terms.feat_coef.append(float(values[p.name]))

    def material(self, form: Form, values: dict, ctx: Context, response_change: float) -> tuple[bool, str]:
        """(material?, floor text).  ``response_change``: relative change of the peak yaw rate of the
        largest training manoeuvre when the effect is removed from the fitted model; material from
        :data:`MIN_RESPONSE` (the floor of the hull's effects: :data:`RESPONSE_FLOOR`)."""
        return bool(response_change >= MIN_RESPONSE), response_floor_text(response_change, MIN_RESPONSE)

    def physical(self, form: Form, values: dict, ctx: Context) -> str:
        return f"{self.words}: " + ", ".join(f"{k} = {v:.3g}" for k, v in values.items())

    def extra_estimate(self, form: Form, values: dict, ctx: Context) -> dict:
        """Derived quantities reported beside the parameters (SI/deg units)."""
        return {}

    def signature_series(self, v, r, delta, ddelta, u_ratio) -> np.ndarray | None:
        """Regressor of the yaw-acceleration error that a model without the effect leaves."""
        return None


#: a removal whose yaw-rate change exceeds the manoeuvre's own peak yaw rate (relative change > 1) is
#: no longer a change of that manoeuvre: the model without the effect does not make the zigzag (its
#: free-run runs away), and a percentage of it ("1845 %") would read as a size of the effect
DIVERGED_CHANGE = 1.0

#: least relative change of the largest manoeuvre's peak yaw rate for an effect judged by its response
#: (the default of :meth:`Effect.material`) to be named: a turning or zigzag prediction within 5 % is
#: what model tests are trusted to (ITTC repeatability)
MIN_RESPONSE = 0.05
#: that floor in words, an effect's ``floor_reason``
RESPONSE_FLOOR = f"changes the peak yaw rate of the largest manoeuvre by >= {MIN_RESPONSE:.0%}"


def response_floor_text(response_change: float, floor: float = MIN_RESPONSE) -> str:
    """The floor text of a response-change materiality test; a removal that diverges says so in words."""
    if not np.isfinite(response_change) or response_change > DIVERGED_CHANGE:
        size = (
            f"its yaw rate departs by {response_change:.0f} times the peak"
            if np.isfinite(response_change)
            else "its yaw rate is no longer finite"
        )
        return (
            f"without it the model's free-run of the largest manoeuvre diverges ({size}): the rest of the "
            f"model cannot make the manoeuvre alone (floor {floor:.0%} change of the peak yaw rate)"
        )
    return f"changes the peak yaw rate of the largest manoeuvre by {response_change:.1%} (floor {floor:.0%})"
