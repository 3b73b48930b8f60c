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
import time
from pathlib import Path

import pytest

from pipeline.diagnose.ahead import fits_ahead
from pipeline.diagnose.fit import FitMemo, SharedFitMemo, fit_memo

fork = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="no fork here")

#: s: how long one stand-in "fit" of the mechanism tests takes (a dozen of them outlast a fork)
_FIT_S = 0.1


def _make(memo, key, seconds: float = _FIT_S):
    """A stand-in fit through ``memo``'s claim protocol: (the process that made it, key)."""
    hit = memo.get(key)
    if hit is None:
        time.sleep(seconds)
        hit = (os.getpid(), key)
        memo.put(key, hit)
    return hit


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
def test_the_helper_makes_the_last_tasks_and_each_fit_once():
    n = 12
    with fit_memo(2, ahead=True) as memo:
        assert isinstance(memo, SharedFitMemo) and memo.ahead
        with fits_ahead(memo, [lambda i=i: _make(memo, i) for i in range(n)]):
            got = [_make(memo, i) for i in range(n)]
        makers = [pid for pid, _ in got]
        helper = memo._helpers[0][0]
        # the block's process made the first ones, the helper the last ones, no fit twice
        assert makers[0] == os.getpid() and makers[-1] == helper.pid
        assert set(makers) == {os.getpid(), helper.pid}
        assert [k for _, k in got] == list(range(n))
        # told to stop when the block ended: it ends by itself at its next request to the memo
        helper.join(timeout=30)
        assert not helper.is_alive() and helper.exitcode == 0
    assert not multiprocessing.active_children()


@fork
def test_a_helper_inside_a_fit_when_its_block_ends_finishes_it():
    """The block ends while the helper makes its first fit (the last task): asked for afterwards,
    that fit is waited for and is the helper's, not made again; the helper then ends."""
    with fit_memo(2, ahead=True) as memo:
        with fits_ahead(memo, [lambda: _make(memo, "a"), lambda: _make(memo, "b", seconds=1.0)]):
            # until the helper has claimed "b" (it is then inside that fit)
            deadline = time.monotonic() + 30
            while not isinstance(memo._store.get(SharedFitMemo._key("b")), tuple):
                assert time.monotonic() < deadline, "the helper never claimed its first fit"
                time.sleep(0.01)
        helper = memo._helpers[0][0]
        assert _make(memo, "b")[0] == helper.pid
        helper.join(timeout=30)
        assert not helper.is_alive()
        assert _make(memo, "a")[0] == os.getpid()     # never reached by the stopped helper
    assert not multiprocessing.active_children()


def test_no_helper_without_a_shared_memo_that_allows_it():
    """A memo of one process, a shared memo without ``ahead``, or a single task: the body alone."""
    with fit_memo(1, ahead=True) as one:
        assert type(one) is FitMemo
        with fits_ahead(one, [lambda: None, lambda: None]):
            pass
    with fit_memo(2) as shared:
        with fits_ahead(shared, [lambda: _make(shared, 0), lambda: _make(shared, 1)]):
            assert not shared._helpers
    with fits_ahead(None, [lambda: None] * 2):
        pass
    assert not multiprocessing.active_children()


@fork
def test_a_diagnosis_is_the_same_bytes_with_the_helper_or_without():
    """With --test runs the diagnosis runs no nested workers, so a helper makes fits ahead; every byte
    of diagnosis.json is the one made without it, and the helpers made some of the fits.  In a fresh
    single-threaded interpreter (tests/ahead_bytes.py): a pytest worker may hold a thread an earlier
    test left, where no helper is forked."""
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run([sys.executable, str(root / "tests" / "ahead_bytes.py")], cwd=root,
                          capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(root)},
                          timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    got = json.loads(done.stdout.strip().splitlines()[-1])
    assert got["same"] is True, got
    # this process made fits and so did its helpers (one process per block, each a few fits)
    assert got["this"] > 0 and sum(got["others"]) > 0, got
