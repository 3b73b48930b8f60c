"""Diagnosis refuses, in one line and with exit 2, runs it cannot learn from or that do not belong
together: u = 0 at the start or throughout, u < 0 (astern), different ships,
different approach speeds.  Before, u = 0 raised ZeroDivisionError and u < 0 put a complex number
into diagnosis.json."""

from __future__ import annotations

import dataclasses as dc

import pytest

from pipeline.cli import main
from pipeline.diagnose import TruthConfig, diagnose, zigzag_truth
from pipeline.errors import InputError
from pipeline.io import write_run


def _pair():
    cfg = TruthConfig(seed=5)
    a = zigzag_truth(20, 20, "starboard", 30.0, cfg)
    return a, zigzag_truth(10, 10, "port", 30.0, dc.replace(cfg, seed=6))


def _with_u(run, fn):
    f = run.frame.copy()
    f["u"] = fn(f)
    return dc.replace(run, frame=f)


@pytest.mark.parametrize(
    "how,match",
    [
        ("zero_start", "zero at the start"),
        ("zero_all", "zero at the start"),
        ("astern", "astern"),
    ],
)
def test_surge_speed_that_cannot_be_diagnosed_is_refused(how, match):
    a, b = _pair()
    fn = {
        "zero_start": lambda f: f["u"].where(f["time"] > 2.0, 0.0),
        "zero_all": lambda f: 0.0 * f["u"],
        "astern": lambda f: -f["u"],
    }[how]
    with pytest.raises(InputError, match=match):
        diagnose([_with_u(a, fn)], [b])


def test_runs_of_other_ships_or_speeds_are_refused():
    a, b = _pair()
    other = dc.replace(b, meta={**b.meta, "ship": "KVLCC2"})
    mine = dc.replace(a, meta={**a.meta, "ship": "KCS"})
    with pytest.raises(InputError, match="different ships"):
        diagnose([mine], [other])
    faster = _with_u(b, lambda f: 1.5 * f["u"])
    with pytest.raises(InputError, match="approach speed"):
        diagnose([a], [faster])


def test_cli_gives_one_line_and_exit_2_for_zero_speed(tmp_path, capsys):
    a, b = _pair()
    pa, pb = tmp_path / "a.parquet", tmp_path / "b.parquet"
    write_run(pa, _with_u(a, lambda f: 0.0 * f["u"]))
    write_run(pb, b)
    out = tmp_path / "diag"
    assert main(["diagnose", "--train", str(pa), "--validate", str(pb), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "u" in err
    assert not out.exists()


def test_run_without_rudder_excitation_is_refused():
    a, b = _pair()
    f = a.frame.copy()
    f["delta"] = 0.3
    with pytest.raises(InputError, match="no rudder excitation"):
        diagnose([dc.replace(a, frame=f)], [b])
