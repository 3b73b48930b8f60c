"""Ingest: canonical CSV round trip, MARIN conversion from a known truth, anti-aliased resampling."""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline.cli import main
from pipeline.config import IngestConfig
from pipeline.errors import InputError
from pipeline.ingest import detect_format, ingest_file, parse_raw, read_raw, resample
from pipeline.io import Run, read_json, read_run, write_run

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_fixtures import MARIN_FILE, MARIN_FULL_DT, MARIN_SCALE, marin_truth  # noqa: E402

TANK_HEADER = """# ship: KCS
# provenance: virtual
# test: zigzag 20/20 starboard
# lpp: 6.0702
# scale: 37.89
# dt: 0.08
# seed: 123456
# note: virtual tank (MMG model of the KCS, SIMMAN 2020 model scale); not measured data
"""


def _synthetic(n=400, dt=0.08, seed=3):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    psi = 25.0 * np.sin(0.2 * t) + 0.01 * rng.standard_normal(n)
    r = 5.0 * np.cos(0.2 * t)
    delta = 20.0 * np.sign(np.cos(0.2 * t + 0.4))
    u = 2.0 - 0.2 * (1 - np.exp(-t / 10))
    v = -0.05 * r / 5.0
    x0 = np.cumsum(u * dt)
    y0 = np.cumsum(0.1 * dt * np.ones(n))
    rpm = np.full(n, 720.0)
    return pd.DataFrame({"time": t, "x0": x0, "y0": y0, "psi": psi, "u": u, "v": v, "r": r,
                         "delta": delta, "rpm": rpm})


def _write_csv(path: Path, frame: pd.DataFrame, header: str = TANK_HEADER) -> Path:
    body = frame.to_csv(index=False, float_format="%.6f", lineterminator="\n")
    path.write_text(header + body)
    return path


