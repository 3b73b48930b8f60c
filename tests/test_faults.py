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
