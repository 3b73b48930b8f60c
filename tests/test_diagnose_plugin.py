"""An effect is one file (docs/diagnosis.md, "Adding an effect"): a toy effect written in a temporary
module, registered in a monkeypatched catalogue, is tried and named by a small diagnosis, read in its
own words and drawn against its own signature axis by the diagnosis report, and injected by the
detection-power study as it says, with no change anywhere else."""

from __future__ import annotations

import dataclasses as dc
import importlib
import json
import runpy
import textwrap
from pathlib import Path

import pytest

#: the toy: cubic yaw damping under another name, with words, a signature axis, an estimate key and an
#: injection of its own (none of them in any table outside this module)
TOY = '''
from pipeline.diagnose.effects.base import R_EQ, Effect, Form, Injection, Param


class ToyYawBrake(Effect):
    name = "toy_yaw_brake"
    label = "toy cubic yaw brake"
    signature_axis = ("r", "toy axis: yaw rate r (deg/s)")
    estimate_key = "n_toy_s_per_deg2"
    magnitude_unit = "toy cut of the 20/20 yaw-rate amplitude"
    injection = Injection(plants=("truth",), solver="damping_for_cut", field="n_rrr",
                          why_not=(("tank", "a toy: the tank cannot take it"),))
    forms = (Form("cubic", (Param("n_toy_s_per_deg2", 0.0, -1.0, 0.0, -1e-4, "s/deg^2",
                                  feature=(0, R_EQ)),)),)
    words = "a toy cubic yaw brake"
    term = "dr/dt += n_toy r^3"
    signature = "yaw-acceleration error odd in r, growing as r^3"
    floor_reason = "changes the peak yaw rate of the largest manoeuvre by >= 5 %"

    def signature_series(self, v, r, delta, ddelta, u_ratio):
        return r**3


EFFECT = ToyYawBrake()
'''
NAME, LABEL, AXIS = "toy_yaw_brake", "toy cubic yaw brake", "toy axis: yaw rate r (deg/s)"


@pytest.fixture
def toy_catalogue(tmp_path, monkeypatch):
    """The catalogue holding only the toy effect, loaded from a module written in ``tmp_path``."""
    import pipeline.diagnose as diag
    import pipeline.diagnose.core as core
    import pipeline.diagnose.effects as effects
    import pipeline.diagnose.fit as fit
    import pipeline.diagnose.select as select

    (tmp_path / "toy_effect_module.py").write_text(textwrap.dedent(TOY), encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    toy = importlib.import_module("toy_effect_module").EFFECT
    for mod in (effects, core, select, diag):
        monkeypatch.setattr(mod, "CATALOGUE", (toy,))
    monkeypatch.setitem(effects.BY_NAME, NAME, toy)
    names = (*effects.NAMES, NAME)
    monkeypatch.setattr(effects, "NAMES", names)
    monkeypatch.setattr(fit, "NAMES", names)
    return toy


def _render_in_process(root: Path, dataset: str, monkeypatch) -> str:
    """The HTML of notebooks/diagnosis.py run in this process (so that it sees the monkeypatched
    catalogue, which a report kernel would not): every displayed object's HTML, in order."""
    import IPython.display as ipd

    shown: list[str] = []

    def display(*objs, **_kw):
        shown.extend(o.data if isinstance(getattr(o, "data", None), str) else "" for o in objs)

    monkeypatch.setattr(ipd, "display", display)
    monkeypatch.setenv("TANKTEST_DATASET", dataset)
    monkeypatch.setenv("TANKTEST_ROOT", str(root))
    monkeypatch.setattr("matplotlib.pyplot.show", lambda *a, **k: None)
    runpy.run_path(str(Path(__file__).parents[1] / "notebooks" / "diagnosis.py"), run_name="__main__")
    return "\n".join(shown)


def test_a_toy_effect_in_its_own_module_is_diagnosed_reported_and_injected(toy_catalogue, tmp_path,
                                                                            monkeypatch):
    """Truth: the linear truth model with a cubic yaw damping cutting the 20/20 yaw-rate amplitude by
    30 % (pipeline.diagnose.truth.damping_for_cut), four 60 s zigzags crossed by side.  The toy (the
    same term under its own name) is the only effect of the catalogue: the diagnosis names it with a
    negative (damping) coefficient; the report says it in its own words and draws its signature
    against its own axis, never showing its internal name; the study injects it into the truth by its
    own solver and refuses the tank with its own reason."""
    from report_catalog import make_catalog

    from pipeline.config import DetectionPowerConfig, DiagnoseConfig
    from pipeline.diagnose import TruthConfig, diagnose, zigzag_truth
    from pipeline.diagnose.output import write_outputs
    from pipeline.diagnose.truth import damping_for_cut
    from pipeline.report import diagnosis_text as dt
    from pipeline.study import detection_power as dp

    n_rrr = damping_for_cut(0.3)
    cfg = TruthConfig(seed=5, n_rrr=n_rrr)
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
    runs = [zigzag_truth(a, a, s, 60.0, dc.replace(cfg, seed=cfg.seed + j)) for j, (a, s) in enumerate(legs)]
    # selection only: the nested gain does not change which effect is named (tests/selection_only.py)
    d = diagnose(runs[:2], runs[2:], cfg=DiagnoseConfig(nested_gain=False))
    rep = d.report
    assert rep["cause"] == NAME and rep["settings"]["catalogue"] == [NAME]
    (f,) = rep["findings"]
    assert f["significant"] and f["estimate"]["n_toy_s_per_deg2"] < 0     # a damping that damps

    # the report, from the stage's own outputs
    cat = make_catalog(tmp_path / "proc", "tiny", "virtual")
    write_outputs(d, cat.diagnose_dir, plots=False)
    assert json.loads((cat.diagnose_dir / "diagnosis.json").read_text())["cause"] == NAME
    page = _render_in_process(tmp_path / "proc", "tiny", monkeypatch)
    assert f"Cause: <b>{LABEL}</b>" in page
    assert f"<h3>{LABEL}</h3>" in page
    assert AXIS in page                                   # the signature figure's caption
    assert NAME not in page
    assert dt.effect_label(NAME) == LABEL and dt.signature_x(d.series, NAME)[1] == AXIS
    assert dt.effect_words(f"{NAME} + {NAME}") == f"{LABEL} + {LABEL}"

    # the detection-power study: the toy's own injection, estimate key, unit and reason
    tc, truth_value = dp._truth_inject(NAME, 0.3, TruthConfig())
    assert tc.n_rrr == truth_value == pytest.approx(damping_for_cut(0.3, TruthConfig()))
    assert dp.catalogue_effects() == (NAME,)
    study = DetectionPowerConfig(magnitudes={NAME: (0.3,)})
    assert dp.not_studied(study) == {"tank": {NAME: "a toy: the tank cannot take it"}}
    with pytest.raises(KeyError, match="the tank cannot take it"):
        dp._tank_inject(NAME, 0.3, dp.TankConfig(), 10.0)
