"""Progress people can read, on a terminal and in a log (docs/operations.md, "Logs").

* :func:`bar`: a tqdm bar on a terminal only; with stderr redirected to a file or a pipe it is off,
  so a log holds no carriage-return refreshes.
* :func:`heartbeat`: in a log (stderr not a terminal), one line every ``every_s`` seconds while a long
  block runs, so a stage that works for minutes is never silent for longer than that.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from collections.abc import Iterable, Iterator

#: s between two heartbeat lines of a stage still running: often enough that a log reader knows the
#: work goes on, rare enough that a 15-minute diagnosis adds 30 lines, not thousands
HEARTBEAT_S = 30.0


def on_terminal() -> bool:
    """True when stderr (where bars and heartbeats go) is a terminal."""
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):     # a closed or replaced stream
        return False


class _NoBar:
    """What :func:`bar` gives when nothing is shown: iterates, and ignores the bar's calls.  Not a
    disabled tqdm, which still starts tqdm's monitor thread (and a second thread stops the diagnosis
    from forking its workers: pipeline.diagnose.core._nested_workers)."""

    def __init__(self, iterable: Iterable | None = None):
        self.iterable = iterable

    def __iter__(self):
        return iter(self.iterable if self.iterable is not None else ())

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None

    def update(self, n: int = 1) -> None:
        return None

    def set_description(self, *a, **k) -> None:
        return None

    def set_postfix(self, *a, **k) -> None:
        return None

    def close(self) -> None:
        return None


def bar(iterable: Iterable | None = None, *, progress: bool = True, **kw):
    """``tqdm(iterable, **kw)`` when ``progress`` and stderr is a terminal; else an object with the
    same calls that shows nothing and starts no thread."""
    if not (progress and on_terminal()):
        return _NoBar(iterable)
    from tqdm import tqdm

    return tqdm(iterable, **kw)


@contextlib.contextmanager
def heartbeat(label: str, every_s: float = HEARTBEAT_S) -> Iterator[None]:
    """While the block runs, write ``"<label> still running, N s"`` to stderr every ``every_s`` s.

    Only in a log (stderr not a terminal: there the bars show progress) and in the main thread.  A
    timer signal (SIGALRM), not a thread: a second thread would stop the diagnosis from forking its
    workers (pipeline.diagnose.core._nested_workers), and forked children inherit no timer.  The line
    is written with one ``os.write``, safe inside a signal handler.

    Parameters
    ----------
    label : str
        What runs, e.g. ``"[virtual] diagnose"``.
    every_s : float
        Seconds between two lines (s).
    """
    if (on_terminal() or threading.current_thread() is not threading.main_thread()
            or not hasattr(signal, "setitimer")):
        yield
        return
    t0 = time.monotonic()

    def beat(_signum, _frame) -> None:
        os.write(2, f"{label} still running, {time.monotonic() - t0:.0f} s\n".encode("utf-8", "replace"))

    old = signal.signal(signal.SIGALRM, beat)
    signal.setitimer(signal.ITIMER_REAL, every_s, every_s)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0, 0.0)
        signal.signal(signal.SIGALRM, old)
