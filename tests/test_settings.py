"""Settings in one place: every tunable number of ingest's checks, the benchmark ships' known
particulars and the paper's figures are written once (pipeline/config.py, pipeline/paper.py) and read
from there."""

from __future__ import annotations

import ast
import io
import os
import tokenize
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline import paper
from pipeline.config import KNOWN_SHIPS, IngestChecks, IngestConfig, TankConfig
from pipeline.errors import InputError
from pipeline.ingest import checks
from pipeline.ingest.core import gap_note

ROOT = Path(__file__).resolve().parent.parent
PIPELINE = ROOT / "pipeline"


def _sources(skip: tuple[str, ...] = ()) -> list[str]:
    out = []
    for folder, dirs, files in os.walk(PIPELINE):       # symlinked folders (pipeline/notebooks) not followed
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            rel = (Path(folder) / name).relative_to(ROOT).as_posix()
            if name.endswith(".py") and not rel.startswith(skip):
                out.append(rel)
    return out


def number_tokens(rel: str, value: float) -> list[str]:
    """'file:line' of every numeric literal of code (not comments or strings) equal to ``value``."""
    text = (ROOT / rel).read_text(encoding="utf-8")
    hits = []
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type == tokenize.NUMBER and not tok.string.endswith(("j", "J")):
            try:
                if float(tok.string.replace("_", "")) == value:
                    hits.append(f"{rel}:{tok.start[0]}")
            except ValueError:
                continue
    return hits


def test_number_tokens_finds_literals_only(tmp_path, monkeypatch):
    src = tmp_path / "pipeline" / "x.py"
    src.parent.mkdir()
    src.write_text('a = 45.7  # 45.7\nb = "45.7"\nc = 4.57e1\n"""1:45.7"""\n')
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    assert number_tokens("pipeline/x.py", 45.7) == ["pipeline/x.py:1", "pipeline/x.py:3"]


# ------------------------------------------------------------------ ingest checks
def test_ingest_checks_module_holds_no_thresholds():
    """pipeline/ingest/checks.py defines no numeric constant of its own: its thresholds are
    IngestChecks's fields (pipeline/config.py), each with its unit and reason."""
    tree = ast.parse((PIPELINE / "ingest" / "checks.py").read_text(encoding="utf-8"))
    numeric = [t.id for node in tree.body if isinstance(node, ast.Assign)
               for t in node.targets if isinstance(t, ast.Name)
               if isinstance(node.value, (ast.Constant, ast.Tuple))]
    assert numeric == []
    assert checks.DEFAULT_CHECKS == IngestConfig().checks == IngestChecks()


def _spiky(step_deg: float) -> pd.DataFrame:
    """A steady 1 deg/s turn logged at 0.08 s with one heading sample moved by ``step_deg``."""
    t = np.arange(200) * 0.08
    psi = 1.0 * t
    psi[100] += step_deg
    return pd.DataFrame({"time": t, "psi": psi, "r": np.full(t.size, 1.0), "delta": np.full(t.size, 10.0)})


def test_spike_threshold_is_the_configured_one():
    """A 3 deg one-sample jump of the heading on an otherwise exact turn: beyond the default 2 deg
    floor (refused, naming the row), within a configured 5 deg one (kept)."""
    frame = _spiky(3.0)
    with pytest.raises(InputError, match="spike") as err:
        checks.check_spikes(frame, np.arange(200) + 2, "turn.csv")
    assert err.value.row == 102 and err.value.column == "psi"
    checks.check_spikes(frame, np.arange(200) + 2, "turn.csv",
                        checks=replace(IngestChecks(), spike_floor_psi_deg=5.0))


def test_froude_band_is_the_configured_one():
    """A 7 m model at 1.5 m/s is Fn 0.18: inside the default band; refused under a band that
    ends at 0.15."""
    t = np.arange(100) * 0.08
    frame = pd.DataFrame({"time": t, "u": np.full(t.size, 1.5)})
    fn = 1.5 / np.sqrt(9.81 * 7.0)
    out = checks.check_scale({}, frame, "run.csv", 1.0, 7.0, "test")
    assert out["froude_number"] == pytest.approx(fn)
    with pytest.raises(InputError, match="Froude number 0.181"):
        checks.check_scale({}, frame, "run.csv", 1.0, 7.0, "test",
                           checks=replace(IngestChecks(), froude_band=(0.05, 0.15)))


