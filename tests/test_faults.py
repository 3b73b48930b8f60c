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


# ---------------------------------------------------------------- no orphaned workers


@pytest.fixture(scope="module")
def four_truth_runs(tmp_path_factory) -> list[str]:
    """Four short zigzags of the diagnosis's known truth (a 1.5 deg rudder offset), as Parquet runs:
    two to train, two to validate (the case of tests/nested_bytes.py)."""
    import dataclasses as dc

    from pipeline.diagnose import TruthConfig, zigzag_truth
    from pipeline.io import write_run

    d = tmp_path_factory.mktemp("truth")
    cfg = TruthConfig(seed=3, rudder_offset=1.5)
    legs = [(20, "starboard"), (10, "port"), (20, "port"), (10, "starboard")]
    out = []
    for j, (a, side) in enumerate(legs):
        p = d / f"zz{j}.parquet"
        write_run(p, zigzag_truth(a, a, side, 40.0, dc.replace(cfg, seed=cfg.seed + j)))
        out.append(str(p))
    return out


def _gone(pids: list[int], within_s: float) -> list[int]:
    """The pids still alive (not zombies) after waiting up to ``within_s`` seconds."""
    import time

    t_end = time.monotonic() + within_s
    while True:
        alive = []
        for pid in pids:
            try:
                if psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                    alive.append(pid)
            except psutil.NoSuchProcess:
                pass
        if not alive or time.monotonic() > t_end:
            return alive
        time.sleep(0.2)


