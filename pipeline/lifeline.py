"""Child processes that die with their parent, whatever signal ends it (docs/operations.md,
"Processes and signals").

:func:`die_with_parent` is the initializer of a worker pool (``ProcessPoolExecutor(...,
initializer=die_with_parent, initargs=(os.getpid(),))``).  A parent ended by SIGKILL or by a SIGTERM it
does not handle runs no clean-up, and its pool's workers, blocked on a pipe nobody writes to any more,
would be reparented to PID 1 and live on with their memory.  Two guards, so that one is enough:

* on Linux the kernel sends the worker SIGKILL the moment its parent dies (``prctl
  PR_SET_PDEATHSIG``), even while the worker is inside compiled code that holds the GIL;
* everywhere, a daemon thread in the worker polls :func:`os.getppid` every :data:`POLL_S` seconds and
  ends the worker once the parent's pid is no longer its parent.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

#: How often (s) the watchdog thread asks whether the parent still lives: a dead parent's workers are
#: gone within this time where the kernel's parent-death signal is not available.
POLL_S = 1.0
_PR_SET_PDEATHSIG = 1     # <linux/prctl.h>


def _parent_death_signal() -> bool:
    """Ask the kernel for SIGKILL when the parent dies (Linux); True when it is in place."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _watch(parent_pid: int) -> None:
    while True:
        if os.getppid() != parent_pid:
            os._exit(1)          # noqa: SLF001 - no clean-up: the parent that would read it is gone
        time.sleep(POLL_S)


def die_with_parent(parent_pid: int) -> None:
    """Make this (worker) process end when process ``parent_pid`` ends.

    Parameters
    ----------
    parent_pid : int
        The pid of the process that started this one (read there with :func:`os.getpid`, before the
        fork: a parent that died before this call is noticed at once).
    """
    _parent_death_signal()
    if os.getppid() != parent_pid:   # the parent died before the kernel's guard was set
        os._exit(1)
    threading.Thread(target=_watch, args=(parent_pid,), name="die-with-parent", daemon=True).start()
