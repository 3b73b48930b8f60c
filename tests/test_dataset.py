"""Dataset descriptions (docs/dataset.md): dataset.toml, discovery, scale."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.dataset import BUILTIN, dataset_names, load_dataset, parse_dataset_toml
from pipeline.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
PROBES = ROOT / "tests" / "data" / "probes"
MARIN = ROOT / "tests" / "data" / "marin_zigzag_fullscale.dat"

EXAMPLE = """
[ship]
name = "KVLCC2"
lpp_m = 320.0
beam_m = 58.0
draught_m = 20.8
design_speed_kn = 15.5

[data]
scale = 45.7
tank = "MARIN"
source = "SIMMAN 2008 free-running tests"

[roles]
identify = "zz_20_s"
train = ["zz_20_s", "zz_10_s"]
validate = ["zz_20_p", "zz_10_p"]
test = []

[runs.zz_20_p]
rudder_sign = -1
test_name = "zigzag 20/20 port"
"""

# the example for a folder holding the one MARIN zigzag zz_20_s (roles and overrides name only its runs)
ONE_RUN = EXAMPLE.split("[roles]")[0] + '[roles]\nidentify = "zz_20_s"\n'


def test_example_parses_into_typed_description(tmp_path):
    ds = parse_dataset_toml(EXAMPLE, name="marin", folder=tmp_path, path=tmp_path / "dataset.toml")
    assert ds.ship.name == "KVLCC2" and ds.ship.lpp_m == 320.0 and ds.ship.design_speed_kn == 15.5
    assert ds.scale == 45.7 and ds.tank == "MARIN"
    assert ds.lpp_model_m == pytest.approx(320.0 / 45.7)
    assert ds.roles.identify == "zz_20_s" and ds.roles.validate == ("zz_20_p", "zz_10_p")
    assert ds.runs["zz_20_p"].rudder_sign == -1 and ds.runs["zz_20_p"].test_name == "zigzag 20/20 port"


@pytest.mark.parametrize("text,msg", [
    ("[ship]\nlpp = 320.0\n", "unknown key 'lpp' in [ship]"),
    ("[data]\nscale = -1\n", "[data] scale must be a positive finite number, got -1"),
    ("[data]\nscale = 'big'\n", "[data] scale must be a positive finite number, got the string 'big'"),
    ("[shipp]\nname = 'x'\n", "unknown section [shipp]"),
    ("[data\nscale = 1\n", "not valid TOML"),
    ("[runs.a]\nrudder_sign = 2\n", "rudder_sign must be 1 or -1"),
])
def test_bad_description_is_one_line_naming_the_file(tmp_path, text, msg):
    with pytest.raises(InputError) as err:
        parse_dataset_toml(text, name="x", folder=tmp_path, path=tmp_path / "dataset.toml")
    assert msg in str(err.value) and "dataset.toml" in str(err.value) and "\n" not in str(err.value)


def test_builtin_descriptions_are_the_committed_files():
    for name, text in BUILTIN.items():
        assert (ROOT / "data" / "raw" / name / "dataset.toml").read_text() == text


def _ingest(*argv):
    return main(["ingest", *map(str, argv)])


def test_folder_without_toml_runs_with_notice_and_template(tmp_path, capsys):
    raw = tmp_path / "raw"
    (raw / "mine").mkdir(parents=True)
    shutil.copy(PROBES / "clean.csv", raw / "mine" / "zz.csv")
    (raw / "mine" / "README.md").write_text("notes")
    rc = _ingest("--dataset", "mine", "--raw", raw, "--root", tmp_path / "proc")
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    notice = [ln for ln in cap.err.splitlines() if "no dataset.toml" in ln]
    assert len(notice) == 1 and "assumed model-scale files (scale 1)" in notice[0]
    written = raw / "mine" / "dataset.toml"
    assert written.is_file()
    ds = load_dataset("mine", raw)                        # the template is a valid description
    assert ds.scale == 1.0 and ds.ship.name is None
    index = json.loads((tmp_path / "proc" / "mine" / "runs" / "index.json").read_text())
    assert [r["run_id"] for r in index["runs"]] == ["zz"]


def test_full_scale_folder_scaled_by_its_toml(tmp_path, capsys):
    raw = tmp_path / "raw"
    (raw / "marin").mkdir(parents=True)
    shutil.copy(MARIN, raw / "marin" / "zz_20_s.dat")
    # without a description: refused: without the ship's length the scale cannot be checked
    rc = _ingest("--dataset", "marin", "--raw", raw, "--root", tmp_path / "proc")
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert rc == 2 and "look full scale" in err and "zz_20_s.dat" in err
    assert not (tmp_path / "proc" / "marin").exists()
    (raw / "marin" / "dataset.toml").write_text(ONE_RUN)
    rc = _ingest("--dataset", "marin", "--raw", raw, "--root", tmp_path / "proc")
    assert rc == 0, capsys.readouterr().err
    index = json.loads((tmp_path / "proc" / "marin" / "runs" / "index.json").read_text())
    ship = index["ship"]
    assert (ship["ship"], ship["lpp_m"], ship["scale"], ship["tank"]) == ("KVLCC2", 320.0, 45.7, "MARIN")
    run = index["runs"][0]
    assert run["scale_factor"] == 45.7 and run["lpp"] == pytest.approx(7.0022, abs=1e-3)
    assert 0.13 < run["froude_number"] < 0.16                      # KVLCC2 at Fn 0.142
    assert run["beam_m"] == 58.0 and run["draught_m"] == 20.8
    assert index["roles"]["identify"] == "zz_20_s"
    # an option that contradicts the description is refused
    rc = _ingest("--dataset", "marin", "--raw", raw, "--root", tmp_path / "proc", "--scale", "1")
    assert rc == 2 and "contradicts" in capsys.readouterr().err


def test_run_with_another_raw_root_applies_the_folders_toml(tmp_path, capsys):
    """`pipeline run --dataset NAME --raw DIR` (a raw root other than data/raw): the stage's ingest reads
    DIR/NAME/dataset.toml.  Before, it read data/raw/NAME/dataset.toml, so a full-scale folder's scale
    was not applied and ingest refused the files as "full scale" (found 2026-11-24)."""
    raw = tmp_path / "elsewhere"
    (raw / "marin").mkdir(parents=True)
    shutil.copy(MARIN, raw / "marin" / "zz_20_s.dat")
    (raw / "marin" / "dataset.toml").write_text(ONE_RUN)
    rc = main(["run", "--dataset", "marin", "--raw", str(raw), "--root", str(tmp_path / "proc"),
               "--until", "ingest"])
    assert rc == 0, capsys.readouterr().err
    index = json.loads((tmp_path / "proc" / "marin" / "runs" / "index.json").read_text())
    assert index["ship"]["scale"] == 45.7 and index["runs"][0]["scale_factor"] == 45.7


def test_per_run_override_of_rudder_sign(tmp_path, capsys):
    raw = tmp_path / "raw"
    (raw / "d").mkdir(parents=True)
    shutil.copy(PROBES / "rudder_sign_flipped.csv", raw / "d" / "flipped.csv")
    assert _ingest("--dataset", "d", "--raw", raw, "--root", tmp_path / "p") == 2
    assert "--rudder-sign -1" in capsys.readouterr().err
    (raw / "d" / "dataset.toml").write_text("[data]\nscale = 1\n\n[runs.flipped]\nrudder_sign = -1\n")
    assert _ingest("--dataset", "d", "--raw", raw, "--root", tmp_path / "p") == 0


def test_dataset_names_and_shell_hostile_folder_names(tmp_path, capsys, monkeypatch):
    raw = tmp_path / "raw"
    evil = "x$(touch${IFS}PWNED) and space"
    (raw / evil).mkdir(parents=True)
    (raw / "plain").mkdir()
    shutil.copy(PROBES / "clean.csv", raw / evil / "run one.csv")
    shutil.copy(PROBES / "clean.csv", raw / "loose.csv")
    (raw / ".gitkeep").write_text("")
    monkeypatch.chdir(tmp_path)
    assert main(["datasets", "--raw", str(raw)]) == 0
    names = capsys.readouterr().out.split("\n")[:-1]
    assert names[0] == "virtual" and evil in names and "plain" in names and names[-1] == "local"
    assert "hsva" not in names                          # no hsva description/files under this root
    assert main(["datasets", "--raw", str(raw), "-0"]) == 0
    assert capsys.readouterr().out.split("\0")[:-1] == names
    rc = _ingest("--dataset", evil, "--raw", raw, "--root", tmp_path / "proc")
    assert rc == 0, capsys.readouterr().err
    assert (tmp_path / "proc" / evil / "runs" / "run one.parquet").is_file()
    assert not list(tmp_path.rglob("PWNED"))
    rc = _ingest("--dataset", "local", "--raw", raw, "--root", tmp_path / "proc")
    assert rc == 0 and (tmp_path / "proc" / "local" / "runs" / "loose.parquet").is_file()


def test_dataset_name_must_be_one_folder(tmp_path, capsys):
    assert _ingest("--dataset", "../etc", "--raw", tmp_path, "--root", tmp_path / "p") == 2
    assert "not a single folder name" in capsys.readouterr().err


def test_hsva_dataset_by_description(hsva_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    assert "hsva" in dataset_names()
    rc = _ingest("--dataset", "hsva", "--root", tmp_path / "proc")
    assert rc == 0, capsys.readouterr().err
    index = json.loads((tmp_path / "proc" / "hsva" / "runs" / "index.json").read_text())
    assert len(index["runs"]) == len(list(hsva_dir.glob("*.dat")))
    assert index["ship"]["ship"] == "KVLCC2" and index["ship"]["model_scale"] == 45.7
    assert {round(r["lpp"], 3) for r in index["runs"]} == {7.002}
    # double scaling is refused, from the description and from the file's own statement
    rc = _ingest("--dataset", "hsva", "--root", tmp_path / "proc2", "--scale", "45.7")
    assert rc == 2 and "contradicts" in capsys.readouterr().err
    one = sorted(hsva_dir.glob("*.dat"))[0]
    rc = _ingest(one, "--out", tmp_path / "x", "--scale", "45.7")
    assert rc == 2 and "scale it twice" in capsys.readouterr().err


@pytest.mark.parametrize("text,msg", [
    ("[identify]\nsamples = 585\nhalf_periods = 3\n", "give one identification window"),
    ("[identify]\nwindow_s = -4.0\n", "[identify] window_s must be a positive finite number, got -4.0"),
    ("[identify]\nmeasurement_noise = 'guess'\n", "measurement_noise must be 'paper' or 'data'"),
    ("[identify]\nwindow = 40\n", "unknown key 'window' in [identify]"),
])
def test_bad_identify_settings_are_one_line(tmp_path, text, msg):
    with pytest.raises(InputError) as err:
        parse_dataset_toml(text, name="x", folder=tmp_path, path=tmp_path / "dataset.toml")
    assert msg in str(err.value) and "\n" not in str(err.value)


def _identify_window(raw, root, name, toml, capsys):
    (raw / name).mkdir(parents=True)
    shutil.copy(MARIN, raw / name / "zz_20_s.dat")
    (raw / name / "dataset.toml").write_text(toml)
    assert _ingest("--dataset", name, "--raw", raw, "--root", root) == 0, capsys.readouterr().err
    assert main(["identify", "--dataset", name, "--root", str(root), "--algorithm", "srukf-ffm"]) == 0
    est = json.loads((root / name / "identify" / "srukf-ffm" / "estimates.json").read_text())
    index = json.loads((root / name / "runs" / "index.json").read_text())
    return est, index


def test_identification_window_from_the_toml_is_scale_free(tmp_path, capsys):
    """The same full-scale KVLCC2 zigzag brought to two model scales (1:45.7 and 1:30): a window of
    zigzag half-periods set in dataset.toml covers the same part of the manoeuvre at both (its sample
    count scales with sqrt of the scale ratio), where a fixed 585 samples would not.  The toml's
    measurement_noise = "data" reaches the filter."""
    raw, root = tmp_path / "raw", tmp_path / "proc"
    base = EXAMPLE.split("[roles]")[0]
    out = {}
    for name, lam in (("s457", 45.7), ("s30", 30.0)):
        toml = base.replace("scale = 45.7", f"scale = {lam}") + (
            '[identify]\nhalf_periods = 2.5\nmeasurement_noise = "data"\n')
        out[name] = _identify_window(raw, root, name, toml, capsys)
    (e1, i1), (e2, _) = out["s457"], out["s30"]
    assert i1["identify"] == {"half_periods": 2.5, "measurement_noise": "data"}
    assert "2.5 zigzag half-periods" in e1["window"] and "2.5 zigzag half-periods" in e2["window"]
    # Froude time: the 1:30 model's manoeuvre lasts sqrt(45.7/30) = 1.234 times longer at model scale
    ratio = (e2["samples"] - 1) / (e1["samples"] - 1)
    assert ratio == pytest.approx(np.sqrt(45.7 / 30.0), rel=0.02), (e1["samples"], e2["samples"])
    # the full-scale time the window covers is the same at both scales (within a sample)
    full = [(e["samples"] - 1) * 0.08 * np.sqrt(lam) for e, lam in ((e1, 45.7), (e2, 30.0))]
    assert full[0] == pytest.approx(full[1], abs=0.08 * np.sqrt(45.7))
    assert e1["settings"]["measurement_noise"] == "data"
    assert e1["consistency"]["r_std_source"].startswith("measured from the run")
    assert e1["settings"]["r_std"] != [0.02, 0.02, 0.01]



@pytest.mark.parametrize("declared", ["virtual", "measured"])
def test_declared_provenance_is_the_datasets_as_well_as_each_runs(tmp_path, capsys, declared):
    """A dataset.toml's ``[data] provenance`` is the user's word on what the files are: every run AND
    the dataset's index.json say it, whatever the file's own header says (here the opposite).  The
    index's provenance is what indices, control and their reports label the dataset with.  Found
    2026-11-26: the index was formed from the files before the declaration was applied, so simulated
    files declared "virtual", whose headers said nothing, were reported as "measured"."""
    raw = tmp_path / "raw"
    (raw / "d").mkdir(parents=True)
    other = "measured" if declared == "virtual" else "virtual"
    (raw / "d" / "zz.csv").write_text(f"# provenance: {other}\n" + (PROBES / "clean.csv").read_text())
    (raw / "d" / "dataset.toml").write_text(f'[data]\nscale = 1\nprovenance = "{declared}"\n')
    assert _ingest("--dataset", "d", "--raw", raw, "--root", tmp_path / "p") == 0, capsys.readouterr().err
    index = json.loads((tmp_path / "p" / "d" / "runs" / "index.json").read_text())
    assert index["provenance"] == declared
    assert [r["provenance"] for r in index["runs"]] == [declared]



@pytest.mark.parametrize("entry, builtin", [
    ({"provenance": "virtual", "ship": "KCS", "header": {"note": "virtual tank (MMG model of the KCS, ...)"}},
     True),
    ({"provenance": "virtual", "ship": None}, True),
    ({"provenance": "virtual", "ship": "KCS", "header": {"note": "CFD free-running simulation"}}, False),
    ({"provenance": "virtual", "ship": "bulk carrier"}, False),
    ({"provenance": "measured", "ship": "KCS"}, False),
])
def test_builtin_tank_is_the_tanks_runs_only(entry, builtin):
    """One rule (pipeline.catalog.is_builtin_tank) for every stage that treats the built-in tank's data
    differently (identify's and validate's labels, control's KCS plant, the reports' banner and index):
    provenance virtual, the KCS or no ship, no note but the tank's.  A dataset is the tank's only when
    every run is."""
    from pipeline.catalog import data_label, is_builtin_tank, is_builtin_tank_run

    assert is_builtin_tank_run(entry) is builtin
    # what identify's and validate's documents then say of the data
    label = data_label(builtin, entry["provenance"])
    assert set(label) == ({"virtual_tank"} if builtin else {"simulated"} if entry["provenance"] == "virtual"
                          else set())
    tank = {"provenance": "virtual", "ship": "KCS"}
    assert is_builtin_tank({"provenance": "virtual", "runs": [tank, entry]}) is builtin
    assert is_builtin_tank({"provenance": "virtual", "runs": []}) is False


def test_a_users_simulated_ship_through_every_stage(tmp_path, monkeypatch, capsys):
    """A user's folder as `make pipeline` meets it, through every real stage: a simulated ferry that is
    not the built-in tank (tests/truths/crossflow.py, canonical CSV at model scale, one run with a
    0.3 s dropout), described by a dataset.toml that declares it virtual, points at its files elsewhere
    and gives the diagnosis its roles.  Each stage must read the description as ingest does: the
    dataset virtual but not the tank's (identify says simulated, control runs no KCS), the dropout
    noted, the diagnosis on the given roles.  The faults this guards were found 2026-11-26 on such a
    folder (README, "Running it on your own files")."""
    from selection_only import SELECTION_ONLY
    from truths import crossflow as cf
    from truths.files import write_csv

    monkeypatch.setattr("pipeline.cli.diagnose.DiagnoseConfig", lambda: SELECTION_ONLY)   # CI time
    raw, root, export = tmp_path / "raw", tmp_path / "proc", tmp_path / "logger_export"
    export.mkdir()
    legs = ((20, "starboard"), (10, "port"), (20, "port"), (10, "starboard"))
    for j, (a, side) in enumerate(legs):
        f = cf.simulate_zigzag(cf.hull("ferry"), a, a, side, seed=9100 + j, duration=60.0)
        if j == 3:
            f = f.drop(f.index[400:406])                                   # 0.3 s at 20 Hz
        write_csv(f, export / f"ferry_zz{a}_{side[0].upper()}.csv",
                  {"ship": "ferry model", "test": f"zigzag {a}/{a} {side}"})
    (raw / "ferry").mkdir(parents=True)
    (raw / "ferry" / "dataset.toml").write_text(
        '[ship]\nname = "ferry"\nlpp_m = 160.0\n\n[data]\nscale = 1.0\nmodel_scale = 40.0\n'
        'provenance = "virtual"\nfiles_dir = "../../logger_export"\n\n'
        '[roles]\ntrain = ["ferry_zz20_S", "ferry_zz10_P"]\nvalidate = ["ferry_zz20_P", "ferry_zz10_S"]\n')
    rc = main(["run", "--dataset", "ferry", "--raw", str(raw), "--root", str(root)])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    index = json.loads((root / "ferry" / "runs" / "index.json").read_text())
    assert index["provenance"] == "virtual" and len(index["runs"]) == 4
    holed = next(r for r in index["runs"] if r["run_id"] == "ferry_zz10_S")
    assert any(n.startswith("1 gap in time") for n in holed["ingest_notes"]), holed.get("ingest_notes")
    est = json.loads((root / "ferry" / "identify" / "srukf-ffm" / "estimates.json").read_text())
    assert "simulated" in est and "virtual_tank" not in est
    ctl = json.loads((root / "ferry" / "control" / "metrics.json").read_text())
    assert ctl["virtual"] is True and ctl["builtin_tank"] is False and ctl["plants"]["kcs"]["used"] is False
    diag = json.loads((root / "ferry" / "diagnose" / "diagnosis.json").read_text())
    assert diag["training_runs"] == ["ferry_zz20_S", "ferry_zz10_P"]
    assert diag["validation_runs"] == ["ferry_zz20_P", "ferry_zz10_S"]
    assert "design (the dataset's [roles])" in cap.out


# ------------------------------------------------------------------ descriptions of the wrong shape
def _refused_one_line(text: str, *needles: str) -> str:
    with pytest.raises(InputError) as err:
        parse_dataset_toml(text, name="x", folder=Path("/d"), path=Path("/d/dataset.toml"))
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("/d/dataset.toml: "), msg
    for n in needles:
        assert n in msg, (n, msg)
    return msg


@pytest.mark.parametrize("text,needles", [
    ("runs = 5\n", ("runs must be a table", "got 5")),
    ("runs = \"a\"\n", ("runs must be a table", "the string 'a'")),
    ("[[runs]]\nskip = true\n", ("runs must be a table", "an array of 1")),
    ("ship = 3\n", ("ship must be a table", "got 3")),
    ("[runs]\nzz = 1\n", ("runs.zz must be a table",)),
    ("[identify]\nwindow_s = inf\n", ("[identify] window_s must be a positive finite number", "got inf")),
    ("[identify]\nhalf_periods = nan\n", ("[identify] half_periods must be a positive finite number", "nan")),
    ("[identify]\nsamples = 2.5\n", ("[identify] samples must be a positive integer", "2.5")),
    ("[identify]\nsamples = 0\n", ("[identify] samples must be a positive integer", "got 0")),
    ("[ship]\nlpp_m = inf\n", ("[ship] lpp_m must be a positive finite number", "inf")),
    ("[ship]\nbeam_m = -58\n", ("[ship] beam_m must be a positive finite number", "-58")),
    ("[ship]\nname = 5\n", ("[ship] name must be a string", "got 5")),
    ("[data]\nmodel_scale = inf\n", ("[data] model_scale must be a positive finite number", "inf")),
    ("[data]\nscale = 1e300\n", ("[data] scale must be a scale factor full/model between 1 and 1000",
                                 "1e+300")),
    ("[data]\nscale = true\n", ("[data] scale must be a positive finite number", "got true")),
    ("[data]\nrudder_sign = 1.0\n", ("[data] rudder_sign must be 1 or -1",)),
    ("[data]\nfiles = [1, 2]\n", ("[data] files must be a string or a list of strings",)),
    ("[data]\nprovenance = 'guess'\n", ("[data] provenance must be 'measured' or 'virtual'",)),
    ("[roles]\ntrain = {a = 1}\n", ("[roles] train must be a string or a list of strings", "a table")),
    ("[runs.a]\nskip = 'yes'\n", ("[runs.a] skip must be true or false",)),
    ("[runs.a]\nkind = 'spiral'\n", ("[runs.a] kind must be 'zigzag', 'turning' or 'other'",)),
    ("[control]\ntw_s = [1, 2]\n", ("[control] tw_s must be a number",)),
    ("x = " + "{a = " * 3000 + "1" + "}" * 3000 + "\n", ("nested too deep",)),
    ("[data]\nfiles = " + "[" * 3000 + "]" * 3000 + "\n", ("nested too deep",)),
    ("[runs." + ".".join(["a"] * 3000) + "]\nb = 1\n", ("unknown key 'a' in [runs.a]",)),
    ("[" + ".".join(["a"] * 3000) + "]\nb = 1\n", ("unknown section [a]",)),
    ("wrong = 1\n", ("unknown key 'wrong'",)),
])
def test_description_of_the_wrong_shape_is_one_line_naming_the_key(text, needles):
    _refused_one_line(text, *needles)


def test_control_table_is_accepted_for_the_autopilot():
    ds = parse_dataset_toml("[control]\ntw_s = 2.5\n", name="x", folder=Path("/d"),
                            path=Path("/d/dataset.toml"))
    assert ds.control == {"tw_s": 2.5}


def _toml_value(v) -> str:
    """A value written as TOML (the test's own writer: strings JSON-escaped ASCII, floats with nan/inf)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if v != v:
            return "nan"
        return "inf" if v == float("inf") else "-inf" if v == -float("inf") else repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=True)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"