def test_gap_window_is_the_configured_one():
    """A dropped sample in a 0.1 s time base is a gap; with fewer samples on one side than the
    configured edge, only a step beyond 1.9 steps would be (so a 2-step hole near the start still is,
    and a 1.6-step one is not)."""
    t = np.arange(60) * 0.1
    hole = np.delete(t, 30)
    assert gap_note(hole) is not None
    near_start = np.concatenate([t[:3], t[3:] + 0.06])     # a 1.6-step step after 3 samples
    assert gap_note(near_start, limits=replace(IngestChecks(), gap_edge=5)) is None
    assert gap_note(near_start, limits=replace(IngestChecks(), gap_edge=2)) is not None


# ------------------------------------------------------------------ known ships
def test_hsva_scale_written_once():
    """HSVA's KVLCC2 model scale 1:45.7 is a code literal only in pipeline/config.py; ingest, the
    built-in description and the IMO check read it from there."""
    hits = [h for rel in _sources() for h in number_tokens(rel, 45.7)]
    assert hits and all(h.startswith("pipeline/config.py:") for h in hits), hits
    assert len(hits) == 1
    from pipeline.dataset import BUILTIN, parse_dataset_toml

    folder = ROOT / "data" / "raw" / "hsva"
    desc = parse_dataset_toml(BUILTIN["hsva"], name="hsva", folder=folder, path=folder / "dataset.toml")
    assert desc.model_scale == KNOWN_SHIPS.hsva_kvlcc2_scale
    from pipeline.config import IndicesConfig

    assert IndicesConfig().ship_scales["KVLCC2"] == KNOWN_SHIPS.hsva_kvlcc2_scale


def test_hsva_model_length_is_the_scale_of_the_ship():
    """The model Lpp the HSVA README states is the full-scale Lpp over its scale, to its rounding."""
    full = KNOWN_SHIPS.lpp_full_m["KVLCC2"]
    assert KNOWN_SHIPS.hsva_kvlcc2_lpp_m == pytest.approx(full / KNOWN_SHIPS.hsva_kvlcc2_scale, abs=0.05)


def test_synthetic_zigzag_servo_is_the_tank_kcs():
    """The synthetic zigzag's rudder rate defaults to the virtual KCS's servo rate (model scale): the
    rudder moves at most that many deg/s."""
    from pipeline.identify.synthetic import zigzag

    t, delta, _, _ = zigzag(n=400)
    rate = np.max(np.abs(np.diff(delta))) / (t[1] - t[0])
    assert rate == pytest.approx(TankConfig.rudder_rate, rel=1e-9)
    assert not [h for rel in _sources() for h in number_tokens(rel, 14.28)
                if not h.startswith("pipeline/config.py:")]


# ------------------------------------------------------------------ the paper's figures
def test_report_and_validate_read_the_paper_module():
    from pipeline import validate
    from pipeline.report import nb

    assert validate.PAPER_TABLES is paper.TABLES_5_6
    for (amp, alg), row in nb.PAPER_TABLES_5_6.items():
        table = {"20/20": "table5", "10/10": "table6"}[amp]
        assert row is paper.TABLES_5_6[table]["rows"][alg]
    assert len(nb.PAPER_TABLES_5_6) == 4
    assert nb.PAPER_IDENT_SECONDS == paper.IDENT_SECONDS and nb.PAPER == paper.REFERENCE
    assert nb.PAPER_SHIP == paper.SHIP


#: figures distinctive enough to find as literals: Table 5/6 errors, Table 7, the graphical K T,
#: the identification time, the course-keeping figures
DISTINCT = (0.0152, 0.0037, 0.0046, 0.0016, 4.43, 3.55, 3.69, 1.95, 3.9688, 0.4094, 0.6960, 3.6822,
            0.576, 4.816, 0.377, 1.46, 0.86, -3.78, -1.09)


def _paper_literals(rels: list[str]) -> list[str]:
    hits = []
    for rel in rels:
        if rel == "pipeline/paper.py":
            continue
        for v in DISTINCT:
            hits += number_tokens(rel, abs(v))
    return hits


