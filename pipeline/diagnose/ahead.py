"""Fits made ahead by a helper process (docs/performance.md, "Fits made ahead").

Most blocks of the selection make fits that do not depend on each other: every effect's forms added
to the current model in every fold, the pairs and triples of a pool, the reference structure in each
fold, the drop-one refits of the backward pass, the test runs' refits.  Within :func:`fits_ahead`,
a process forked at the block's start runs the same block's tasks in REVERSE order while this process
runs them forward; both ask the diagnosis's :class:`~pipeline.diagnose.fit.SharedFitMemo` for every
fit, so each fit is made once, by whichever process asks first (the memo's claim), and the other
finds it made.  The two meet in the middle of the block, so a block of independent fits takes about
half its time on two cores.

Nothing decided depends on the helper: a fit is a deterministic function of its memo key (the runs'
content, structure, start, settings), so the diagnosis is the same bytes with or without it
(tests/test_diagnose_ahead.py); the helper's own results, and its copy of the search, are thrown away.
A helper that is still inside a fit when its block ends finishes that fit (its claim is never left
behind) and stops at its next request to the memo.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import threading
from collections.abc import Callable, Sequence

from pipeline.diagnose.fit import FitMemo, HelperStopped, SharedFitMemo
from pipeline.lifeline import die_with_parent


def may_fork() -> bool:
    """Whether this process may fork a helper: ``fork`` is available, this process runs a single thread
    (a fork copies only the calling thread, so a lock another thread holds would stay locked in the
    child) and is not a daemon (a Dask worker's or a pool's process, whose cores are not its own)."""
    return ("fork" in multiprocessing.get_all_start_methods()
            and not multiprocessing.current_process().daemon
            and threading.active_count() == 1)


@contextlib.contextmanager
def fits_ahead(memo: FitMemo | None, tasks: Sequence[Callable[[], object]]):
    """While the body runs, a forked helper runs ``tasks`` (callables of no argument, each making some
    fits through ``memo``) last first; the body is expected to make the same fits first to last.

    Without a helper (``memo`` not a :class:`SharedFitMemo` that allows helpers, fewer than two tasks,
    or a fork not safe here: :func:`may_fork`) the body runs alone; its results are the same either
    way.  On leaving, the helper is told to stop (not waited for: it ends at its next fit request);
    every helper still alive is killed when the memo's context ends
    (:func:`~pipeline.diagnose.fit.fit_memo`)."""
    if not isinstance(memo, SharedFitMemo) or not memo.ahead or len(tasks) < 2 or not may_fork():
        yield
        return
    memo.reap_helpers()
    fork = multiprocessing.get_context("fork")
    stop = fork.RawValue("b", 0)          # shared memory: set to 1 when the block ends
    proc = fork.Process(target=_helper, args=(memo, stop, tuple(tasks), os.getpid()), daemon=True)
    proc.start()
    memo.add_helper(proc, stop)
    try:
        yield
    finally:
        stop.value = 1


def _helper(memo: SharedFitMemo, stop, tasks, parent: int) -> None:
    """The helper process's body: ``tasks`` last first until ``stop`` (a shared byte) is set, then out
    without running any of the parent's exit handlers or flushing its inherited output buffers
    (``os._exit``)."""
    try:
        die_with_parent(parent)
        memo.stop_when(stop)
        for task in reversed(tasks):
            if stop.value:
                break
            try:
                task()
            except HelperStopped:
                break
            except Exception:  # noqa: BLE001, S112
                # a task that fails here fails in the block's own process too, which reports it; the
                # helper only makes fits ahead, so it goes on with the next task
                continue
    finally:
        os._exit(0)
