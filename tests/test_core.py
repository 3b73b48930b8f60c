"""Core plumbing: errors are one line, writes are atomic, runs round-trip, test names parse."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pipeline import units
from pipeline.errors import InputError
from pipeline.io import Run, atomic_path, read_json, read_run, write_json, write_run
from pipeline.runinfo import choose_runs, parse_test_name


def test_error_is_one_line_naming_file_row_column():
    err = InputError("value is not a number:\n 'abc'", file="a.csv", row=12, column="psi")
    text = str(err)
    assert "\n" not in text
    assert text.startswith("a.csv, row 12, column 'psi':")
    assert "not a number" in text


def test_atomic_write_leaves_old_file_on_failure(tmp_path):
    dest = tmp_path / "out.json"
    write_json(dest, {"a": 1})
    with pytest.raises(RuntimeError):
        with atomic_path(dest) as tmp:
            tmp.write_text("partial")
            raise RuntimeError("boom")
    assert read_json(dest) == {"a": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]


def test_json_nan_becomes_null(tmp_path):
    write_json(tmp_path / "x.json", {"a": float("nan"), "b": np.float64(2.5), "c": np.arange(2)})
    assert read_json(tmp_path / "x.json") == {"a": None, "b": 2.5, "c": [0, 1]}


def test_run_roundtrip_keeps_metadata(tmp_path):
    frame = pd.DataFrame({"time": [0.0, 0.08], "psi": [0.0, 0.1], "r": [1.0, 1.0], "delta": [5.0, 5.0]})
    run = Run(frame, {"provenance": "virtual", "test_name": "zigzag 20/20 starboard"})
    write_run(tmp_path / "a.parquet", run)
    back = read_run(tmp_path / "a.parquet")
    pd.testing.assert_frame_equal(back.frame, frame)
    assert back.meta["provenance"] == "virtual" and back.is_virtual
    assert back.meta["run_id"] == "a"


def test_read_run_missing_column(tmp_path):
    run = Run(pd.DataFrame({"time": [0.0], "psi": [0.0], "r": [0.0]}), {})
    write_run(tmp_path / "b.parquet", run)
    with pytest.raises(InputError, match="column 'delta'"):
        read_run(tmp_path / "b.parquet")


def test_froude_scaling_and_body_velocities():
    lam = 37.89
    assert units.froude_to_model(100.0, "length", lam) == pytest.approx(100 / lam)
    assert units.froude_to_model(10.0, "velocity", lam) == pytest.approx(10 / np.sqrt(lam))
    assert units.froude_to_model(1.0, "rate", lam) == pytest.approx(np.sqrt(lam))
    assert units.froude_to_model(20.0, "angle", lam) == 20.0
    # heading 90 deg: moving along +y0 earth is pure surge; along +x0 is sway to port (v < 0)
    u, v = units.body_velocities([0.0, 1.0], [1.0, 0.0], [90.0, 90.0])
    np.testing.assert_allclose(u, [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(v, [0.0, -1.0], atol=1e-12)


@pytest.mark.parametrize("text, expected", [
    ("zigzag 20/20 starboard", ("zigzag", 20.0, 20.0, "starboard")),
    ("Zig-zag manoeuvring for KVLCC2 : 20 / -20", ("zigzag", 20.0, 20.0, None)),
    ("Z20°/10° starting to port", ("zigzag", 20.0, 10.0, "port")),
    ("Z10°/1°", ("zigzag", 10.0, 1.0, None)),
    ("turning circle 35 port", ("turning", 35.0, None, "port")),
    ("calm water straight run", ("other", None, None, None)),
])
def test_parse_test_name(text, expected):
    got = parse_test_name(text)
    assert (got["kind"], got["rudder_deg"], got["heading_deg"], got["first_side"]) == expected


def test_choose_runs_prefers_20_20_starboard():
    runs = [
        {"run_id": "z10p", "kind": "zigzag", "rudder_deg": 10, "heading_deg": 10, "first_side": "port"},
        {"run_id": "z20p", "kind": "zigzag", "rudder_deg": 20, "heading_deg": 20, "first_side": "port"},
        {"run_id": "z20s", "kind": "zigzag", "rudder_deg": 20, "heading_deg": 20, "first_side": "starboard"},
        {"run_id": "tc", "kind": "turning", "rudder_deg": 35, "heading_deg": None, "first_side": "port"},
    ]
    ident, val = choose_runs(runs)
    assert ident == "z20s" and val == ["z10p", "z20p"]
    assert choose_runs(runs, "z10p")[0] == "z10p"
    with pytest.raises(ValueError):
        choose_runs(runs, "nope")
    with pytest.raises(ValueError, match=r"no zigzag run to identify from .*\[roles\] identify"):
        choose_runs(runs[3:])
    assert choose_runs(runs[3:], "tc") == ("tc", [])      # a named run is taken whatever its kind
