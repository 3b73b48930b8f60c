"""Starting dask clusters for studies, benchmarks and tests: one place.

* :func:`local_cluster` / :func:`local_client`: a ``LocalCluster`` of worker *processes*, one thread
  each, numba and OpenMP single-threaded (one case per core; the numba kernels are serial).  Every
  socket it opens (scheduler, workers, nannies) listens on 127.0.0.1 only, and there is no dashboard
  (an unauthenticated web server) unless ``dashboard=True`` asks for one, also on 127.0.0.1
  (docs/operations.md, "The Dask cluster and its sockets").
* :func:`loopback_cluster`: a scheduler and workers started as separate processes (``dask scheduler``,
  ``dask worker tcp://127.0.0.1:PORT``), as on a real cluster; yields the scheduler's address and
  stops the processes on exit.  The workers import this package from the same path as the caller.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
#: The only address a local cluster listens on: a shared machine's other users cannot reach it.
LOOPBACK = "127.0.0.1"


def local_cluster(workers: int, memory_limit: str = "auto", *, dashboard: bool = False):
    """(client, cluster): a LocalCluster of ``workers`` processes, one thread each, on the loopback.

    ``dashboard``: start the scheduler's web dashboard (on 127.0.0.1, a free port); off by default.
    Close both.
    """
    import dask
    from distributed import Client, LocalCluster

    # The scheduler always runs a web server; without the dashboard it serves /health only (not the
    # info and JSON pages that list workers, tasks and logs), on a free loopback port (not 8787).
    routes = {} if dashboard else {"distributed.scheduler.http.routes": ["distributed.http.health"]}
    with dask.config.set(routes):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host=LOOPBACK,
                               dashboard_address=f"{LOOPBACK}:0", memory_limit=memory_limit,
                               scheduler_kwargs={"dashboard": dashboard}, env=dict(WORKER_ENV))
    try:
        return Client(cluster), cluster
    except BaseException:
        cluster.close()
        raise


@contextmanager
def local_client(workers: int, memory_limit: str = "auto", *, dashboard: bool = False) -> Iterator:
    """:func:`local_cluster` as a context manager yielding the client."""
    client, cluster = local_cluster(workers, memory_limit, dashboard=dashboard)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def free_port() -> int:
    """A TCP port free on the loopback address now."""
    with socket.socket() as s:
        s.bind((LOOPBACK, 0))
        return s.getsockname()[1]


def dask_command() -> list[str]:
    """The ``dask`` command of this Python environment."""
    exe = Path(sys.executable).with_name("dask")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "dask"]


def package_env() -> dict[str, str]:
    """This process's environment with this package first on PYTHONPATH (for worker processes)."""
    return {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}


@contextmanager
def loopback_cluster(workers: int, *, nanny: bool = True, timeout: float = 120.0) -> Iterator[str]:
    """A scheduler and ``workers`` one-thread workers as separate processes on 127.0.0.1.

    Yields the scheduler address (``tcp://127.0.0.1:PORT``) once every worker has joined; terminates
    the processes (then kills any that hang) on exit.
    """
    from distributed import Client

    port = free_port()
    addr = f"tcp://{LOOPBACK}:{port}"
    env = {**package_env(), **WORKER_ENV}
    dask = dask_command()
    quiet = {"env": env, "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    procs = [subprocess.Popen([*dask, "scheduler", "--host", LOOPBACK, "--port", str(port),
                               "--no-dashboard"], **quiet)]
    try:
        for _ in range(workers):
            procs.append(subprocess.Popen([*dask, "worker", addr, "--host", LOOPBACK, "--nthreads", "1",
                                           "--no-dashboard",
                                           *([] if nanny else ["--no-nanny"])], **quiet))
        t0 = time.monotonic()
        with Client(addr, timeout=f"{int(timeout)}s") as client:
            client.wait_for_workers(workers, timeout=max(1.0, timeout - (time.monotonic() - t0)))
        yield addr
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=10)