@pytest.mark.parametrize("roles", ["nested", "test runs"])
@pytest.mark.parametrize("sig", ["SIGKILL", "SIGTERM"])
def test_the_diagnosis_pool_dies_with_its_parent(sig, roles, four_truth_runs, tmp_path):
    """A standalone ``python -m pipeline diagnose`` whose nested leave-one-run-out runs in 2 forked
    workers, or (with --test runs) whose fits are made ahead by a forked helper beside the manager of
    the memo the processes share, ended by SIGKILL or SIGTERM while they work: no child outlives it (a
    pool's workers were left blocked on a pipe, reparented to PID 1).  ``run`` calls the same code in
    its own process."""
    import signal
    import subprocess
    import sys
    import time

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "PYTHONPATH": root}
    a, b, c, d = four_truth_runs
    design = ["--train", a, b, "--validate", c, d] if roles == "nested" else \
        ["--train", a, "--validate", c, "--test", b, d]
    proc = subprocess.Popen([sys.executable, "-m", "pipeline", "diagnose", *design,
                             "--out", str(tmp_path / "out")],
                            env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    workers: list[int] = []
    try:
        parent = psutil.Process(proc.pid)
        t_end = time.monotonic() + 300
        while len(workers) < 2 and proc.poll() is None and time.monotonic() < t_end:
            workers = [p.pid for p in parent.children(recursive=True)]
            time.sleep(0.1)
        assert len(workers) >= 2, f"the pool never started (exit {proc.poll()})"
        time.sleep(1.0)                                  # the workers are inside their first task
        proc.send_signal(getattr(signal, sig))
        proc.wait(timeout=30)
        assert proc.returncode != 0
        # the kernel's parent-death signal acts at once; the watchdog's poll is 1 s (pipeline.lifeline)
        assert _gone(workers, within_s=10.0) == []
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for pid in workers:
            try:
                psutil.Process(pid).kill()
            except psutil.NoSuchProcess:
                pass


# ---------------------------------------------------------------- one bad dataset, hostile names

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HOSTILE_NAMES = ("-dash", "$x #% y")


def test_one_bad_dataset_never_stops_the_others(tmp_path, monkeypatch, capsys):
    """``run --all``: a dataset.toml of the wrong shape (``runs = 5``) is one error line naming its
    dataset; the datasets after it, named ``-dash`` (an option to argparse, were it parsed as one) and
    ``$x #% y``, are built all the same; the exit status is 2."""
    import shutil

    from pipeline import build
    from pipeline.cli import main

    raw, root = tmp_path / "raw", tmp_path / "proc"
    clean = os.path.join(ROOT, "tests", "data", "probes", "clean.csv")
    for name in ("a-bad", *HOSTILE_NAMES):
        (raw / name).mkdir(parents=True)
        shutil.copy(clean, raw / name / "zz.csv")
        (raw / name / "dataset.toml").write_text("[data]\nscale = 1\n")
    (raw / "a-bad" / "dataset.toml").write_text("runs = 5\n[data]\nscale = 1\n")
    # the built-in virtual tank is not under test: its folder holds a ready run (no 40 s simulation)
    (raw / "virtual").mkdir()
    shutil.copy(clean, raw / "virtual" / "zz.csv")
    monkeypatch.setattr(build, "tank_up_to_date", lambda _raw: True)
    monkeypatch.chdir(tmp_path)
    rc = main(["run", "--all", "--raw", str(raw), "--root", str(root), "--shared", str(tmp_path / "none"),
               "--until", "ingest"])
    cap = capsys.readouterr()
    assert rc == 2
    errors = [line for line in cap.err.splitlines() if line.startswith("error:")]
    assert len(errors) == 2, cap.err
    # the bad dataset's one line names its description (a refusal) or its folder (an unexpected error)
    assert errors[0].startswith((f"error: {raw / 'a-bad' / 'dataset.toml'}: runs must be a table",
                                 f"error: dataset 'a-bad' ({raw / 'a-bad'}): "))
    assert "Traceback" not in cap.err
    assert errors[-1] == "error: 1 of 4 dataset(s) not fully built: a-bad (see above)"
    for name in ("virtual", *HOSTILE_NAMES):
        assert (root / name / "runs" / "index.json").is_file(), name
        assert f"[{name}] ran ingest" in cap.out
    assert not (root / "a-bad" / "runs").exists()


def test_stage_commands_take_dataset_names_as_values_only(tmp_path):
    """The build runs each stage through the Python API (pipeline.api.run): a dataset called ``-dash``,
    with a run file ``-zz.csv``, reaches the stage as the value it is (no argument list is parsed),
    and the stage's settings are the command's own (every option a name the command knows)."""
    from pipeline import api, build

    ds = build.Dataset("-dash", tmp_path / "-dash")
    (tmp_path / "-dash").mkdir()
    (tmp_path / "-dash" / "-zz.csv").write_text("time,psi,r,delta\n")
    (tmp_path / "-dash" / "dataset.toml").write_text("[data]\nscale = 1\n")
    for stage in build.STAGES:
        for options in stage.calls(ds, tmp_path / "proc"):
            ns = api._namespace(stage.name, ds.name, tmp_path / "proc", options)
            assert ns.dataset == "-dash" and ns.stage == stage.name, (stage.name, options)
            if stage.name == "ingest":
                assert [p.name for p in ns.files] == ["-zz.csv"]


def test_diagnosis_plots_take_dollar_names_as_text(tmp_path):
    """A run called ``$\\macro$ zz`` (mathtext to matplotlib, a ValueError at the plot title), a test
    run called ``$t$ test`` and a provenance with ``$``: both diagnosis plots of each are rendered,
    titles as written."""
    from types import SimpleNamespace

    import numpy as np
    import pandas as pd

    from pipeline.diagnose.output import plot_series

    t = np.arange(0.0, 20.0, 0.08)
    cols = {c: np.sin(0.3 * t + k) for k, c in enumerate(
        ("psi", "psi_baseline", "psi_extended", "r", "r_baseline", "r_extended", "delta"))}
    series = pd.DataFrame({"run_id": "$\\macro$ zz", "time": t, **cols})
    diag = SimpleNamespace(series=series, test_series=series.assign(run_id="$t$ test"),
                           report={"extended": {"effects": ["rudder_offset"]}, "provenance": "tank $5$ %"})
    paths = plot_series(diag, tmp_path)
    assert [p.name for p in paths] == ["freerun___macro__zz.png", "residuals___macro__zz.png",
                                       "freerun__t__test.png", "residuals__t__test.png"]
    assert all(p.stat().st_size > 1000 for p in paths)


# ---------------------------------------------------------------- studies refused before they run

AUTOPILOT = ('[study]\nkind = "autopilot_monte_carlo"\nname = "t"\nseed = 5\n'
             '[autopilot_monte_carlo]\nplants = ["nomoto"]\ntw = [3.0]\nwind_rudder = [2.0]\nseeds = 1\n'
             '[autopilot_monte_carlo.control]\nduration = 60.0\nsteady_start = 30.0\n')


@pytest.mark.parametrize("body,key", [
    ("[study]\nkind = 'detection_power'\n[detection_power]\nduration_s = -5\n", "detection_power.duration_s"),
    ("[study]\nkind = 'detection_power'\n[detection_power.magnitudes]\nrudder_offset = [0.5, inf]\n",
     "detection_power.magnitudes.rudder_offset[1]"),
    ("[study]\nkind = 'detection_power'\n[detection_power.magnitudes]\nrudder_ofset = [0.5]\n",
     "detection_power.magnitudes.rudder_ofset"),
    ("[study]\nkind = 'detection_power'\n[detection_power]\neffects = ['rudder_ofset']\n",
     "detection_power.effects"),
    ("[study]\nkind = 'detection_power'\n[detection_power]\nrudder_deg = nan\n",
     "detection_power.rudder_deg"),
    (AUTOPILOT.replace("tw = [3.0]", "tw = [-3.0]"), "autopilot_monte_carlo.tw"),
    (AUTOPILOT.replace("duration = 60.0", "duration = -5.0"), "autopilot_monte_carlo.control.duration"),
    ("[study]\nkind = 'batch_identify'\n[batch_identify]\ndt = 0.0\n", "batch_identify.dt"),
    ("[study]\nkind = 'autopilot_monte_carlo'\nno_worker_timeout_s = 0.0\n", "study.no_worker_timeout_s"),
])
def test_a_study_spec_no_case_could_run_with_is_refused_before_anything_runs(body, key, tmp_path, capsys):
    """One line naming the file and the key, exit 2, no output folder: a duration of -5 s, a magnitude
    of inf, a misspelt effect (with the known names), NaN, a negative time constant (before: every case
    failed and the study exited 0, or the misspelt effect was dropped)."""
    from pipeline.cli import main

    spec = tmp_path / "bad spec.toml"
    spec.write_text(body)
    assert main(["study", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(spec) in err and f"key '{key}'" in err, err
    if "ofset" in body:
        assert "rudder_offset" in err and "rudder_delay" in err        # the known names
    assert not (tmp_path / "out").exists()


def test_a_study_whose_workers_all_died_says_so_in_bounded_time(tmp_path):
    """The only worker of a cluster (``dask worker`` without a nanny, as on a remote cluster) killed
    with SIGKILL: the study stops with one line naming the cause within the spec's no_worker_timeout_s
    (2 s here) instead of waiting silently."""
    import time
    import tomllib

    from distributed import Client

    from pipeline.errors import PipelineError
    from pipeline.study import run_study
    from pipeline.study.cluster import loopback_cluster
    from pipeline.study.spec import spec_from_dict

    doc = tomllib.loads(AUTOPILOT)
    doc["study"]["no_worker_timeout_s"] = 2.0
    spec = spec_from_dict(doc, "t.toml")
    with loopback_cluster(1, nanny=False) as addr, Client(addr, timeout="60s") as client:
        for p in psutil.Process(os.getpid()).children():
            if " worker " in " ".join(p.cmdline()) + " ":
                p.kill()
        t_end = time.monotonic() + 60
        while client.nthreads() and time.monotonic() < t_end:
            time.sleep(0.2)
        assert not client.nthreads()
        t0 = time.monotonic()
        with pytest.raises(PipelineError, match=r"t\.toml: study t: no dask worker for 2 s") as exc:
            run_study(spec, tmp_path / "out", client=client, progress=False)
        assert time.monotonic() - t0 < 30                      # 2 s and the poll, with a wide margin
        assert "\n" not in str(exc.value) and "0 of 1 cases" in str(exc.value)


# ---------------------------------------------------------------- write errors and memory, in one line


def _no_space(*_a, **_k):
    import errno

    raise OSError(errno.ENOSPC, "No space left on device")   # as write(2) on a full disk: no file name


@pytest.mark.parametrize("what", ["json", "frame", "dir"])
def test_a_full_disk_names_the_file_being_written(what, tmp_path, monkeypatch):
    """ENOSPC while writing (no file name of its own, as from write(2) or pyarrow) names the file the
    user asked for, never the temporary; nothing is left behind and an earlier file stays intact."""
    import errno
    import json

    import pandas as pd
    import pyarrow.parquet as pq

    from pipeline import io

    dest = tmp_path / "out" / ("estimates.json" if what != "frame" else "runs.parquet")
    dest.parent.mkdir()
    dest.write_text("earlier")
    if what == "frame":
        monkeypatch.setattr(pq, "write_table", _no_space)
    else:
        monkeypatch.setattr(json, "dumps", _no_space)
    with pytest.raises(OSError) as exc:
        if what == "json":
            io.write_json(dest, {"a": 1})
        elif what == "frame":
            io.write_frame(dest, pd.DataFrame({"a": [1.0]}))
        else:
            with io.atomic_dir(tmp_path / "stage") as tmp:
                io.write_json(tmp / "metrics.json", {"a": 1})
    expect = tmp_path / "stage" / "metrics.json" if what == "dir" else dest
    assert exc.value.errno == errno.ENOSPC and exc.value.filename == str(expect)
    assert dest.read_text() == "earlier"
    assert sorted(p.name for p in tmp_path.rglob("*")) == sorted(["out", dest.name])


def test_a_full_disk_is_one_line_at_the_command_line(tmp_path, monkeypatch, capsys):
    """``ingest`` onto a full disk: one line naming the run file it was writing, exit 2."""
    import shutil

    import pyarrow.parquet as pq

    from pipeline.cli import main

    shutil.copy(os.path.join(ROOT, "tests", "data", "probes", "clean.csv"), tmp_path / "zz.csv")
    monkeypatch.setattr(pq, "write_table", _no_space)
    out = tmp_path / "runs"
    assert main(["ingest", str(tmp_path / "zz.csv"), "--scale", "1", f"--out={out}"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "No space left on device" in err, err
    assert f"{out / 'zz.parquet'}" in err and ".tmp." not in err and ".out." not in err, err


@pytest.mark.parametrize("limit,match", [("1MiB", "below the 512 MiB"), ("lots", "is not a size")])
def test_a_small_or_bad_memory_limit_is_one_line_before_any_worker(limit, match, tmp_path, capsys):
    """``[study] memory_limit = "1MiB"`` (every worker killed by dask at 95 % of it, 37 lines of
    tracebacks) or a word: one line naming the key, exit 2, no cluster started, no output folder."""
    from pipeline.cli import main

    spec = tmp_path / "s.toml"
    spec.write_text(AUTOPILOT.replace('seed = 5\n', f'seed = 5\nmemory_limit = "{limit}"\n'))
    assert main(["study", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "key 'study.memory_limit'" in err and match in err and str(spec) in err
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- damaged outputs rebuilt


def _stage_writer(root, ran: list[str]):
    """Stand-in stage commands of dataset 'mine': each writes its outputs (and indices a zigzag.json
    beside indices.json, as the real stage does) from a content that depends only on the stage, and
    a timing.json that differs every time."""
    from pipeline import build

    outputs = {s.name: s.outputs for s in build.STAGES}

    def fake(stage, dataset, options):
        ran.append(stage)
        files = list(outputs[stage]) + (["indices/zigzag.json"] if stage == "indices" else [])
        for o in files:
            p = root / "mine" / o
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_text(f'{{"stage": "{stage}", "file": "{o}"}}\n')
        timing = root / "mine" / build.STAGE_DIRS[stage] / "timing.json"
        timing.write_text(f'{{"seconds": {len(ran)}}}\n')
        return 0

    return fake


@pytest.mark.parametrize("damage", ["truncate identify/srukf-ffm/estimates.json",
                                    "delete indices/zigzag.json"])
def test_a_damaged_or_missing_output_is_rebuilt_by_the_next_run(damage, tmp_path):
    """Stamps cover the outputs: a truncated estimates.json reruns identify, a deleted
    indices/zigzag.json (not among the stage's declared outputs) reruns indices; the rebuilt files
    are the same bytes, so nothing downstream reruns; a changed timing.json alone reruns nothing."""
    from pipeline import build

    raw, root = tmp_path / "raw", tmp_path / "proc"
    (raw / "mine").mkdir(parents=True)
    (raw / "mine" / "a.csv").write_text("time,psi,r,delta\n0,0,0,0\n")
    (raw / "mine" / "dataset.toml").write_text("[data]\nscale = 1\n")
    ran: list[str] = []
    ds = build.Dataset("mine", raw / "mine")
    fake = _stage_writer(root, ran)
    build.build_dataset(ds, root, run=fake, say=lambda s: None)
    assert list(dict.fromkeys(ran)) == [s.name for s in build.STAGES]
    ran.clear()
    (root / "mine" / "identify" / "timing.json").write_text('{"seconds": 99}\n')
    assert build.build_dataset(ds, root, run=fake, say=lambda s: None) == [] and ran == []
    verb, rel = damage.split()
    target = root / "mine" / rel
    if verb == "truncate":
        target.write_text(target.read_text()[:7])
    else:
        target.unlink()
    done = build.build_dataset(ds, root, run=fake, say=lambda s: None)
    assert done == [rel.split("/")[0]]
    assert target.read_text().startswith('{"stage"')
    ran.clear()
    assert build.build_dataset(ds, root, run=fake, say=lambda s: None) == [] and ran == []


# ---------------------------------------------------------------- logs people can read; same bytes


def test_a_heartbeat_line_in_a_log_and_none_on_a_terminal(capfd, monkeypatch):
    """In a log (stderr not a terminal) a long block says it still runs every ``every_s`` s; on a
    terminal (where the bars show progress) it says nothing; the timer is gone afterwards."""
    import signal
    import time

    from pipeline import progress

    with progress.heartbeat("[x] diagnose", every_s=0.1):
        t_end = time.monotonic() + 0.45
        while time.monotonic() < t_end:
            sum(range(1000))                 # busy in Python, as a stage is between its C calls
    beats = [line for line in capfd.readouterr().err.splitlines() if line.startswith("[x] diagnose still")]
    assert 3 <= len(beats) <= 5, beats
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    monkeypatch.setattr(progress, "on_terminal", lambda: True)
    with progress.heartbeat("[x] diagnose", every_s=0.1):
        time.sleep(0.3)
    assert "still running" not in capfd.readouterr().err


def test_a_stage_run_alone_beats_in_a_log(capfd, monkeypatch):
    """``python -m pipeline diagnose --dataset NAME > log``: the stage command run alone says it still
    runs every HEARTBEAT_S seconds, as the build says of each stage; ``run`` itself does not (the build
    beats per stage) and the timer is gone afterwards."""
    import signal
    import time

    import pipeline.cli.diagnose as cli_diagnose
    from pipeline import progress
    from pipeline.cli import main

    def busy(args):                          # a stand-in diagnosis: busy in Python for 0.45 s
        t_end = time.monotonic() + 0.45
        while time.monotonic() < t_end:
            sum(range(1000))
        return 0

    monkeypatch.setattr(progress, "HEARTBEAT_S", 0.1)
    monkeypatch.setattr(cli_diagnose, "run", busy)
    assert main(["diagnose", "--dataset=-x $y"]) == 0
    beats = [s for s in capfd.readouterr().err.splitlines() if s.startswith("[-x $y] diagnose still running")]
    assert 3 <= len(beats) <= 5, beats
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


def test_a_bar_refreshes_on_a_terminal_only(capfd, monkeypatch):
    from pipeline import progress

    for _ in progress.bar(range(20), desc="fits"):
        pass
    assert "\r" not in capfd.readouterr().err              # stderr captured: not a terminal
    monkeypatch.setattr(progress, "on_terminal", lambda: True)
    for _ in progress.bar(range(20), desc="fits"):
        pass
    assert "\r" in capfd.readouterr().err


def _tree_bytes(root) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != "timing.json"}


@pytest.mark.slow
def test_make_pipeline_log_is_lines_and_a_table_and_a_rebuild_gives_the_same_bytes(tmp_path):
    """``python -m pipeline run --all`` with stdout and stderr to a file (the virtual tank, to
    ingest): no carriage-return refresh anywhere, a line per stage with its time, a closing table
    naming each stage run; timing.json holds the times; a full rebuild (outputs removed, as by
    ``make clean``) gives the same bytes for every output but timing.json."""
    import json
    import shutil
    import subprocess
    import sys

    raw, root = tmp_path / "raw", tmp_path / "proc"
    raw.mkdir()
    argv = [sys.executable, "-m", "pipeline", "run", "--all", f"--raw={raw}", f"--root={root}",
            f"--shared={tmp_path / 'none'}", "--until", "ingest"]
    env = {**os.environ, "PYTHONPATH": ROOT}
    log = tmp_path / "log.txt"
    with open(log, "wb") as fh:
        done = subprocess.run(argv, env=env, cwd=tmp_path, stdout=fh, stderr=subprocess.STDOUT, timeout=600)
    text = log.read_text()
    assert done.returncode == 0, text[-2000:]
    assert "\r" not in text
    lines = text.splitlines()
    assert "[virtual] tank" in lines and any(s.startswith("[virtual] ingest ran in ") for s in lines), text
    head = next(i for i, s in enumerate(lines) if s.split() == ["dataset", "stage", "status", "seconds"])
    assert lines[head + 1].split()[:3] == ["virtual", "ingest", "ran"]
    assert lines[head + 2].startswith("stages finished in ")
    timing = json.loads((root / "virtual" / "timing.json").read_text())
    assert list(timing["stages"]) == ["ingest"] and timing["stages"]["ingest"]["seconds"] > 0
    first = _tree_bytes(root)
    assert "virtual/runs/index.json" in first and len(first) >= 7
    shutil.rmtree(root)
    done = subprocess.run(argv, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert _tree_bytes(root) == first


def test_a_hidden_bar_starts_no_thread(monkeypatch):
    """In a log the bar is nothing at all: no tqdm monitor thread, which would keep the diagnosis
    from forking its nested workers (a process with two threads does not fork)."""
    import threading

    from pipeline import progress

    monkeypatch.setattr(progress, "on_terminal", lambda: False)
    before = threading.active_count()
    b = progress.bar(desc="diagnose: fits", leave=False)
    b.update(1)
    b.set_description("held-out runs")
    b.close()
    assert list(progress.bar(range(3))) == [0, 1, 2]
    assert threading.active_count() == before


# ---------------------------------------------------------------- the whole build, twice (make test-long)


@pytest.fixture(scope="module")
def two_full_builds(tmp_path_factory):
    """What ``make pipeline`` does, done twice from nothing: ``run`` of a dataset whose dataset.toml has
    the wrong shape (``runs = 5``) beside a good one of four short virtual-tank zigzags, then ``report
    --all --changed --keep-going``.  Returns (raw, [(status of run, status of report, every file's bytes
    of data/processed and reports but timing.json)] for each build)."""
    import shutil

    from pipeline import tank
    from pipeline.cli import main

    tmp = tmp_path_factory.mktemp("twice")
    raw = tmp / "raw"
    (raw / "a-bad").mkdir(parents=True)
    (raw / "good").mkdir()
    shutil.copy(os.path.join(ROOT, "tests", "data", "probes", "clean.csv"), raw / "a-bad" / "zz.csv")
    (raw / "a-bad" / "dataset.toml").write_text("runs = 5\n[data]\nscale = 1\n")
    for a, side in ((20, "starboard"), (20, "port"), (10, "starboard"), (10, "port")):
        run = tank.simulate(tank.zigzag(a, a, side, duration=60.0))
        tank.write_csv(raw / "good" / f"zz{a}_{side[0]}.csv", run)
    (raw / "good" / "dataset.toml").write_text("[data]\nscale = 1\n")
    builds = []
    for _ in range(2):
        root, reports = tmp / "proc", tmp / "reports"
        shutil.rmtree(root, ignore_errors=True)             # what make clean removes
        shutil.rmtree(reports, ignore_errors=True)
        rc_run = main(["run", "--dataset", "a-bad", "good", f"--raw={raw}", f"--root={root}",
                       f"--shared={tmp / 'none'}"])
        rc_rep = main(["report", "--all", "--changed", "--keep-going", f"--root={root}", f"--out={reports}"])
        files = {}
        for base in (root, reports):
            files.update({str(p.relative_to(tmp)): p.read_bytes() for p in sorted(base.rglob("*"))
                          if p.is_file() and p.name != "timing.json"})
        builds.append((rc_run, rc_rep, files))
    return raw, builds


@pytest.mark.long
def test_a_bad_dataset_leaves_the_good_ones_reports(two_full_builds):
    """The bad dataset is one error and exit 2; the good one is built to the end and its four reports
    are rendered and linked from the index."""
    _, builds = two_full_builds
    rc_run, rc_rep, files = builds[0]
    assert rc_run == 2 and rc_rep == 0
    for nb in ("identification", "indices", "control", "diagnosis"):
        assert f"reports/{nb}-good.html" in files, nb
        assert f"href='{nb}-good.html'".encode() in files["reports/index.html"], nb
    assert "proc/good/diagnose/diagnosis.json" in files and "proc/good/control/metrics.json" in files
    assert not [f for f in files if f.startswith(("proc/a-bad/runs", "reports/identification-a-bad"))]


@pytest.mark.long
def test_a_full_rebuild_gives_the_same_bytes(two_full_builds):
    """Everything removed and built again (stages and reports): every file the same bytes but
    timing.json (the stages' and the reports' times), the identification's estimates included."""
    _, (first, second) = two_full_builds
    assert first[2].keys() == second[2].keys()
    assert len(first[2]) >= 20
    assert [f for f in first[2] if first[2][f] != second[2][f]] == []
