"""Fits made ahead by a helper process (pipeline.diagnose.ahead, docs/performance.md "Fits made
ahead"): the helper makes a block's tasks last first while the block's process makes them first to
last, each fit is made once, the helper ends with its block and leaves no claim behind, the memo's
key bytes depend on values only, and a diagnosis is the same bytes with the helper or without it."""

from __future__ import annotations

import json
import multiprocessing
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.diagnose.ahead import fits_ahead
from pipeline.diagnose.fit import FitMemo, SharedFitMemo, fit_memo

fork = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="no fork here")
# one xdist group: the fresh interpreter's run (the module fixture) is made once, on one worker
pytestmark = pytest.mark.xdist_group("diagnose_ahead")

@pytest.fixture(scope="module")
def fresh() -> dict:
    """tests/ahead_bytes.py run in a fresh single-threaded interpreter (a pytest worker may hold a
    thread an earlier test left, and no helper is forked where another thread runs): its JSON line."""
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run([sys.executable, str(root / "tests" / "ahead_bytes.py")], cwd=root,
                          capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(root)},
                          timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_key_bytes_depend_on_values_only():
    """Equal keys built from distinct objects (a name shared in one process, an unpickled copy in
    another) give the same bytes; a different value gives other bytes."""
    name = "sway_yaw_coupling"
    copy = "".join(["sway_yaw_", "coupling"])
    assert copy is not name
    shared = ((name, "linear"), (name, "linear"), 1.5, b"\x00\x01")
    distinct = ((name, "linear"), (copy, "linear"), 1.5, b"\x00\x01")
    assert SharedFitMemo._key(shared) == SharedFitMemo._key(distinct)
    assert SharedFitMemo._key(shared) != SharedFitMemo._key(((name, "linear"), (name, "cubic"), 1.5, b""))


@fork
def test_the_helper_makes_the_last_tasks_and_each_fit_once(fresh):
    """Twelve stand-in fits of 0.1 s: the block's process made the first, the helper the last, each key
    once; told to stop when its block ended, the helper ended by itself, and no child is left."""
    got = fresh["block"]
    makers = got["makers"]
    assert makers[0] == fresh["pid"] and makers[-1] == got["helper"], got
    assert set(makers) == {fresh["pid"], got["helper"]} and got["keys"] == list(range(12))
    assert got["ended"] and got["exitcode"] == 0 and got["children_left"] == 0


@fork
def test_a_helper_inside_a_fit_when_its_block_ends_finishes_it(fresh):
    """The block ends while the helper makes its first fit (the last task, "b"): asked for afterwards,
    that fit is waited for and is the helper's, not made again; the first task, never reached by the
    stopped helper, is made by the block's process; the helper then ends."""
    got = fresh["inside"]
    assert got["b"] == got["helper"] and got["a"] == fresh["pid"] and got["ended"], got


def test_no_helper_without_a_shared_memo_that_allows_it():
    """A memo of one process, a shared memo without ``ahead``, or no memo: the body alone."""
    with fit_memo(1, ahead=True) as one:
        assert type(one) is FitMemo
        with fits_ahead(one, [lambda: None, lambda: None]):
            pass
    with fit_memo(2) as shared:
        with fits_ahead(shared, [lambda: shared.get(0), lambda: shared.get(1)]):
            assert not shared._helpers
    with fits_ahead(None, [lambda: None] * 2):
        pass
    assert not multiprocessing.active_children()


@fork
def test_a_diagnosis_is_the_same_bytes_with_the_helper_or_without(fresh):
    """With --test runs the diagnosis runs no nested workers, so a helper makes fits ahead; every byte
    of diagnosis.json is the one made without it, and the helpers made some of the fits."""
    got = fresh["diagnosis"]
    assert got["same"] is True, got
    # this process made fits and so did its helpers (one process per block, each a few fits)
    assert got["this"] > 0 and sum(got["others"]) > 0, got
