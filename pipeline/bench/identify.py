"""Filter speed: SR-UKF-FFM (numba kernel) vs the filterpy FFM-UKF baseline on the same 585 samples,
measured back to back in one run (warm-up first; timing covers the filter loop alone), plus the
batch throughput of the kernel (1,000 runs of 585 samples in one call)."""

from __future__ import annotations

import numpy as np

from pipeline.config import FilterConfig
from pipeline.identify import identify_arrays, identify_batch, synthetic


def run(quick: bool = False) -> list[dict]:
    cfg = FilterConfig()
    n = cfg.samples
    t, d, _, y = synthetic.zigzag(n=n, seed=1)
    reps_fast, reps_base, n_batch = (20, 1, 200) if quick else (200, 15, 1000)
    identify_arrays(t, d, y, cfg, algorithm="srukf-ffm")          # compile / warm up
    identify_arrays(t[:20], d[:20], y[:20], cfg, algorithm="ffm-ukf")
    fast = min(identify_arrays(t, d, y, cfg, algorithm="srukf-ffm").timing["seconds_total"]
               for _ in range(reps_fast))
    base = min(identify_arrays(t, d, y, cfg, algorithm="ffm-ukf").timing["seconds_total"]
               for _ in range(reps_base))
    steps = n - 1
    Ys = np.empty((n_batch, n, 3))
    ds = np.empty((n_batch, n))
    for k in range(n_batch):
        _, ds[k], _, Ys[k] = synthetic.zigzag(n=n, seed=1000 + k, rudder=10 + 15 * (k % 7) / 6)
    _, _, status, secs = identify_batch(Ys, ds, cfg.dt, cfg)
    _, _, status2, secs2 = identify_batch(Ys, ds, cfg.dt, cfg, parallel=True)
    return [
        {"name": "srukf-ffm per step", "value": fast / steps * 1e6, "unit": "us",
         "note": f"best of {reps_fast}, numba kernel"},
        {"name": "ffm-ukf (filterpy) per step", "value": base / steps * 1e6, "unit": "us",
         "note": f"best of {reps_base}"},
        {"name": "speed-up srukf-ffm / ffm-ukf", "value": base / fast, "unit": "x", "target": ">= 350",
         "note": "same run, per step"},
        {"name": f"srukf-ffm identification, {n} samples", "value": fast * 1e3, "unit": "ms",
         "target": "< 10", "note": "paper: 377 ms"},
        {"name": f"srukf-ffm batch throughput ({n_batch} runs x {n})", "value": n_batch / secs,
         "unit": "runs/s", "note": f"{int(np.sum(status != 0))} runs failed; serial kernel, one core"},
        {"name": f"srukf-ffm batch throughput, both cores ({n_batch} x {n})", "value": n_batch / secs2,
         "unit": "runs/s", "note": f"numba threads over blocks of runs; {int(np.sum(status2 != 0))} failed"},
    ]
