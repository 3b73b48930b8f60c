"""Run by tests/test_diagnose_ahead.py::test_a_diagnosis_is_the_same_bytes_with_the_helper_or_without
in a fresh, single-threaded interpreter (the only kind that forks the helper of
pipeline.diagnose.ahead): one diagnosis with --test runs, with the helper that makes fits ahead and
without it (DiagnoseConfig.fit_ahead); prints whether the two diagnosis.json are the same bytes, how
many fits each process made in the run with the helper, and the cause."""

from __future__ import annotations

import dataclasses as dc
import json
import os
import sys
import tempfile
import threading
from collections import Counter
from pathlib import Path

from pipeline.config import DiagnoseConfig
from pipeline.diagnose import TruthConfig, diagnose, zigzag_truth
from pipeline.diagnose.ahead import may_fork
from pipeline.diagnose.fit import SharedFitMemo
from pipeline.io import write_json


def main() -> None:
    if not may_fork():
        raise SystemExit(f"not single-threaded: {threading.active_count()} threads")
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
        for ahead in (True, False):
            rep = diagnose(runs[:2], runs[2:4], test=runs[4:], cfg=DiagnoseConfig(fit_ahead=ahead)).report
            write_json(Path(tmp) / f"{ahead}.json", rep)
            out[ahead] = (Path(tmp) / f"{ahead}.json").read_bytes()
        makers = Counter(log.read_text().split()) if log.exists() else Counter()
    print(json.dumps({"same": out[True] == out[False], "this": makers.pop(str(os.getpid()), 0),
                      "others": sorted(makers.values()), "cause": rep["cause"]}))


if __name__ == "__main__":
    main()
    sys.exit(0)