def _wrong_values():
    """Per kind of key, values that are not of that kind (by construction, not by the reader's test)."""
    from hypothesis import strategies as st

    text = st.text(alphabet=st.characters(codec="ascii", categories=("L", "N", "P", "Zs")), max_size=12)
    scalars = st.one_of(st.integers(), st.floats(allow_nan=True), text, st.booleans())
    arrays = st.lists(scalars, max_size=3)
    tables = st.dictionaries(st.sampled_from(["a", "b", "k"]), scalars, min_size=1, max_size=2)
    not_number = st.one_of(text, st.booleans(), arrays, tables)
    bad_number = st.one_of(st.floats(max_value=0.0), st.integers(max_value=0),
                           st.sampled_from([float("nan"), float("inf"), float("-inf")]))
    return {
        "positive": st.one_of(not_number, bad_number),
        "string": st.one_of(st.integers(), st.floats(allow_nan=True), st.booleans(),
                            st.lists(st.integers(), min_size=1, max_size=3), tables),
        "strings": st.one_of(st.integers(), st.floats(allow_nan=True), st.booleans(), tables,
                             st.lists(st.one_of(st.integers(), st.booleans()), min_size=1, max_size=3)),
        "sign": st.one_of(not_number, st.floats(allow_nan=True), st.integers().filter(lambda i: abs(i) != 1)),
        "count": st.one_of(not_number, st.floats(allow_nan=True), st.integers(max_value=0)),
        "bool": st.one_of(st.integers(), st.floats(allow_nan=True), text, arrays, tables),
    }


