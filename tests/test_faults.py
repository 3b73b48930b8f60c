"""Faults and hostile input, round two (docs/operations.md): no endpoint beyond the loopback, no
orphaned workers, one bad dataset never stops the others, damaged outputs rebuilt, studies refused
before they run, one-line write and memory errors, same bytes on a rebuild, logs without refreshes."""

from __future__ import annotations

import ipaddress
import os

import psutil
import pytest

LOOPBACK = {ipaddress.ip_address("127.0.0.1"), ipaddress.ip_address("::1")}


def _listening(pid: int) -> list[tuple[int, str, int]]:
    """(pid, address, port) of every listening TCP socket of ``pid`` and all its descendants."""
    procs = [psutil.Process(pid), *psutil.Process(pid).children(recursive=True)]
    out = []
    for p in procs:
        try:
            conns = p.net_connections(kind="inet")
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            continue
        out += [(p.pid, c.laddr.ip, c.laddr.port) for c in conns if c.status == psutil.CONN_LISTEN]
    return out


# ---------------------------------------------------------------- the study cluster's sockets


@pytest.mark.parametrize("dashboard", [False, True])
def test_local_cluster_listens_on_the_loopback_only(dashboard):
    from pipeline.study.cluster import local_client

    before = set(_listening(os.getpid()))
    with local_client(1, dashboard=dashboard) as client:
        socks = [s for s in _listening(os.getpid()) if s not in before]
        info = client.scheduler_info()
        link = client.dashboard_link
        pages = {p: _get(link.replace("/status", p)) for p in
                 ("/health", "/json/identity.json", "/info/main/workers.html")}
    # the scheduler (in this process), the worker and its nanny (child processes) at least
    assert len(socks) >= 3, socks
    assert {ipaddress.ip_address(ip) for _, ip, _ in socks} <= LOOPBACK, socks
    assert info["address"].startswith("tcp://127.0.0.1:")
    for w in info["workers"]:
        assert w.startswith("tcp://127.0.0.1:")
    # the scheduler's web server: the dashboard and its info pages only when asked for; else /health
    assert link and "127.0.0.1" in link and ":8787" not in link
    assert pages["/health"] == 200
    assert pages["/json/identity.json"] == pages["/info/main/workers.html"] == (200 if dashboard else 404)


def _get(url: str) -> int:
    """HTTP status of a GET of ``url`` (the cluster is gone once closed: asked while it runs)."""
    import urllib.error
    import urllib.request

    try:
        with urllib.request.urlopen(url, timeout=10) as r:
            return r.status
    except urllib.error.HTTPError as exc:
        return exc.code


# ---------------------------------------------------------------- no orphaned workers


@pytest.fixture(scope="module")
def four_truth_runs(tmp_path_factory) -> list[str]:
    """Four short zigzags of the diagnosis's known truth (a 1.5 deg rudder offset), as Parquet runs:
    two to train, two to validate (the case of tests/nested_bytes.py)."""
    import dataclasses as dc

    from pipeline.diagnose import TruthConfig, zigzag_truth
    from pipeline.io import write_run

    d = tmp_path_factory.mktemp("truth")
    cfg = TruthConfig(seed=3, rudder_offset=1.5)
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
    out = []
    for j, (a, side) in enumerate(legs):
        p = d / f"zz{j}.parquet"
        write_run(p, zigzag_truth(a, a, side, 40.0, dc.replace(cfg, seed=cfg.seed + j)))
        out.append(str(p))
    return out


def _gone(pids: list[int], within_s: float) -> list[int]:
    """The pids still alive (not zombies) after waiting up to ``within_s`` seconds."""
    import time

    t_end = time.monotonic() + within_s
    while True:
        alive = []
        for pid in pids:
            try:
                if psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                    alive.append(pid)
            except psutil.NoSuchProcess:
                pass
        if not alive or time.monotonic() > t_end:
            return alive
        time.sleep(0.2)


@pytest.mark.parametrize("sig", ["SIGKILL", "SIGTERM"])
def test_the_diagnosis_pool_dies_with_its_parent(sig, four_truth_runs, tmp_path):
    """A standalone ``python -m pipeline diagnose`` whose nested leave-one-run-out runs in 2 forked
    workers, ended by SIGKILL or SIGTERM while they work: no worker outlives it (a pool's workers were
    left blocked on a pipe, reparented to PID 1).  ``run`` calls the same code in its own process."""
    import signal
    import subprocess
    import sys
    import time

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "PYTHONPATH": root}
    a, b, c, d = four_truth_runs
    proc = subprocess.Popen([sys.executable, "-m", "pipeline", "diagnose", "--train", a, b,
                             "--validate", c, d, "--out", str(tmp_path / "out")],
                            env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    workers: list[int] = []
    try:
        parent = psutil.Process(proc.pid)
        t_end = time.monotonic() + 300
        while len(workers) < 2 and proc.poll() is None and time.monotonic() < t_end:
            workers = [p.pid for p in parent.children(recursive=True)]
            time.sleep(0.1)
        assert len(workers) >= 2, f"the pool never started (exit {proc.poll()})"
        time.sleep(1.0)                                  # the workers are inside their first task
        proc.send_signal(getattr(signal, sig))
        proc.wait(timeout=30)
        assert proc.returncode != 0
        # the kernel's parent-death signal acts at once; the watchdog's poll is 1 s (pipeline.lifeline)
        assert _gone(workers, within_s=10.0) == []
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for pid in workers:
            try:
                psutil.Process(pid).kill()
            except psutil.NoSuchProcess:
                pass