def test_paper_figures_are_literals_only_in_paper_module():
    hits = _paper_literals(_sources())
    assert not hits, hits


def _heading_in_radians(factor: float) -> pd.DataFrame:
    """A weaving 60 s run at 0.08 s: r = 5 sin(0.2 t) deg/s, its heading logged in radians times
    ``factor`` (1.10: 10 % off 1/57.3)."""
    t = np.arange(750) * 0.08
    r = 5.0 * np.sin(0.2 * t)
    psi_deg = 25.0 * (1.0 - np.cos(0.2 * t))             # the integral of r
    return pd.DataFrame({"time": t, "psi": np.deg2rad(psi_deg) * factor, "r": r,
                         "delta": np.full(t.size, 10.0)})


def test_unit_factor_tolerance_is_the_configured_one():
    """A heading in radians, 10 % off: within the default 15 % band of 1/57.3 it is named as radians;
    under a configured 5 % band only the general refusal (not d(psi)/dt) is left."""
    frame = _heading_in_radians(1.10)
    lines = np.arange(len(frame)) + 2
    with pytest.raises(InputError, match="heading looks like radians"):
        checks.check_units(frame, lines, {}, "weave.csv", IngestConfig())
    strict = replace(IngestConfig(), checks=replace(IngestChecks(), unit_factor_tolerance=0.05))
    with pytest.raises(InputError, match="yaw rate is not d\\(psi\\)/dt"):
        checks.check_units(frame, lines, {}, "weave.csv", strict)


def test_pinned_parameters_take_the_configured_one_sigma():
    """Without v, b11 and a21 are held at their prior with FilterConfig.pin_std (their own units)."""
    from pipeline.config import FilterConfig
    from pipeline.identify import initial_state

    y0 = np.array([np.nan, 0.1, 0.0])
    for pin in (1e-9, 1e-6):
        _, P0 = initial_state(y0, np.array([1, 2]), FilterConfig(pin_std=pin))
        std = np.sqrt(np.diag(P0))
        assert std[3 + 4] == pytest.approx(pin) and std[3 + 2] == pytest.approx(pin)
        assert std[3] == FilterConfig().theta0_std[0]


def test_process_noise_search_stops_at_the_configured_bisections():
    """A zigzag simulated with process noise on v and r (0.02 m/s, 0.05 deg/s a step), so that the
    least Q of the bracket leaves the filter over-confident: the mean-NIS match of Q evaluates the two
    bracket ends and at most FilterConfig.process_max_bisections midpoints, and says it did not match
    when they run out short of the tolerance."""
    from pipeline.config import FilterConfig
    from pipeline.identify import initial_state, synthetic
    from pipeline.identify.core import estimate_process_noise

    t, d, _, y = synthetic.zigzag(n=300, seed=5, process_noise=(0.02, 0.05, 0.0))
    idx = np.array([0, 1, 2])
    for most, matched in ((1, False), (3, False), (30, True)):
        cfg = FilterConfig(process_max_bisections=most)
        x0, P0 = initial_state(y[0], idx, cfg)
        got = estimate_process_noise(x0, P0, y[1:], d[:-1], h=t[1] - t[0], cfg=cfg, meas_idx=idx)
        assert got["matched"] is matched, (most, got)
        assert got["evaluations"] == 2 + most if not matched else got["evaluations"] <= 2 + most
        assert (abs(got["mean_nis"] / 3 - 1) <= cfg.process_nis_tolerance) is matched


def test_moved_thresholds_are_no_longer_literals():
    """The unit-factor band, the radians-rudder share, the gap factors and the time-jitter share are
    IngestChecks fields: no literal of theirs is left in the ingest code that reads them."""
    assert number_tokens("pipeline/ingest/checks.py", 0.15) == []
    assert number_tokens("pipeline/ingest/checks.py", 0.2) == []
    assert number_tokens("pipeline/ingest/core.py", 1.9) == []
    assert number_tokens("pipeline/ingest/core.py", 1.5) == []
    assert number_tokens("pipeline/ingest/core.py", 0.25) == []
    assert number_tokens("pipeline/identify/core.py", 1e-9) == []