_KEY_KINDS = [
    ("ship", "name", "string"), ("ship", "lpp_m", "positive"), ("ship", "beam_m", "positive"),
    ("ship", "draught_m", "positive"), ("ship", "design_speed_kn", "positive"),
    ("data", "scale", "positive"), ("data", "model_scale", "positive"), ("data", "tank", "string"),
    ("data", "source", "string"), ("data", "files_dir", "string"), ("data", "files", "strings"),
    ("data", "rudder_sign", "sign"), ("roles", "identify", "string"), ("roles", "train", "strings"),
    ("roles", "validate", "strings"), ("roles", "test", "strings"), ("identify", "samples", "count"),
    ("identify", "window_s", "positive"), ("identify", "half_periods", "positive"),
    ("runs.r1", "rudder_sign", "sign"), ("runs.r1", "test_name", "string"), ("runs.r1", "skip", "bool"),
]


def test_property_every_wrong_value_is_refused_naming_its_key():
    from hypothesis import given
    from hypothesis import strategies as st

    wrong = _wrong_values()
    cases = st.sampled_from(_KEY_KINDS).flatmap(
        lambda skk: st.tuples(st.just(skk[0]), st.just(skk[1]), wrong[skk[2]]))

    @given(cases)
    def check(case):
        section, key, value = case
        text = f"[{section}]\n{key} = {_toml_value(value)}\n"
        _refused_one_line(text, f"[{section}] {key} must be ")

    check()


