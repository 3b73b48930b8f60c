"""The probe corpus: every probe gives its expected outcome.

Accepted probes must give the clean run back (same columns, same values within the files' printed
precision); refused ones exit 2 with one line naming the file, and the row or column where it is known.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.ingest import read_raw

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_probes import PROBE_DIR, PROBES, make_probes  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _file(key: str) -> Path:
    return PROBE_DIR / key.split(" ")[0]


def test_corpus_is_complete_and_current(tmp_path):
    fresh = {p.name: p.read_bytes() for p in make_probes(tmp_path)}
    held = {p.name: p.read_bytes() for p in PROBE_DIR.iterdir()}
    assert held == fresh, "tests/data/probes/ is stale: run tests/make_probes.py"
    assert {k.split(" ")[0] for k in PROBES} == set(held)


@pytest.fixture(scope="module")
def clean():
    return read_raw(PROBE_DIR / "clean.csv")


@pytest.fixture(scope="module")
def marin_clean():
    return read_raw(ROOT / "tests" / "data" / "marin_zigzag_fullscale.dat", scale=45.7)


def _assert_same(run, ref, rtol=1e-6, atol=1e-4):
    assert list(run.frame.columns) == list(ref.frame.columns)
    assert len(run.frame) == len(ref.frame)
    for c in ref.frame.columns:
        np.testing.assert_allclose(run.frame[c], ref.frame[c], rtol=rtol, atol=atol, err_msg=c)


@pytest.mark.parametrize("key", [k for k, v in PROBES.items() if v[1] != "refused"])
def test_accepted_probe(key, clean, marin_clean):
    opts, outcome, detail = PROBES[key]
    run = read_raw(_file(key), **opts)
    notes = " | ".join(run.meta.get("ingest_notes", []))
    if "note" in detail:
        assert detail["note"] in notes, notes
    if outcome in ("equal", "converted"):
        _assert_same(run, clean)
    elif outcome == "equal_marin":
        _assert_same(run, marin_clean)
    elif outcome == "kind":
        for k, v in detail.items():
            assert run.meta.get(k) == v, (k, run.meta.get(k))


@pytest.mark.parametrize("key", [k for k, v in PROBES.items() if v[1] == "refused"])
def test_refused_probe(key, tmp_path, capsys):
    opts, _, (text, row, column) = PROBES[key]
    argv = ["ingest", str(_file(key)), "--out", str(tmp_path / "runs")]
    if "scale" in opts:
        argv += ["--scale", str(opts["scale"])]
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert err.startswith("error: ") and "\n" not in err
    assert _file(key).name in err and text in err, err
    if row is not None:
        assert f"row {row}" in err, err
    if column is not None:
        assert f"column '{column}'" in err, err
    assert not (tmp_path / "runs").exists()


def test_rudder_sign_option_on_the_cli(tmp_path, capsys):
    rc = main(["ingest", str(PROBE_DIR / "rudder_sign_flipped.csv"), "--rudder-sign", "-1",
               "--out", str(tmp_path / "runs")])
    assert rc == 0, capsys.readouterr().err