# ------------------------------------------------------------------ canonical CSV
def test_canonical_csv_round_trip(tmp_path):
    frame = _synthetic()
    path = _write_csv(tmp_path / "kcs_zigzag_20_20_S.csv", frame)
    run = ingest_file(path)
    out = run.frame
    assert list(out.columns) == list(frame.columns)
    assert len(out) == len(frame)
    for c in frame.columns:
        np.testing.assert_allclose(out[c].to_numpy(), frame[c].to_numpy(), atol=1e-6, err_msg=c)
    m = run.meta
    assert m["source_file"] == path.name
    assert m["source_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert m["source_format"] == "csv"
    assert m["provenance"] == "virtual" and m["ship"] == "KCS"
    assert m["lpp"] == pytest.approx(6.0702) and m["model_scale"] == pytest.approx(37.89)
    assert m["seed"] == 123456 and m["scale_factor"] == 1.0
    assert m["test_name"] == "zigzag 20/20 starboard"
    assert (m["kind"], m["rudder_deg"], m["heading_deg"]) == ("zigzag", 20.0, 20.0)
    assert m["first_side"] == "starboard"
    assert m["dt"] == 0.08 and m["original_dt"] == pytest.approx(0.08)
    assert m["samples"] == len(frame) and m["duration"] == pytest.approx(frame["time"].iloc[-1])
    sel = frame["time"] <= IngestConfig().approach_window
    assert m["approach_speed"] == pytest.approx(frame.loc[sel, "u"].mean(), abs=1e-6)
    # and through Parquet
    write_run(tmp_path / "x.parquet", run)
    back = read_run(tmp_path / "x.parquet")
    pd.testing.assert_frame_equal(back.frame, out)
    assert back.meta["source_sha256"] == m["source_sha256"]


def test_csv_minimal_columns_default_provenance_and_extra_column(tmp_path):
    frame = _synthetic()[["delta", "time", "r", "psi"]].copy()
    frame["phi"] = 0.5
    text = "# a free-text note\n" + frame.to_csv(index=False, lineterminator="\n")
    run = parse_raw(text, name="mine.csv")
    assert run.meta["provenance"] == "measured"
    assert run.meta["comments"] == ["a free-text note"]
    assert run.meta["approach_speed"] is None
    assert set(run.frame.columns) == {"time", "delta", "r", "psi", "phi"}
    np.testing.assert_allclose(run.frame["phi"], 0.5)


def test_side_from_rudder_when_name_lacks_it(tmp_path):
    frame = _synthetic()
    frame["delta"] = -frame["delta"]
    frame["r"] = -frame["r"]
    frame["psi"] = -frame["psi"]
    path = _write_csv(tmp_path / "z.csv", frame, "# test: zigzag 20/20\n")
    m = read_raw(path).meta
    assert m["first_side"] == "port" and m["first_side_from"] == "rudder"


def test_heading_is_unwrapped(tmp_path):
    frame = _synthetic()
    frame["psi"] = 3.0 * frame["time"]                 # steady turn, 3 deg/s
    frame["r"] = 3.0
    wrapped = frame.copy()
    wrapped["psi"] = (frame["psi"] + 180.0) % 360.0 - 180.0
    run = read_raw(_write_csv(tmp_path / "turn.csv", wrapped))
    np.testing.assert_allclose(run.frame["psi"], frame["psi"], atol=1e-5)


def test_missing_samples_are_noted_not_silently_bridged(tmp_path):
    """Samples missing from a log (shorter than the gap limit, so bridged by the resampling's
    interpolation) are said in the run's ingest_notes: how many gaps, the longest and where.  A logger's
    jitter of a fifth of a step is not a gap; a clean log has no such note."""
    frame = _synthetic()
    clean = ingest_file(_write_csv(tmp_path / "clean.csv", frame))
    assert not any("gap" in n for n in clean.meta.get("ingest_notes", []))
    holed = frame.drop(frame.index[100:103]).drop(frame.index[300:301])     # 3 samples, then 1
    notes = ingest_file(_write_csv(tmp_path / "holed.csv", holed)).meta["ingest_notes"]
    gap = [n for n in notes if "gap" in n]
    assert gap == ["2 gaps in time (samples missing), the longest 0.32 s after 7.92 s; interpolated over by "
                   "the resampling"], notes
    jit = frame.copy()
    jit["time"] = jit["time"] + np.random.default_rng(1).uniform(-0.016, 0.016, len(jit))
    assert not any("gap" in n for n in ingest_file(_write_csv(tmp_path / "jit.csv", jit)).meta.get(
        "ingest_notes", []))


def test_mixed_rate_and_strong_jitter_are_not_missing_samples(tmp_path):
    """A logger that changes its rate (0.04 s steps, then 0.08 s) or whose stamps jitter by up to 0.4
    of a step has no samples missing; a dropped sample in the slower part still is one."""
    frame = _synthetic(n=800, dt=0.04)
    mixed = pd.concat([frame.iloc[:400], frame.iloc[400::2]], ignore_index=True)
    notes = ingest_file(_write_csv(tmp_path / "mixed.csv", mixed)).meta.get("ingest_notes", [])
    assert not any("missing" in n for n in notes), notes
    holed = mixed.drop(mixed.index[500])
    notes = ingest_file(_write_csv(tmp_path / "mholed.csv", holed)).meta.get("ingest_notes", [])
    assert [n for n in notes if "missing" in n] == [
        "1 gap in time (samples missing), the longest 0.16 s after 23.92 s; interpolated over by the "
        "resampling"], notes
    jit = _synthetic()
    jit["time"] = jit["time"] + np.random.default_rng(2).uniform(-0.032, 0.032, len(jit))
    assert np.max(np.diff(jit["time"])) > 1.5 * 0.08                 # steps beyond 1.5 of the median
    notes = ingest_file(_write_csv(tmp_path / "jit.csv", jit)).meta.get("ingest_notes", [])
    assert not any("missing" in n for n in notes), notes


def test_detect_format():
    assert detect_format(TANK_HEADER.splitlines() + ["time,psi,r,delta", "0,0,0,0"]) == "csv"
    assert detect_format(MARIN_FILE.read_text().splitlines()) == "marin"
    hsva = [" HSVA, experimental data CPMC", " KVLCC2", " Z20/10", " Time series",
            " ".join(["1.0"] * 12)]
    assert detect_format(hsva) == "hsva"
    with pytest.raises(InputError, match="unknown format"):
        detect_format(["hello", "1 2 3"], file="x.dat")


# ------------------------------------------------------------------ MARIN
def _quantum(full_values):
    """Half a unit in the 3rd significant digit of the largest full-scale value."""
    m = np.max(np.abs(full_values))
    return 0.5 * 10.0 ** (np.floor(np.log10(m)) - 2) if m > 0 else 0.0


def test_marin_fixture_matches_its_truth():
    truth = marin_truth()
    run = ingest_file(MARIN_FILE, scale=MARIN_SCALE)
    m = run.meta
    s = np.sqrt(MARIN_SCALE)
    # step rebuilt from the rounded time column: full-scale 0.5 s -> model 0.5/sqrt(45.7)
    assert m["original_dt"] == pytest.approx(0.5 / s, rel=1e-4)
    assert m["scale_factor"] == MARIN_SCALE and m["source_format"] == "marin"
    assert m["ship"] == "KVLCC2" and m["lpp"] == pytest.approx(320.0 / MARIN_SCALE)
    assert (m["kind"], m["rudder_deg"], m["heading_deg"]) == ("zigzag", 20.0, 20.0)
    assert m["first_side"] == "starboard"                 # canonical: the truth's first rudder is +20
    assert m["duration"] == pytest.approx(truth["time"][-1], abs=0.08)
    f = run.frame
    # reference: the truth through the same resampling, so that only the file's conversion is checked
    cols = ["time", "x0", "y0", "psi", "u", "v", "r", "delta", "rpm", "phi", "p"]
    ref_run = resample(Run(frame=pd.DataFrame({c: truth[c] for c in cols}), meta={}), 0.08)
    assert len(ref_run.frame) == len(f)
    # tolerance per column: the file's 3-digit rounding, brought to model scale
    full_factor = {"x0": MARIN_SCALE, "y0": MARIN_SCALE, "psi": 1, "phi": 1, "delta": 1,
                   "r": 1 / s, "p": 1 / s, "rpm": 1 / s, "u": s, "v": s}
    for c, fac in full_factor.items():
        ref = ref_run.frame[c].to_numpy()
        if c in ("u", "v"):      # rotated from dx0, dy0: rounding of both, plus psi rounding
            tol = 2 * max(_quantum(truth["dx0"] * s), _quantum(truth["dy0"] * s)) / s \
                + np.max(np.abs(truth["u"])) * np.deg2rad(_quantum(truth["psi"]))
        else:
            tol = _quantum(truth[c] * fac) / fac
        tol = 2.2 * tol      # rounding errors pass the anti-alias filter (impulse-response l1 norm 2.18)
        err = np.max(np.abs(f[c].to_numpy() - ref))
        assert err <= tol, f"{c}: error {err:.4g} > {tol:.4g}"
    # the sign flip really happened: r follows +delta (canonical), not -delta
    k = int(np.argmax(np.abs(f["delta"]) > 10))
    assert f["delta"].iloc[k] > 0 and f["r"].iloc[k + 20] > 0


def test_marin_time_step_rebuilt_exactly_from_rounded_column():
    truth = marin_truth()
    raw = read_raw(MARIN_FILE, scale=MARIN_SCALE)
    np.testing.assert_allclose(raw.frame["time"], truth["time"], atol=1e-9)
    text = MARIN_FILE.read_text().splitlines()
    times = [float(s.split()[0]) for s in text[3:] if s.strip()]
    assert len(set(times)) < len(times)                    # the file really repeats time values


@pytest.mark.slow
def test_bench_rows():
    from pipeline.bench.ingest import run as bench_run

    rows = bench_run(quick=True)
    assert rows[0]["unit"] == "s" and 0 < rows[0]["value"] < 20
    assert rows[1]["value"] == pytest.approx(360_000 / rows[0]["value"])


def test_marin_full_scale_without_scale_is_refused():
    """Full-scale KVLCC2 files taken as model scale must not pass silently."""
    with pytest.raises(InputError, match=r"Lpp 320 m .*look full scale: give the scale") as err:
        read_raw(MARIN_FILE, config=IngestConfig(max_abs_rate=90.0))
    assert "\n" not in str(err.value) and "marin_zigzag_fullscale.dat" in str(err.value)


def test_marin_model_scale_file_of_a_known_ship_takes_the_model_scale(tmp_path):
    """Model-scale MARIN files naming a known ship (KVLCC2, 320 m): without a model scale the Lpp
    is 320 m at scale 1 and the file is refused; with ``model_scale`` (a dataset.toml's
    ``[data] model_scale``) the model's Lpp is 320 / 45.7 = 7.0 m and it reads as the full-scale file
    read with --scale 45.7."""
    # Froude exponents of: time x0 y0 phi psi dx0 dy0 p r delta rev
    froude = (0.5, 1.0, 1.0, 0.0, 0.0, 0.5, 0.5, -0.5, -0.5, 0.0, -0.5)
    lines = MARIN_FILE.read_text().splitlines()
    out = lines[:3]
    for k, line in enumerate(lines[3:]):
        if line.strip():   # the time column rebuilt exactly (the file's is rounded to 3 digits)
            vals = [float(x) * MARIN_SCALE ** -e for x, e in zip(line.split("\t"), froude, strict=True)]
            vals[0] = k * MARIN_FULL_DT / MARIN_SCALE ** 0.5
            line = "\t".join(f"{x:.6E}" for x in vals)
        out.append(line)
    model = tmp_path / "kvlcc2_model.dat"
    model.write_text("\n".join(out) + "\n")
    with pytest.raises(InputError, match=r"Lpp 320 m"):
        read_raw(model)
    run = read_raw(model, model_scale=MARIN_SCALE)
    assert run.meta["lpp"] == pytest.approx(320.0 / MARIN_SCALE)
    full = read_raw(MARIN_FILE, scale=MARIN_SCALE)
    t = full.frame["time"].to_numpy()
    for col, tol in (("psi", 0.02), ("r", 0.02), ("u", 1e-3)):
        assert np.max(np.abs(np.interp(t, run.frame["time"], run.frame[col]) - full.frame[col])) < tol, col


# ------------------------------------------------------------------ resampling
def test_header_lpp_of_a_full_scale_csv_is_scaled_with_the_file(tmp_path, capsys):
    """A full-scale file stating its ship's Lpp in its header, ingested with --scale: the header's
    Lpp is at the file's scale, so the run records the model's Lpp = Lpp / scale (and the Froude number
    of the model-scale run).  The same file without --scale is refused: 230 m is no tank model."""
    lam, lpp_full = 37.89, 230.0
    f = _synthetic()
    s = np.sqrt(lam)
    full = f.assign(time=f["time"] * s, x0=f["x0"] * lam, y0=f["y0"] * lam, u=f["u"] * s, v=f["v"] * s,
                    r=f["r"] / s, rpm=f["rpm"] / s)
    # a ship ingest does not know, so only the header can give the length
    head = f"# ship: MYSHIP\n# Lpp: {lpp_full:g}\n# test: zigzag 20/20 starboard\n"
    path = _write_csv(tmp_path / "zz_full.csv", full, header=head)
    assert main(["ingest", str(path), "--scale", str(lam), "--out", str(tmp_path / "runs")]) == 0
    meta = read_run(tmp_path / "runs" / "zz_full.parquet").meta
    assert meta["lpp"] == pytest.approx(lpp_full / lam, rel=1e-12)
    assert meta["lpp_source"] == "the file's header"
    assert meta["froude_number"] == pytest.approx(2.0 / np.sqrt(9.81 * lpp_full / lam), rel=0.01)
    capsys.readouterr()
    assert main(["ingest", str(path), "--out", str(tmp_path / "runs2")]) == 2
    err = capsys.readouterr().err
    assert "Lpp 230 m" in err and "not a tank model" in err and not (tmp_path / "runs2").exists()


def _tone_run(dt_in, duration, freqs_amps, jitter=0.0, seed=0):
    t = np.arange(int(round(duration / dt_in)) + 1) * dt_in
    if jitter:
        t = t + np.random.default_rng(seed).uniform(-jitter, jitter, t.size) * dt_in
        t[0] = 0.0
    sig = sum(a * np.sin(2 * np.pi * f * t) for f, a in freqs_amps)
    slow = np.sin(2 * np.pi * 0.1 * t)
    r = 2 * np.pi * 0.1 * 10 * np.cos(2 * np.pi * 0.1 * t)
    frame = pd.DataFrame({"time": t, "psi": 10 * slow, "r": r, "delta": slow + sig})
    return Run(frame=frame, meta={"source_file": "tone"}), t


@pytest.mark.parametrize("jitter", [0.0, 0.2])
def test_resampling_suppresses_tone_above_new_nyquist(jitter):
    # 100 Hz log, new step 0.08 s (Nyquist 6.25 Hz); a 9 Hz tone would alias to 3.5 Hz
    run, _ = _tone_run(0.01, 60.0, [(9.0, 1.0)], jitter=jitter)
    out = resample(run, 0.08)
    t = out.frame["time"].to_numpy()
    slow = np.sin(2 * np.pi * 0.1 * t)
    err = out.frame["delta"].to_numpy() - slow
    inner = (t > 0.5) & (t < t[-1] - 0.5)                   # the end samples are pinned to the data
    assert np.max(np.abs(err[inner])) < 0.01                # tone gone, slow part kept
    # naive decimation (no low-pass) keeps a full-amplitude alias: the test can fail
    naive = np.interp(t, run.frame["time"], run.frame["delta"]) - slow
    assert np.max(np.abs(naive)) > 0.5
    assert out.meta["dt"] == 0.08 and out.meta["original_dt"] == pytest.approx(0.01, rel=1e-3 + jitter)


def test_resampling_keeps_slow_content_and_passband():
    run, _ = _tone_run(0.05, 60.0, [(1.0, 0.5)])
    out = resample(run, 0.08)
    t = out.frame["time"].to_numpy()
    ref = np.sin(2 * np.pi * 0.1 * t) + 0.5 * np.sin(2 * np.pi * 1.0 * t)
    assert np.max(np.abs(out.frame["delta"].to_numpy() - ref)) < 0.01
    assert np.max(np.abs(out.frame["psi"].to_numpy() - 10 * np.sin(2 * np.pi * 0.1 * t))) < 1e-3


def test_resampling_grid_and_upsampling():
    run, t_in = _tone_run(0.1, 20.05, [])
    out = resample(run, 0.08)
    t = out.frame["time"].to_numpy()
    assert t[0] == 0.0 and t[-1] <= t_in[-1] + 1e-12 and np.allclose(np.diff(t), 0.08)
    # finer step: linear interpolation only, samples at common instants unchanged
    common = np.isclose((t / 0.4) % 1.0, 0.0) | np.isclose((t / 0.4) % 1.0, 1.0)
    ref = np.interp(t[common], t_in, run.frame["delta"])
    np.testing.assert_allclose(out.frame["delta"].to_numpy()[common], ref, atol=1e-9)
    assert out.meta["antialias"] == "none"


def test_resampling_refuses_too_few_samples():
    run, _ = _tone_run(0.05, 3.0, [])
    with pytest.raises(InputError, match="too few samples"):
        resample(run, 0.08)


# ------------------------------------------------------------------ CLI
def test_cli_writes_runs_and_index(tmp_path, capsys):
    raw = tmp_path / "raw"
    raw.mkdir()
    _write_csv(raw / "kcs_zigzag_20_20_S.csv", _synthetic())
    _write_csv(raw / "kcs_zigzag_10_10_P.csv", _synthetic(seed=4),
               TANK_HEADER.replace("20/20 starboard", "10/10 port"))
    (raw / "README.md").write_text("notes")
    out = tmp_path / "processed" / "virtual" / "runs"
    rc = main(["ingest", *sorted(str(p) for p in raw.iterdir()), "--out", str(out)])
    assert rc == 0
    index = read_json(out / "index.json")
    assert index["dataset"] == "virtual" and index["provenance"] == "virtual"
    ids = [e["run_id"] for e in index["runs"]]
    assert ids == ["kcs_zigzag_10_10_P", "kcs_zigzag_20_20_S"]
    for e in index["runs"]:
        run = read_run(out / e["file"])
        assert run.meta["source_sha256"] == e["source_sha256"]
        assert e["samples"] == len(run.frame)
    assert index["runs"][0]["first_side"] == "port" and index["runs"][0]["heading_deg"] == 10.0
    assert sorted(p.name for p in out.iterdir()) == ["index.json", "kcs_zigzag_10_10_P.parquet",
                                                     "kcs_zigzag_20_20_S.parquet"]
    assert "skipped" in capsys.readouterr().err


def test_cli_dt_option(tmp_path):
    path = _write_csv(tmp_path / "a.csv", _synthetic())
    out = tmp_path / "o" / "runs"
    assert main(["ingest", str(path), "--out", str(out), "--dt", "0.16", "--dataset", "mine"]) == 0
    run = read_run(out / "a.parquet")
    assert np.allclose(np.diff(run.frame["time"]), 0.16)
    assert read_json(out / "index.json")["dataset"] == "mine"


def _marin_circle(tmp_path, spike_at: int | None = None, spike_deg: float = 30.0, wrap: bool = False) -> Path:
    """A model-scale turning circle in the MARIN layout (3 significant digits): 3 deg/s for 400 s, the
    heading through 1185 deg, white heading noise of 0.05 deg; optionally a heading spike, optionally
    the heading written wrapped to [-180, 180) deg."""
    from truths.files import write_marin

    t = np.arange(0.0, 400.0, 0.1)
    r = 3.0 * np.clip(t / 5.0, 0.0, 1.0)
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * 0.1)])
    psi = psi + np.random.default_rng(2).normal(0.0, 0.05, t.size)
    if spike_at is not None:
        psi[spike_at] += spike_deg
    if wrap:
        psi = (psi + 180.0) % 360.0 - 180.0
    f = pd.DataFrame({"time": t, "x0": 0.0 * t, "y0": 0.0 * t, "psi": psi, "u": np.full(t.size, 1.0),
                      "v": np.full(t.size, -0.05), "r": r, "delta": np.full(t.size, 35.0), "rpm": 600.0})
    return write_marin(f, tmp_path / "circle.dat", "Turning circle 35 deg starboard for Model")