def test_property_sections_of_the_wrong_shape_are_refused():
    from hypothesis import given
    from hypothesis import strategies as st

    scalars = st.one_of(st.integers(), st.floats(allow_nan=True), st.booleans(),
                        st.text(alphabet="abc xyz", max_size=5))

    @given(st.sampled_from(["ship", "data", "roles", "identify", "runs", "control"]),
           st.one_of(scalars, st.lists(scalars, max_size=3)))
    def check(section, value):
        _refused_one_line(f"{section} = {_toml_value(value)}\n", f"{section} must be a table")

    check()


def test_runs_and_roles_naming_no_run_are_refused_naming_the_known_ids(tmp_path, capsys):
    raw = tmp_path / "raw"
    (raw / "d").mkdir(parents=True)
    shutil.copy(MARIN, raw / "d" / "zz_a.dat")
    toml = "[data]\nscale = 45.7\n"
    (raw / "d" / "dataset.toml").write_text(toml + "[runs.zz_20_s]\nskip = true\n")
    assert _ingest("--dataset", "d", "--raw", raw, "--root", tmp_path / "p") == 2
    err = capsys.readouterr().err.strip()
    assert "[runs.zz_20_s] names no run of the dataset (run ids: zz_a)" in err and "\n" not in err
    (raw / "d" / "dataset.toml").write_text(toml + "[roles]\nidentify = 'zz_20_s'\n")
    assert _ingest("--dataset", "d", "--raw", raw, "--root", tmp_path / "p") == 2
    err = capsys.readouterr().err.strip()
    assert "[roles] identify names run 'zz_20_s', which the dataset has not (run ids: zz_a)" in err
    assert not (tmp_path / "p" / "d" / "runs").exists()
    # a skipped run is no run of the dataset for a role
    (raw / "d" / "dataset.toml").write_text(toml + "[roles]\ntrain = ['zz_a']\n[runs.zz_a]\nskip = true\n")
    assert _ingest("--dataset", "d", "--raw", raw, "--root", tmp_path / "p") == 2
    capsys.readouterr()
    # files given (as make pipeline gives them): the roles may name the folder's other runs, not others
    shutil.copy(MARIN, raw / "d" / "zz_b.dat")
    (raw / "d" / "dataset.toml").write_text(toml + "[roles]\nidentify = 'zz_b'\n[runs.zz_c]\nskip = true\n")
    out = tmp_path / "q"
    assert _ingest(raw / "d" / "zz_a.dat", "--dataset", "d", "--raw", raw, "--out", out) == 2
    assert "[runs.zz_c] names no run of the dataset (run ids: zz_a, zz_b)" in capsys.readouterr().err
    (raw / "d" / "dataset.toml").write_text(toml + "[roles]\nidentify = 'zz_b'\n")
    assert _ingest(raw / "d" / "zz_a.dat", "--dataset", "d", "--raw", raw, "--out", out) == 0
    (raw / "d" / "dataset.toml").write_text(toml + "[roles]\nidentify = 'zz_20_s'\n")
    assert _ingest(raw / "d" / "zz_a.dat", "--dataset", "d", "--raw", raw, "--out", out) == 2
    assert "[roles] identify names run 'zz_20_s', which the dataset has not (run ids: zz_a, zz_b)" in \
        capsys.readouterr().err
    # a [runs.<id>] skip of a run in the folder is no error
    (raw / "d" / "dataset.toml").write_text(toml + "[runs.zz_b]\nskip = true\n")
    assert _ingest("--dataset", "d", "--raw", raw, "--root", tmp_path / "p") == 0, capsys.readouterr().err


