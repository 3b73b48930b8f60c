"""Run by tests/test_diagnose_jacobian.py in a fresh interpreter (the signatures a process has compiled
or loaded are those its own calls asked for): calls the diagnosis kernels every way the fits do (one
or several parameter rows; the runs' own starts or given ones; Jacobians in either memory order, of one
column or several, with start columns; the prediction-error pieces with and without sensitivities; a
free run of the extended model) and a short diagnosis in this process, and the identification's filter
on writable and read-only arrays, one run and a batch, serially and on numba's threads; then prints
one JSON line: each numba kernel of pipeline.diagnose.extended and pipeline.identify.fast and the
signatures it holds."""

from __future__ import annotations

import dataclasses as dc
import json

import numpy as np
from numba.core.registry import CPUDispatcher

from pipeline.config import DiagnoseConfig, FilterConfig
from pipeline.diagnose import TruthConfig, diagnose, extended, zigzag_truth
from pipeline.diagnose.core import _context
from pipeline.diagnose.effects import REFERENCE
from pipeline.diagnose.fit import (
    Layout,
    _scales,
    jacobian,
    oe_batch,
    reference_speed,
    series_from_run,
    structure_of,
    with_initial_states,
)
from pipeline.identify import fast, identify_arrays, identify_batch, synthetic
from pipeline.model import PAPER_TABLE4


def main() -> None:
    cfg = TruthConfig(seed=11, rudder_offset=1.0, speed_loss_k=0.2)
    runs = [zigzag_truth(a, a, side, 20.0, dc.replace(cfg, seed=11 + j))
            for j, (a, side) in enumerate([(20, "starboard"), (10, "port")])]
    series = with_initial_states([series_from_run(r) for r in runs], 2.0, box_sigma=2.0)
    ctx = _context(series)
    sc, u_ref = _scales(series), reference_speed(series)
    horizon = max(10, int(round(ctx.t_ship / series[0].h)))
    for st in (structure_of("rudder_offset"), structure_of(*REFERENCE)):
        layout = Layout(st, ctx)
        lo, hi = layout.bounds()
        p = np.clip(np.concatenate([list(PAPER_TABLE4.values()), np.zeros(len(lo) - 6)]), lo, hi)
        for batch in (oe_batch(series, sc, layout, u_ref),
                      oe_batch([dc.replace(series[0], v=None), series[1]], sc, layout, u_ref)):
            batch(p)
            batch(np.stack([p, p]))
            batch(p, X0=batch.x0s[None])
            for order in ("C", "F"):
                jacobian(batch, p, lo, hi, order=order)
                jacobian(batch, p, lo, hi, starts=[(0, 2, 1.0)], x0=batch.x0s, order=order)
                batch.jacobian(p, [0], [0], 1, order=order)
                pieces = batch.pe_layout(horizon)
                if pieces is not None:
                    jacobian(batch, p, lo, hi, pieces=pieces, order=order)
                    batch.pe_jacobian(p, [0], [0], 1, pieces, order=order)
                    batch.pe_jacobian(p, [], [], 0, pieces, sens=False)
    diagnose(runs[:1], runs[1:], cfg=DiagnoseConfig(nested_workers=1, fit_ahead=False))
    t, d, _, y = synthetic.zigzag(n=120, seed=1, rudder=15)
    for frozen in (False, True):
        yy, dd = np.array(y), np.array(d)
        yy.setflags(write=not frozen)
        dd.setflags(write=not frozen)
        identify_arrays(t, dd, yy, FilterConfig(), samples=120)
        for parallel in (False, True):
            identify_batch(np.stack([yy, yy]), np.stack([dd, dd]), float(t[1] - t[0]), parallel=parallel)
    held = {f"{mod.__name__.rsplit('.', 1)[-1]}.{name}": [str(s) for s in obj.signatures]
            for mod in (extended, fast) for name, obj in sorted(vars(mod).items())
            if isinstance(obj, CPUDispatcher)}
    print(json.dumps(held))


if __name__ == "__main__":
    main()