def test_marin_rounding_is_not_a_spike(tmp_path):
    """The MARIN layout writes 3 significant digits, so a heading beyond 999 deg is written to 10 deg;
    a turning circle's third turn flickers across rounding boundaries (1000 between 999 and 1010:
    5 deg off its neighbours' mean).  That is the format, not the ship: the run is read, its heading
    within half a unit of the last digit; a real 30 deg spike is still refused, below and beyond 999
    deg (known answers of checks.last_digit_unit too)."""
    from pipeline.ingest.checks import last_digit_unit

    units = last_digit_unit(np.array([1230.0, -99.9, 0.5, 0.0]), 3)
    assert list(units) == pytest.approx([10.0, 0.1, 0.001, 0.0])
    run = ingest_file(_marin_circle(tmp_path))
    assert run.frame["psi"].iloc[-1] > 1100.0
    true = 3.0 * run.frame["time"].to_numpy() - 7.5
    late = run.frame["time"].to_numpy() > 10.0
    assert np.max(np.abs(run.frame["psi"].to_numpy()[late] - true[late])) < 5.5
    for row in (2500, 3800):        # heading about 740 and 1130 deg
        with pytest.raises(InputError, match="spike") as e:
            ingest_file(_marin_circle(tmp_path, spike_at=row))
        assert f"row {row + 4}" in str(e.value) and "'psi'" in str(e.value)
    # written wrapped, the heading is unwrapped to the same turn; the threshold is the file's digit
    wrapped = ingest_file(_marin_circle(tmp_path, wrap=True))
    assert np.max(np.abs(wrapped.frame["psi"].to_numpy()[late] - true[late])) < 1.0
    with pytest.raises(InputError, match="spike"):
        ingest_file(_marin_circle(tmp_path, spike_at=3800, spike_deg=5.0, wrap=True))