def test_per_run_rudder_sign_applies_to_that_run_only(tmp_path, capsys):
    raw = tmp_path / "raw"
    (raw / "d").mkdir(parents=True)
    shutil.copy(PROBES / "rudder_sign_flipped.csv", raw / "d" / "flipped.csv")
    shutil.copy(PROBES / "rudder_sign_flipped.csv", raw / "d" / "again.csv")
    (raw / "d" / "dataset.toml").write_text("[data]\nscale = 1\n\n[runs.flipped]\nrudder_sign = -1\n")
    assert _ingest("--dataset", "d", "--raw", raw, "--root", tmp_path / "p") == 2
    err = capsys.readouterr().err
    assert "again.csv" in err and "[runs.<id>]" in err
    (raw / "d" / "again.csv").unlink()
    assert _ingest("--dataset", "d", "--raw", raw, "--root", tmp_path / "p") == 0
    index = json.loads((tmp_path / "p" / "d" / "runs" / "index.json").read_text())
    assert index["runs"][0]["rudder_sign"] == -1
    # the same through the FILE form with --dataset
    out = tmp_path / "q"
    assert _ingest(raw / "d" / "flipped.csv", "--dataset", "d", "--raw", raw, "--out", out) == 0
    assert json.loads((out / "index.json").read_text())["runs"][0]["rudder_sign"] == -1


