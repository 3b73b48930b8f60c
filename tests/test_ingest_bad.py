"""Bad input (docs/contract.md#bad-input): one clear line, non-zero exit, nothing written, outputs kept."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pipeline.cli import main
from pipeline.errors import PipelineError
from pipeline.ingest import FORMATS, parse_raw
from pipeline.io import Run

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fuzzing import examples  # noqa: E402
from make_fixtures import BAD, MARIN_FILE  # noqa: E402

BAD_DIR = Path(__file__).resolve().parent / "data" / "bad"
GOOD = """# test: zigzag 10/10 starboard
time,psi,r,delta
""" + "\n".join(f"{k * 0.08:.2f},{k * 0.08:.4f},1.0,5.0" for k in range(80)) + "\n"


def test_corpus_is_complete():
    assert sorted(p.name for p in BAD_DIR.iterdir()) == sorted(BAD)


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_file_refused_with_one_line(name, tmp_path, capsys):
    text, row = BAD[name]
    out = tmp_path / "runs"
    rc = main(["ingest", str(BAD_DIR / name), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc != 0
    assert "\n" not in err and err.startswith("error: ")
    assert name in err and text in err, err
    if row is not None:
        assert f"row {row}" in err, err
    assert not out.exists() or not any(out.iterdir())
    assert [p.name for p in tmp_path.iterdir() if p.name != "runs"] == []     # no temporary left


def test_bad_file_leaves_earlier_outputs_untouched(tmp_path, capsys):
    good1, good2 = tmp_path / "good1.csv", tmp_path / "good2.csv"
    good1.write_text(GOOD)
    good2.write_text(GOOD)
    out = tmp_path / "proc" / "runs"
    assert main(["ingest", str(good1), "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert set(before) == {"good1.parquet", "index.json"}
    rc = main(["ingest", str(good2), str(good1), str(BAD_DIR / "time_gap.csv"), "--out", str(out)])
    assert rc != 0
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in out.parent.iterdir()) == [".runs.set.json", "runs"]
    assert "time_gap.csv" in capsys.readouterr().err


def test_missing_file_and_bad_format_option(tmp_path, capsys):
    assert main(["ingest", str(tmp_path / "nope.csv"), "--out", str(tmp_path / "o")]) == 2
    assert "nope.csv" in capsys.readouterr().err
    good = tmp_path / "g.csv"
    good.write_text(GOOD)
    assert main(["ingest", str(good), "--format", "hsva", "--out", str(tmp_path / "o")]) == 2
    assert "g.csv" in capsys.readouterr().err
    assert main(["ingest", str(good), "--scale", "-3", "--out", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o").exists()


def test_marin_text_with_a_broken_value_names_row_and_column():
    lines = MARIN_FILE.read_text().splitlines()
    lines[10] = lines[10].replace("E", "X", 1)
    with pytest.raises(PipelineError) as exc:
        parse_raw("\n".join(lines), name="m.dat")
    assert "row 11" in str(exc.value) and "column 'time'" in str(exc.value)


def test_marin_text_with_a_fortran_exponent_is_read():
    """A value written with a Fortran exponent (1.5D+00) is a number: the column is read, the value
    parsed (found by the fuzz test below: pandas 3 handed out a read-only array, ValueError)."""
    lines = MARIN_FILE.read_text().splitlines()
    toks = lines[10].split()
    first = float(toks[0])
    lines[10] = lines[10].replace(toks[0], f"{first:.6E}".replace("E", "D"), 1)
    run = parse_raw("\n".join(lines), name="m.dat", scale=45.7)  # the file is full scale
    ref = parse_raw(MARIN_FILE.read_text(), name="m.dat", scale=45.7)
    assert run.frame.equals(ref.frame)


# ---------------------------------------------------------------- property: never another exception
_token = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(lambda x: f"{x:.3g}"),
    st.integers(-1000, 1000).map(str),
    st.sampled_from(["", "nan", "inf", "abc", "1e999", "-", "1.2.3", "time", "psi", "r", "delta", "#", "°",
                     "\t", '"', "0x1f", "1_0", "NaN", "E+02"]),
    st.text(max_size=6),
)
_line = st.lists(_token, max_size=13).flatmap(
    lambda toks: st.sampled_from([",", "\t", " ", "  "]).map(lambda sep: sep.join(toks)))
_headers = st.sampled_from(["", "# test: zigzag 20/20\ntime,psi,r,delta\n",
                            "time,x0,y0,psi,u,v,r,delta,rpm\n",
                            "MARIN\nZig-zag manoeuvring for KVLCC2 : 20 / -20\n\n",
                            " HSVA, experimental data CPMC\n KVLCC2\n Z20°/10° starting to port\n Title\n"])


@settings(max_examples=examples(150), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(header=_headers, lines=st.lists(_line, max_size=30), fmt=st.sampled_from([None, *FORMATS]),
       as_bytes=st.booleans())
def test_malformed_text_gives_run_or_pipeline_error(header, lines, fmt, as_bytes):
    text = header + "\n".join(lines)
    data = text.encode("latin-1", errors="replace") if as_bytes else text
    try:
        run = parse_raw(data, name="fuzz.txt", fmt=fmt)
    except PipelineError as exc:
        assert "\n" not in str(exc)
        return
    assert isinstance(run, Run) and {"time", "psi", "r", "delta"} <= set(run.frame.columns)


@settings(max_examples=examples(60), deadline=None)
@given(cut=st.integers(0, 4000), junk=st.binary(max_size=40), fmt=st.sampled_from([None, *FORMATS]))
def test_damaged_real_layouts_give_run_or_pipeline_error(cut, junk, fmt):
    data = MARIN_FILE.read_bytes()
    data = data[:cut] + junk + data[cut + len(junk):]
    try:
        run = parse_raw(data, name="fuzz.dat", fmt=fmt)
    except PipelineError:
        return
    assert isinstance(run, Run)


# ------------------------------------------------------------------ headers, scales, formats, echoes
TEST_ROWS = "\n".join(f"{k * 0.08:.2f},{k * 0.08:.4f},1.0,5.0" for k in range(80)) + "\n"


@pytest.mark.parametrize("line,msg", [
    ("# scale: 0", "header value 'scale' must be a positive finite number, got 0"),
    ("# scale: -45.7", "header value 'scale' must be a positive finite number, got -45.7"),
    ("# scale: nan", "header value 'scale' must be a positive finite number, got nan"),
    ("# scale: 0.5", "header value 'scale' must be a scale factor full/model between 1 and 1000, got 0.5"),
    ("# Lpp: 0", "header value 'lpp' must be a positive finite number, got 0"),
    ("# lpp: inf", "header value 'lpp' must be a positive finite number, got inf"),
    ("# dt: -0.1", "header value 'dt' must be a positive finite number, got -0.1"),
])
def test_header_values_that_cannot_be_are_refused(line, msg):
    with pytest.raises(PipelineError) as err:
        parse_raw(f"{line}\n# test: zigzag 10/10 starboard\ntime,psi,r,delta\n" + TEST_ROWS, name="h.csv")
    assert str(err.value) == f"h.csv: {msg}"


@pytest.mark.parametrize("argv,msg", [
    (["--scale", "1e300"], "scale factor must be full/model between 1 and 1000, got 1e+300"),
    (["--scale", "inf"], "scale factor must be a positive finite number, got inf"),
])
def test_scales_that_cannot_be_give_the_right_message(tmp_path, capsys, argv, msg):
    path = tmp_path / "g.csv"
    path.write_text(GOOD)
    assert main(["ingest", str(path), "--out", str(tmp_path / "o"), *argv]) == 2
    assert capsys.readouterr().err.strip() == f"error: {path}: {msg}"


def test_model_scale_inf_in_the_description_names_the_key(tmp_path, capsys):
    (tmp_path / "raw" / "d").mkdir(parents=True)
    (tmp_path / "raw" / "d" / "g.csv").write_text(GOOD)
    (tmp_path / "raw" / "d" / "dataset.toml").write_text("[data]\nmodel_scale = inf\n")
    argv = ["ingest", "--dataset", "d", "--raw", str(tmp_path / "raw"), "--root", str(tmp_path / "p")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("dataset.toml: [data] model_scale must be a positive finite number, got inf"), err


def _marin_lines(extra_column: bool) -> str:
    lines = MARIN_FILE.read_text().splitlines()
    if extra_column:
        lines = lines[:3] + [ln + "\t0.00E+00" if ln.strip() else ln for ln in lines[3:]]
    return "\n".join(lines) + "\n"


def test_twelve_column_marin_file_is_named_as_such():
    with pytest.raises(PipelineError) as err:
        parse_raw(_marin_lines(True), name="m.dat")
    assert str(err.value) == ("m.dat: the header says MARIN .dat, whose rows have 11 columns, but row 4 "
                              "has 12: not a MARIN file of the layout the reader knows (docs/dataset.md); "
                              "give --format to read it as another")
    with pytest.raises(PipelineError, match=r"m.dat, row 4: a MARIN .dat has 11 columns, this row has 12"):
        parse_raw(_marin_lines(True), name="m.dat", fmt="marin")


def test_eleven_column_hsva_file_is_named_as_such(hsva_dir):
    lines = sorted(hsva_dir.glob("*.dat"))[0].read_bytes().decode("latin-1").splitlines()
    cut = lines[:4] + [" ".join(ln.split()[:11]) for ln in lines[4:] if ln.strip()]
    with pytest.raises(PipelineError) as err:
        parse_raw("\n".join(cut) + "\n", name="h.dat")
    assert "the header says HSVA .dat, whose rows have 12 columns, but row 5 has 11" in str(err.value)
    with pytest.raises(PipelineError, match=r"h.dat, row 5: a HSVA .dat has 12 columns, this row has 11"):
        parse_raw("\n".join(cut) + "\n", name="h.dat", fmt="hsva")


def test_refusals_do_not_quote_files_reached_through_links_or_outside(tmp_path, capsys, monkeypatch):
    secret = tmp_path / "outside" / "secret.txt.dat"
    secret.parent.mkdir()
    secret.write_text("password=hunter2 and more\nline two\n")
    project = tmp_path / "project"
    (project / "data" / "raw" / "d").mkdir(parents=True)
    monkeypatch.chdir(project)
    # a files_dir outside the project
    toml = project / "data" / "raw" / "d" / "dataset.toml"
    toml.write_text('[data]\nfiles_dir = "../../../../outside"\n')
    assert main(["ingest", "--dataset", "d"]) == 2
    err = capsys.readouterr().err
    assert "secret.txt.dat" in err and "hunter2" not in err and "password" not in err, err
    # a symbolic link inside the project
    (project / "data" / "raw" / "d" / "dataset.toml").unlink()
    (project / "data" / "raw" / "d" / "link.dat").symlink_to(secret)
    assert main(["ingest", "--dataset", "d"]) == 2
    err = capsys.readouterr().err
    assert "unknown format" in err and "hunter2" not in err, err
    # the same text in a file of the project is quoted (the user's own file)
    (project / "data" / "raw" / "d" / "link.dat").unlink()
    (project / "data" / "raw" / "d" / "own.dat").write_text(secret.read_text())
    assert main(["ingest", "--dataset", "d"]) == 2
    assert "first line 'password=hunter2 and more'" in capsys.readouterr().err