# ------------------------------------------------------------------ ingest never overwrites
def _tree_bytes(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (hidden ones and those beside it included) with its bytes."""
    return {str(p.relative_to(root.parent)): p.read_bytes()
            for p in sorted(root.parent.rglob("*")) if p.is_file()}


def test_cli_ingest_one_file_at_a_time_keeps_both(tmp_path, capsys):
    a = _write_csv(tmp_path / "a.csv", _synthetic())
    b = _write_csv(tmp_path / "b.csv", _synthetic(seed=4),
                   TANK_HEADER.replace("20/20 starboard", "10/10 port"))
    out = tmp_path / "D"
    out.mkdir()
    (out / "notes.txt").write_text("the user's own notes")
    assert main(["ingest", str(a), "--out", str(out)]) == 0
    a_bytes = (out / "a.parquet").read_bytes()
    assert main(["ingest", str(b), "--out", str(out)]) == 0
    index = read_json(out / "index.json")
    assert [e["run_id"] for e in index["runs"]] == ["a", "b"]
    assert (out / "a.parquet").read_bytes() == a_bytes            # kept unchanged
    assert index["runs"][0]["source_sha256"] == hashlib.sha256(a.read_bytes()).hexdigest()
    assert index["runs"][1]["heading_deg"] == 10.0
    assert (out / "notes.txt").read_text() == "the user's own notes"
    assert "2 runs, 1 kept" in capsys.readouterr().out
    # re-ingesting a with another step replaces only a
    assert main(["ingest", str(a), "--out", str(out), "--dt", "0.16"]) == 0
    assert np.allclose(np.diff(read_run(out / "a.parquet").frame["time"]), 0.16)
    assert np.allclose(np.diff(read_run(out / "b.parquet").frame["time"]), 0.08)
    assert [e["run_id"] for e in read_json(out / "index.json")["runs"]] == ["a", "b"]


def test_cli_refused_file_leaves_the_folder_byte_for_byte(tmp_path, capsys):
    a = _write_csv(tmp_path / "a.csv", _synthetic())
    out = tmp_path / "processed" / "D"
    assert main(["ingest", str(a), "--out", str(out)]) == 0
    (out / "mine.csv").write_text("1,2,3\n")
    before = _tree_bytes(out)
    frame = _synthetic()
    frame.loc[100, "r"] = np.nan
    bad = _write_csv(tmp_path / "bad.csv", frame)
    good = _write_csv(tmp_path / "c.csv", _synthetic(seed=5))
    assert main(["ingest", str(good), str(bad), "--out", str(out)]) == 2
    assert "bad.csv" in capsys.readouterr().err
    assert _tree_bytes(out) == before


def test_cli_damaged_run_in_the_folder_is_named(tmp_path, capsys):
    import pyarrow as pa
    import pyarrow.parquet as pq

    a = _write_csv(tmp_path / "a.csv", _synthetic())
    out = tmp_path / "processed" / "D"
    assert main(["ingest", str(a), "--out", str(out)]) == 0
    table = pq.read_table(out / "a.parquet")
    table = table.replace_schema_metadata({b"tanktest.run": b"{not json"})
    pq.write_table(table, out / "a.parquet")
    before = _tree_bytes(out)
    b = _write_csv(tmp_path / "b.csv", _synthetic(seed=4))
    assert main(["ingest", str(b), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "a.parquet" in err[0] and "tanktest.run" in err[0]
    assert "Traceback" not in err[0]
    assert _tree_bytes(out) == before
    with pytest.raises(InputError, match="not valid JSON"):
        read_run(out / "a.parquet")
    # a Parquet file of the user's that is not a run is kept and left out of the index
    pq.write_table(pa.table({"x": [1.0, 2.0]}), out / "a.parquet")
    assert main(["ingest", str(b), "--out", str(out)]) == 0
    assert [e["run_id"] for e in read_json(out / "index.json")["runs"]] == ["b"]
    assert pq.read_table(out / "a.parquet").column_names == ["x"]
    assert "not a processed run" in capsys.readouterr().err


def test_commands_writing_into_one_out_folder_keep_each_others_files(tmp_path):
    """ingest, identify and ingest again into the same --out: nothing of either is removed."""
    out = tmp_path / "D"
    a = _write_csv(tmp_path / "a.csv", _synthetic(n=700))
    assert main(["ingest", str(a), "--out", str(out)]) == 0
    assert main(["identify", str(out / "a.parquet"), "--out", str(out), "--samples", "300"]) == 0
    b = _write_csv(tmp_path / "b.csv", _synthetic(n=700, seed=4))
    assert main(["ingest", str(b), "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["a.parquet", "b.parquet", "estimates.json", "index.json",
                                                     "timing.json", "trace.parquet"]
    assert main(["identify", str(out / "b.parquet"), "--out", str(out), "--samples", "300"]) == 0
    assert read_json(out / "estimates.json")["run_id"] == "b"
    assert [e["run_id"] for e in read_json(out / "index.json")["runs"]] == ["a", "b"]
