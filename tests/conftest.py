"""Shared fixtures.  Tests that need ../shared skip with a clear reason when it is absent."""

from __future__ import annotations

from pathlib import Path

import pytest

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
