"""Shared fixtures.  Tests that need ../shared skip with a clear reason when it is absent."""

from __future__ import annotations

import os
from pathlib import Path

import numpy  # noqa: F401  (loads numpy's OpenBLAS before it is limited below)
import pytest
import scipy.linalg  # noqa: F401  (loads SciPy's own OpenBLAS before it is limited below)
from hypothesis import settings
from threadpoolctl import threadpool_limits

# One BLAS thread in every test process, as the diagnosis runs its fits (pipeline.diagnose.core.diagnose,
# pipeline.control.stage): tests that call its searches and fits directly otherwise get OpenBLAS's
# threads on the least-squares SVDs, which on the 2-core machine fight the other xdist worker, and
# their bits are not the product's.  Measured: tests/test_diagnose_group_screen.py 18.5 s -> 6.3 s
# alone.  Kept for the life of the process (a module-level object; subprocesses limit themselves).
_ONE_BLAS_THREAD = threadpool_limits(limits=1, user_api="blas")

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
#: (the MARIN KVLCC2 fold 1 diagnosis, reused by its model-scale twin: tests/test_diagnose_generalise.py;
#: the two diagnoses and rendered pages of tests/test_diagnosis_numbers.py, 47 s; the diagnosis of
#: tests/test_diagnose_result.py)
SHARED_WORK_GROUPS = {"kv_files": "kvlcc2", "hsva_design": "hsva_design", "rendered": "report_security",
                      "cases": "diagnosis_numbers", "diag": "diagnose_result"}


#: the known cost of the slow tests (tests/known_slow.txt: seconds, node id), by which `make test` hands
#: them out longest first (docs/operations.md, "Tests")
KNOWN_SLOW = Path(__file__).with_name("known_slow.txt")


def _grouped(nodeid: str) -> bool:
    """The node id ends in an xdist group (``...@group``; pytest-xdist's own test: an ``@`` after the
    parameters' ``]``)."""
    return nodeid.rfind("@") > nodeid.rfind("]")


def known_seconds(path: Path = KNOWN_SLOW) -> dict[str, float]:
    """{node id: seconds} of ``path`` (lines ``seconds node-id``, an ``@group`` end dropped; ``#`` starts
    a comment); {} when absent."""
    if not path.is_file():
        return {}
    out: dict[str, float] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            seconds, nodeid = line.split(maxsplit=1)
            nodeid = nodeid.rsplit("@", 1)[0] if _grouped(nodeid) else nodeid
            out[nodeid] = out.get(nodeid, 0.0) + float(seconds)
    return out


def longest_first(items: list, seconds: dict[str, float]) -> list:
    """``items`` as xdist should hand them out: the units of work (an ``xdist_group``, else one test)
    by their known seconds, longest first, so that the two workers of `make test` finish together
    instead of one waiting on a long test handed out last; a unit's tests stay together, and units of
    equal (or unknown: 0) cost keep their collection order."""
    def unit(item) -> str:
        groups = sorted(m.args[0] if m.args else m.kwargs.get("name", "default")
                        for m in item.iter_markers("xdist_group"))
        return "@" + "_".join(groups) if groups else item.nodeid

    cost: dict[str, float] = {}
    first: dict[str, int] = {}
    for k, item in enumerate(items):
        u = unit(item)
        cost[u] = cost.get(u, 0.0) + seconds.get(item.nodeid, 0.0)
        first.setdefault(u, k)
    order = {id(item): k for k, item in enumerate(items)}
    return sorted(items, key=lambda it: (-cost[unit(it)], first[unit(it)], order[id(it)]))


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """An ``xdist_group`` mark on every test that uses a fixture of :data:`SHARED_WORK_GROUPS` (before
    xdist reads the marks); a ``long`` mark on every test a module names in its ``LONG_TESTS`` (test
    names with their parameter ids: the cases of a parametrised family that ``make test`` leaves to
    ``make test-long``), before ``-m "not long"`` deselects them; then the tests in
    :func:`longest_first` order (the same on every worker, as xdist requires)."""
    for item in items:
        long_names = getattr(getattr(item, "module", None), "LONG_TESTS", ())
        if item.name in long_names:
            item.add_marker(pytest.mark.long)
        for name, group in SHARED_WORK_GROUPS.items():
            if name in getattr(item, "fixturenames", ()):
                item.add_marker(pytest.mark.xdist_group(group))
    items[:] = longest_first(items, known_seconds())
    if getattr(config.option, "loadgroup", False):      # an xdist worker under --dist loadgroup
        _group_in_node_ids(items)


def _group_in_node_ids(items) -> None:
    """Each test's ``xdist_group`` as the ``@group`` end of its node id, where pytest-xdist's loadgroup
    scheduler reads it.  pytest-xdist (3.8) writes it to ``Item._nodeid``, which pytest 9 no longer
    reads (``Node.nodeid`` is made from the structured ``Node._id``): without this the groups are
    silently ignored and each worker builds the shared results again.  Written here where pytest 9
    reads it, the same string xdist writes; nothing is done on a pytest whose ids xdist can write."""
    try:
        from _pytest.nodeid import NodeId
    except ImportError:              # pytest < 9: xdist's own write takes
        return
    for item in items:
        groups = sorted({str(m.args[0] if m.args else m.kwargs.get("name", "default"))
                         for m in item.iter_markers("xdist_group")})
        if groups and isinstance(getattr(item, "_id", None), NodeId) and not _grouped(item.nodeid):
            item._id = NodeId.parse(f"{item.nodeid}@{'_'.join(groups)}")