# ------------------------------------------------------------------ the documentation's examples run
_RUNNABLE = "# example for "


def _runnable_examples() -> list[tuple[str, int, str, str]]:
    """(file, block number, folder, text) of every ```toml block in README.md and docs/*.md whose first
    line is ``# example for <folder>`` (a folder of raw files, from the project root)."""
    import re

    found = []
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        if not doc.is_file():
            continue
        blocks = re.findall(r"^```toml\n(.*?)^```", doc.read_text(encoding="utf-8"), flags=re.S | re.M)
        for k, text in enumerate(blocks):
            first = text.splitlines()[0] if text.strip() else ""
            if first.startswith(_RUNNABLE):
                found.append((doc.name, k, first[len(_RUNNABLE):].strip(), text))
    return found


def test_there_is_a_runnable_example():
    assert any(f == "dataset.md" for f, *_ in _runnable_examples())


@pytest.mark.parametrize("doc,k,folder,text", _runnable_examples(),
                         ids=[f"{d}-{k}" for d, k, *_ in _runnable_examples()])
def test_runnable_examples(doc, k, folder, text, tmp_path, capsys):
    """The block, saved as data/raw/<name>/dataset.toml of a project beside the folder's own parent
    (so that its files_dir, written for data/raw/<name>/ of this project, finds the same files),
    ingests the folder and its roles resolve as identify and diagnose resolve them."""
    from pipeline.diagnose.design import roles_design
    from pipeline.runinfo import choose_runs

    source = (ROOT / folder).resolve()
    if not source.is_dir():
        pytest.skip(f"{folder} (the example's files) is absent: {source}")
    # rebuild the example's layout: a project deep enough for the folder's '..', and the folder (a
    # link to the real one) where it is from that project
    import os

    rel = Path(folder)
    project = tmp_path.joinpath(*[f"up{i}" for i in range(rel.parts.count(".."))], "project")
    target = Path(os.path.normpath(project / rel))
    target.parent.mkdir(parents=True, exist_ok=True)
    target.symlink_to(source, target_is_directory=True)
    (project / "data" / "raw" / "ex").mkdir(parents=True)
    (project / "data" / "raw" / "ex" / "dataset.toml").write_text(text)
    ds = load_dataset("ex", project / "data" / "raw")
    assert ds.raw_files(), f"the example's files_dir finds no files ({ds.files_dir})"
    raw = project / "data" / "raw"
    rc = main(["ingest", "--dataset", "ex", "--raw", str(raw), "--root", str(tmp_path / "p")])
    assert rc == 0, capsys.readouterr().err
    index = json.loads((tmp_path / "p" / "ex" / "runs" / "index.json").read_text())
    ident, _ = choose_runs(index["runs"], index["roles"]["identify"])
    if ds.roles.identify:
        assert ident == ds.roles.identify
    design = roles_design(index)
    if ds.roles.train:
        assert design is not None and design[0] == list(ds.roles.train)


