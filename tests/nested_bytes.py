"""Run by tests/test_diagnose.py::test_nested_workers_give_the_same_report_bytes in a fresh,
single-threaded interpreter (the only kind that uses the nested workers): one 4-run diagnosis with
the nested leave-one-run-out in this process and in 2 worker processes; prints whether the two
reports are the same bytes, and how many runs were held out; and which keys of the report (and of its
reference fit) change when the nested leave-one-run-out is switched off (DiagnoseConfig.nested_gain)."""

from __future__ import annotations

import dataclasses as dc
import json
import threading

from pipeline.config import DiagnoseConfig
from pipeline.diagnose import TruthConfig, diagnose, zigzag_truth
from pipeline.diagnose.core import _nested_workers


def _dump(report: dict) -> str:
    def enc(o):
        return o.tolist() if hasattr(o, "tolist") else repr(o)

    return json.dumps(report, sort_keys=True, default=enc)


def main() -> None:
    cfg = TruthConfig(seed=3, rudder_offset=1.5)
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
    runs = [zigzag_truth(a, a, s, 40.0, dc.replace(cfg, seed=cfg.seed + j)) for j, (a, s) in enumerate(legs)]
    out = {}
    for w in (1, 2):
        d = DiagnoseConfig(nested_workers=w)
        if _nested_workers(d, 4) != w:
            raise SystemExit(f"not single-threaded: {threading.active_count()} threads")
        out[w] = _dump(diagnose(runs[:2], runs[2:], cfg=d).report)
    # the same case with the nested leave-one-run-out switched off (DiagnoseConfig.nested_gain): the
    # report's keys that differ from the full one
    on = json.loads(out[2])
    off = json.loads(_dump(diagnose(runs[:2], runs[2:], cfg=DiagnoseConfig(nested_gain=False)).report))
    differ = sorted(k for k in set(on) | set(off) if _dump(on.get(k)) != _dump(off.get(k)))
    ref_on, ref_off = on.get("reference") or {}, off.get("reference") or {}
    ref_differ = sorted(k for k in set(ref_on) | set(ref_off)
                        if _dump(ref_on.get(k)) != _dump(ref_off.get(k)))
    print(json.dumps({"same": out[1] == out[2], "nested": len(on["gain"]["nested"]), "off_differ": differ,
                      "off_gain": off["gain"]["mae_psi_relative_reduction"],
                      "off_method": off["gain"]["method"], "cause": [on["cause"], off["cause"]],
                      "reference_differ": ref_differ}))


if __name__ == "__main__":
    main()
