"""Run by tests/test_diagnose_ahead.py in a fresh, single-threaded interpreter (the only kind that
forks the helper of pipeline.diagnose.ahead; a pytest worker may hold a thread an earlier test left).
Prints one JSON line:

- ``block``: a block of twelve stand-in fits (0.1 s each) through the claim protocol, made by this
  process first to last and by the helper last first: who made each, the helper's pid, whether it had
  ended 30 s after its block and its exit code, and whether any child process is left after the memo;
- ``inside``: a block that ends while the helper is inside its first fit ("b"): who made "b" (asked for
  afterwards) and "a", whether the helper then ended;
- ``diagnosis``: one diagnosis with --test runs with the helper and without it
  (DiagnoseConfig.fit_ahead): whether the two diagnosis.json are the same bytes, how many fits this
  process and the helpers made in the run with them, and the cause.
"""

from __future__ import annotations

import dataclasses as dc
import json
import multiprocessing
import os
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path

from pipeline.config import DiagnoseConfig
from pipeline.diagnose import TruthConfig, diagnose, zigzag_truth
from pipeline.diagnose.ahead import fits_ahead, may_fork
from pipeline.diagnose.fit import SharedFitMemo, fit_memo
from pipeline.io import write_json

#: s: how long one stand-in fit takes (a dozen of them outlast a fork)
FIT_S = 0.1


def make(memo, key, seconds: float = FIT_S):
    """A stand-in fit through ``memo``'s claim protocol: (the pid of the process that made it, key)."""
    hit = memo.get(key)
    if hit is None:
        time.sleep(seconds)
        hit = (os.getpid(), key)
        memo.put(key, hit)
    return hit


def block() -> dict:
    n = 12
    with fit_memo(2, ahead=True) as memo:
        with fits_ahead(memo, [lambda i=i: make(memo, i) for i in range(n)]):
            got = [make(memo, i) for i in range(n)]
        helper = memo._helpers[0][0]
        helper.join(timeout=30)
        out = {"makers": [pid for pid, _ in got], "keys": [k for _, k in got], "helper": helper.pid,
               "ended": not helper.is_alive(), "exitcode": helper.exitcode}
    out["children_left"] = len(multiprocessing.active_children())
    return out


def inside() -> dict:
    with fit_memo(2, ahead=True) as memo:
        with fits_ahead(memo, [lambda: make(memo, "a"), lambda: make(memo, "b", seconds=1.0)]):
            # until the helper has claimed "b" (it is then inside that fit)
            deadline = time.monotonic() + 60
            while not isinstance(memo._store.get(SharedFitMemo._key("b")), tuple):
                if time.monotonic() > deadline:
                    raise SystemExit("the helper never claimed its first fit")
                time.sleep(0.01)
        helper = memo._helpers[0][0]
        b = make(memo, "b")[0]
        helper.join(timeout=30)
        return {"b": b, "a": make(memo, "a")[0], "helper": helper.pid, "ended": not helper.is_alive()}


def diagnosis() -> dict:
    cfg = TruthConfig(seed=41, rudder_offset=1.0)
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard"), (15, "starboard")]
    runs = [zigzag_truth(a, a, s, 40.0, dc.replace(cfg, seed=cfg.seed + j)) for j, (a, s) in enumerate(legs)]
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "makers"
        put = SharedFitMemo.put

        def put_and_log(self, key, hit):               # the forked helper inherits it
            put(self, key, hit)
            fd = os.open(log, os.O_WRONLY | os.O_APPEND | os.O_CREAT)
            os.write(fd, f"{os.getpid()}\n".encode())
            os.close(fd)

        SharedFitMemo.put = put_and_log
        out = {}
        try:
            for ahead in (True, False):
                rep = diagnose(runs[:2], runs[2:4], test=runs[4:], cfg=DiagnoseConfig(fit_ahead=ahead)).report
                write_json(Path(tmp) / f"{ahead}.json", rep)
                out[ahead] = (Path(tmp) / f"{ahead}.json").read_bytes()
        finally:
            SharedFitMemo.put = put
        makers = Counter(log.read_text().split()) if log.exists() else Counter()
    return {"same": out[True] == out[False], "this": makers.pop(str(os.getpid()), 0),
            "others": sorted(makers.values()), "cause": rep["cause"]}


def main() -> None:
    if not may_fork():
        raise SystemExit(f"not single-threaded: {threading.active_count()} threads")
    print(json.dumps({"pid": os.getpid(), "block": block(), "inside": inside(), "diagnosis": diagnosis()}))


if __name__ == "__main__":
    main()