def test_the_build_reads_the_hsva_description_and_goes_stale_when_it_changes(hsva_dir, tmp_path, capsys):
    """`run` (make pipeline) ingests the HSVA files with data/raw/hsva/dataset.toml of its raw root, as
    `ingest --dataset hsva` does, and an edit of that file makes ingest stale and changes its output."""
    from pipeline.build import STAGES, discover, up_to_date

    raw, root = tmp_path / "raw", tmp_path / "proc"
    (raw / "hsva").mkdir(parents=True)
    toml = raw / "hsva" / "dataset.toml"
    toml.write_text(BUILTIN["hsva"])
    argv = ["run", "--dataset", "hsva", "--raw", str(raw), "--root", str(root), "--shared",
            str(hsva_dir.parents[1]), "--until", "ingest"]
    assert main(argv) == 0, capsys.readouterr().err
    index = json.loads((root / "hsva" / "runs" / "index.json").read_text())
    assert index["ship"]["dataset_toml"] == str(toml) and Path(index["ship"]["dataset_toml"]).is_file()
    assert index["identify"] == {"half_periods": 3.4} and index["ship"]["tank"] == "HSVA"
    ds = next(d for d in discover(raw, hsva_dir.parents[1]) if d.name == "hsva")
    assert up_to_date(STAGES[0], ds, root)
    toml.write_text(BUILTIN["hsva"].replace('tank = "HSVA"', 'tank = "HSVA Hamburg"')
                    .replace("half_periods = 3.4", "half_periods = 3.0"))
    assert not up_to_date(STAGES[0], ds, root)
    capsys.readouterr()
    assert main(argv) == 0
    assert "ran ingest" in capsys.readouterr().out
    index = json.loads((root / "hsva" / "runs" / "index.json").read_text())
    assert index["identify"] == {"half_periods": 3.0} and index["ship"]["tank"] == "HSVA Hamburg"


def test_the_dataset_list_is_the_builds(tmp_path, capsys):
    """``python -m pipeline datasets`` lists what the build builds (pipeline.build.discover): hsva
    only when the shared folder holds its files, a folder named 'local' never (the name of the files
    straight in the raw root), hidden folders never."""
    from pipeline.build import discover

    raw, shared = tmp_path / "raw", tmp_path / "shared"
    for name in ("mine", "_scratch", ".hidden", "local"):
        (raw / name).mkdir(parents=True)
    (raw / "zz20.csv").write_text("time,psi,r,delta\n0,0,0,0\n")
    assert dataset_names(raw, shared) == ["virtual", "_scratch", "mine", "local"]
    (shared / "data" / "kvlcc2_hsva").mkdir(parents=True)
    (shared / "data" / "kvlcc2_hsva" / "z1.dat").write_text("x\n")
    names = dataset_names(raw, shared)
    assert names == ["virtual", "hsva", "_scratch", "mine", "local"]
    assert names == [d.name for d in discover(raw, shared)]
    assert main(["datasets", "--raw", str(raw), "--shared", str(shared)]) == 0
    assert capsys.readouterr().out.splitlines() == names
