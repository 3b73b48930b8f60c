"""Shared fixtures.  Tests that need ../shared skip with a clear reason when it is absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

# Property tests: `make test` (and CI) replays the same examples every run (derandomize: the draw is
# seeded from the test itself), so a green clone stays green and a failure reproduces byte for byte.
# `make fuzz` explores: fresh random examples each run, ten times as many, for finding new bad inputs
# (how the Fortran-exponent ingest bug of 2026-11-24 surfaced).  A new failure found there becomes an
# explicit regression test, not a random one.
settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
settings.register_profile("fuzz", derandomize=False, print_blob=True)
settings.load_profile(os.environ.get("TANKTEST_HYPOTHESIS", "ci"))

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
HSVA_DIR = SHARED / "data" / "kvlcc2_hsva"


@pytest.fixture(scope="session")
def hsva_dir() -> Path:
    """The measured HSVA KVLCC2 zigzags in ../shared (skip when absent)."""
    if not HSVA_DIR.is_dir() or not list(HSVA_DIR.glob("*.dat")):
        pytest.skip(f"measured HSVA data not found at {HSVA_DIR} (../shared is absent in a user's clone)")
    return HSVA_DIR


@pytest.fixture(scope="module")
def study_client():
    """One 2-worker LocalCluster (worker processes, one thread each) per test module that asks for it,
    started by the same helper as the study engine's (pipeline.study.cluster)."""
    from pipeline.study.cluster import local_client

    with local_client(2) as client:
        yield client


#: tests that share a costly result made once per process (a module fixture, or a module cache keyed
#: by what the fixture gives) run on one xdist worker under ``--dist loadgroup`` (make test): the
#: fixture's name -> the group.  Without it each worker that ran one of them made the result again
#: (the MARIN KVLCC2 fold 1 diagnosis, reused by its model-scale twin: tests/test_diagnose_generalise.py)
SHARED_WORK_GROUPS = {"kv_files": "kvlcc2", "hsva_design": "hsva_design", "rendered": "report_security"}


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """An ``xdist_group`` mark on every test that uses a fixture of :data:`SHARED_WORK_GROUPS` (before
    xdist reads the marks); a ``long`` mark on every test a module names in its ``LONG_TESTS`` (test
    names with their parameter ids: the cases of a parametrised family that ``make test`` leaves to
    ``make test-long``), before ``-m "not long"`` deselects them."""
    for item in items:
        long_names = getattr(getattr(item, "module", None), "LONG_TESTS", ())
        if item.name in long_names:
            item.add_marker(pytest.mark.long)
        for name, group in SHARED_WORK_GROUPS.items():
            if name in getattr(item, "fixturenames", ()):
                item.add_marker(pytest.mark.xdist_group(group))
