"""Writing a diagnosis: diagnosis.json, series.parquet (validation runs), test_series.parquet (test runs,
where given) and PNG plots, all atomically into one directory."""

from __future__ import annotations

from pathlib import Path

from pipeline.diagnose.core import Diagnosis
from pipeline.io import atomic_dir, write_frame, write_json


def plot_series(diag: Diagnosis, out_dir: Path) -> list[Path]:
    """Per validation run and per test run: measured vs baseline vs extended free-run psi and r; and the
    residuals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    label_ext = "extended (" + (", ".join(diag.report["extended"]["effects"]) or "none") + ")"
    banner = (
        "VIRTUAL TANK / simulated data"
        if diag.report.get("provenance") == "virtual"
        else diag.report.get("provenance", "")
    )
    tables = [(diag.series, "free-run on held-out data")]
    if diag.test_series is not None:
        tables.append((diag.test_series, "free-run on a test run, models refitted on all selection runs"))
    for run_id, g, what in ((r, g, w) for t, w in tables for r, g in t.groupby("run_id", sort=False)):
        t = g["time"].to_numpy()
        # the layout engine set here, not by the caller's rcParams (a notebook may have set another)
        fig, ax = plt.subplots(3, 1, figsize=(9, 8), sharex=True, layout="tight")
        ax[0].plot(t, g["psi"], "k", lw=1.2, label="measured")
        ax[0].plot(t, g["psi_baseline"], "C0--", lw=1, label="baseline linear")
        ax[0].plot(t, g["psi_extended"], "C3", lw=1, label=label_ext)
        ax[0].set_ylabel("psi (deg)")
        ax[0].legend(fontsize=8)
        ax[1].plot(t, g["r"], "k", lw=1.2)
        ax[1].plot(t, g["r_baseline"], "C0--", lw=1)
        ax[1].plot(t, g["r_extended"], "C3", lw=1)
        ax[1].set_ylabel("r (deg/s)")
        ax[2].plot(t, g["delta"], "k", lw=1)
        ax[2].set_ylabel("delta (deg)")
        ax[2].set_xlabel("time (s)")
        # parse_math and usetex off: a run called "$x$ zz" is a name, not TeX to typeset (or refuse)
        fig.suptitle(f"{run_id}: {what}  {banner}", fontsize=10, parse_math=False,
                     usetex=False)
        p = out_dir / f"freerun_{_safe(run_id)}.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        paths.append(p)

        fig, ax = plt.subplots(1, 2, figsize=(10, 3.8), layout="tight")
        ax[0].plot(t, g["psi_baseline"] - g["psi"], "C0", lw=1, label="baseline")
        ax[0].plot(t, g["psi_extended"] - g["psi"], "C3", lw=1, label="extended")
        ax[0].axhline(0, color="k", lw=0.5)
        ax[0].set_xlabel("time (s)")
        ax[0].set_ylabel("psi error (deg)")
        ax[0].legend(fontsize=8)
        ax[1].plot(g["r"], g["r_baseline"] - g["r"], "C0.", ms=2, label="baseline")
        ax[1].plot(g["r"], g["r_extended"] - g["r"], "C3.", ms=2, label="extended")
        ax[1].axhline(0, color="k", lw=0.5)
        ax[1].set_xlabel("measured r (deg/s)")
        ax[1].set_ylabel("r error (deg/s)")
        fig.suptitle(f"{run_id}: residuals", fontsize=10, parse_math=False, usetex=False)
        p = out_dir / f"residuals_{_safe(run_id)}.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        paths.append(p)
    return paths


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in str(name))


def write_outputs(diag: Diagnosis, out_dir: str | Path, plots: bool = True) -> Path:
    """Write DIR/diagnosis.json, DIR/series.parquet, DIR/test_series.parquet (only with test runs) and
    the plots; nothing is left half-written."""
    out_dir = Path(out_dir)
    with atomic_dir(out_dir) as tmp:
        write_json(tmp / "diagnosis.json", diag.report)
        meta = {"provenance": diag.report.get("provenance"), "effects": diag.report["extended"]["effects"]}
        for name, table in (("series.parquet", diag.series), ("test_series.parquet", diag.test_series)):
            if table is None:
                continue
            frame = table.copy()
            for c in frame.columns:
                if c != "run_id":
                    frame[c] = frame[c].astype(float)
            write_frame(tmp / name, frame, meta)
        if plots:
            plot_series(diag, tmp)
    return out_dir / "diagnosis.json"


__all__ = ["write_outputs", "plot_series"]
