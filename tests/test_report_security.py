"""Reports: data-derived strings never become markup; the same inputs give the same bytes.

Run ids come from file names and test/ship names from CSV headers, so a
dataset is made whose run ids, ship and test names carry HTML payloads; every report is rendered
from it twice.  The pages are parsed (stdlib HTMLParser): no element or attribute of a payload
may exist, and the two renders must be byte-identical (no wall clock on a page: the render times are
in reports/timing.json).
"""

from __future__ import annotations

import os
import re
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest

from pipeline.cli import main

sys.path.insert(0, str(Path(__file__).parent))
from report_catalog import make_catalog  # noqa: E402

# '$...$' is matplotlib's mathtext markup: in a run file name or a test name it is only text too
EVIL_IDS = ("evil<svg onload=alert(1)>$x$zz20", "x<img src=x onerror=alert(2)>zz10")
EVIL_SHIP = "KCS<script>alert(3)</script>"
EVIL_TESTS = ("zigzag 20/20 <b onmouseover=alert(4)>starboard</b> $\\macro$",
              "zigzag 10/10 evil<svg/onload=alert(5)> starboard")
NOTEBOOKS = ("identification", "indices", "control", "diagnosis")
TIME_LINE = re.compile(r'<div class="provenance-time">[^<]*</div>')


class _Tags(HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict]] = []
        self.scripts: list[str] = []
        self._in_script = False

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))
        self._in_script = tag == "script"

    def handle_endtag(self, tag):
        self._in_script = False

    def handle_data(self, data):
        if self._in_script:
            self.scripts.append(data)


def _render_evil(tmp: Path, k: int) -> Path:
    """Every report of the hostile catalog under ``tmp/proc``, rendered into ``tmp/reports<k>``."""
    out = tmp / f"reports{k}"
    assert main(["report", "--datasets", "evil", "--root", str(tmp / "proc"), "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> list[Path]:
    """The hostile catalog's reports rendered once (a second render is made by the test that needs
    it: make test-long)."""
    tmp = tmp_path_factory.mktemp("evil")
    make_catalog(tmp / "proc", "evil", "virtual", ids=EVIL_IDS, ship=EVIL_SHIP, test_names=EVIL_TESTS,
                 rich_diagnosis=True)   # every section of the diagnosis report, hostile run ids in it
    return [_render_evil(tmp, 0)]


@pytest.mark.slow
def test_no_payload_is_live_markup(rendered):
    for name in [f"{n}-evil.html" for n in NOTEBOOKS] + ["index.html"]:
        page = (rendered[0] / name).read_text(encoding="utf-8")
        p = _Tags()
        p.feed(page)
        tags = {t for t, _ in p.tags}
        assert "svg" not in tags, name
        for tag, attrs in p.tags:
            handlers = {a for a in attrs if a.lower().startswith("on")}
            # the report's own "show code" button is the only element with a handler
            assert handlers <= {"onclick"}, (name, tag, attrs)
            if "onclick" in handlers:
                assert attrs["onclick"] == "toggleCode(this)", (name, tag, attrs)
            if tag == "img":
                assert (attrs.get("src") or "").startswith("data:image/png;base64,"), (name, attrs)
        for body in p.scripts:
            assert "alert(" not in body, name
        if name != "index.html":
            # the payloads are there, as text (escaped), so a reader still sees the real names
            assert "&lt;script&gt;alert(3)&lt;/script&gt;" in page, name
            assert "$x$zz20" in page and "$\\macro$" in page, name     # mathtext shown as typed


@pytest.mark.long     # CI cut: tests/test_faults.py's make_pipeline_log (a rebuild's bytes, to ingest)
def test_same_inputs_same_bytes(rendered):
    import json

    a = rendered[0]
    b = _render_evil(a.parent, 1)
    for name in [f"{n}-evil.html" for n in NOTEBOOKS] + ["index.html", "reports.json"]:
        pa = (a / name).read_text(encoding="utf-8")
        assert not TIME_LINE.findall(pa), name             # no wall-clock line
        assert pa == (b / name).read_text(encoding="utf-8"), name
    # the clock and the render times are kept beside the pages, one entry per page
    timing = json.loads((a / "timing.json").read_text())["reports"]
    assert sorted(timing) == sorted(f"{n}-evil.html" for n in NOTEBOOKS)
    assert all(t["seconds"] > 0 and len(t["rendered"]) == 19 for t in timing.values())


def test_figure_text_is_never_mathtext():
    """After nb.setup() a title, label or legend entry holding '$\\macro$' or '$x$' is drawn as typed;
    with matplotlib's default (mathtext on) the same figure cannot be drawn."""
    import io

    import matplotlib as mpl
    import matplotlib.pyplot as plt

    from pipeline.report import nb

    def draw() -> bytes:
        fig, ax = plt.subplots()
        ax.plot([0, 1], [0, 1], label="run $x$ of test $\\macro$")
        ax.set_title("zz20 ($\\macro$)")
        ax.set_xlabel("$x$ (s)")
        ax.legend()
        buf = io.BytesIO()
        try:
            fig.savefig(buf, format="png")
        finally:
            plt.close(fig)
        return buf.getvalue()

    with mpl.rc_context():
        mpl.rcParams["text.parse_math"] = True               # matplotlib's default (another test may have
        #                                                      run nb.setup() in this process already)
        with pytest.raises(ValueError, match="macro"):      # the fault: mathtext parses the name
            draw()
        nb.setup()
        assert draw().startswith(b"\x89PNG")


def test_index_links_survive_any_dataset_name(tmp_path):
    """Dataset names with '#', '?', '%', spaces, quotes and '&': every link of index.html, read by a
    browser (URL-decoded relative to the page), opens that dataset's file; the name is shown as typed."""
    from urllib.parse import unquote, urlsplit

    from pipeline.report.render import Report, write_index

    names = ("run #3", "what?", "50% load", "a&b 'c'", "plain")
    reports = []
    for ds in names:
        page = tmp_path / f"indices-{ds}.html"
        page.write_text("<html></html>")
        reports.append(Report("indices", ds, page, 1.0, "measured", 2))
    write_index(tmp_path, reports)
    p = _Tags()
    p.feed((tmp_path / "index.html").read_text(encoding="utf-8"))
    hrefs = [a["href"] for t, a in p.tags if t == "a"]
    assert len(hrefs) == len(names)
    for href in hrefs:
        parts = urlsplit(href)
        assert not parts.scheme and not parts.netloc and not parts.query and not parts.fragment, href
        assert (tmp_path / unquote(parts.path)).is_file(), href
    assert sorted(unquote(urlsplit(h).path) for h in hrefs) == sorted(f"indices-{d}.html" for d in names)
    text = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert "<code>a&amp;b &#x27;c&#x27;</code>" in text and "<code>50% load</code>" in text


def _dead_pid() -> int:
    """The id of a process that has exited (a finished child, reaped)."""
    import subprocess

    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_stale_scratch_is_removed_by_a_safe_rule(tmp_path):
    """Only folders named tanktest-report-<pid>-<random> whose process is gone are removed; a live
    render's folder, other names, a symbolic link and what it points to stay."""
    from pipeline.report.render import remove_stale_scratch

    dead = _dead_pid()
    stale = tmp_path / f"tanktest-report-{dead}-abc123"
    stale.mkdir()
    (stale / "kernel.json").write_text('{"key": "secret"}')
    live = tmp_path / f"tanktest-report-{os.getpid()}-live1"        # this process: alive
    live.mkdir()
    other = [tmp_path / "tanktest-report-abc", tmp_path / f"other-{dead}-x",
             tmp_path / f"tanktest-report-{dead}"]
    for d in other:
        d.mkdir()
    target = tmp_path / "keep"
    target.mkdir()
    (target / "f").write_text("x")
    link = tmp_path / f"tanktest-report-{dead}-link1"
    link.symlink_to(target)
    stale_file = tmp_path / f"tanktest-report-{dead}-file1"        # a file, not a folder this module made
    stale_file.write_text("x")
    assert remove_stale_scratch(tmp_path) == [stale]
    assert not stale.exists()
    assert live.is_dir() and all(d.is_dir() for d in other) and stale_file.is_file()
    assert link.is_symlink() and (target / "f").is_file()
    assert remove_stale_scratch(tmp_path / "absent") == []


def _processes_using(path: Path) -> list[int]:
    """Ids of the processes whose command line names ``path`` (Linux /proc)."""
    pids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if str(path).encode() in (d / "cmdline").read_bytes():
                    pids.append(int(d.name))
            except OSError:
                continue
    return pids


@pytest.mark.long     # CI cut: test_stale_scratch_is_removed_by_a_safe_rule (the rule, no kill)
def test_a_killed_render_leaves_nothing_after_the_next(tmp_path):
    """A render killed (SIGKILL) while its kernel runs leaves its scratch folder with the kernel's
    connection file (signing key) in the temporary folder; the next render removes it and leaves
    nothing of its own; no connection file is ever written in the Jupyter runtime folder."""
    import json
    import signal
    import subprocess
    import time

    root, out, tmp, runtime = tmp_path / "proc", tmp_path / "out", tmp_path / "tmp", tmp_path / "runtime"
    tmp.mkdir()
    make_catalog(root, "tiny", "virtual")
    env = {**os.environ, "TMPDIR": str(tmp), "JUPYTER_RUNTIME_DIR": str(runtime)}
    cmd = [sys.executable, "-m", "pipeline", "report", "--datasets", "tiny", "--root", str(root),
           "--out", str(out), "--notebooks", "indices"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120          # a bound on the wait, not a measured time
        while not list(tmp.glob("tanktest-report-*/kernel.json")) and time.monotonic() < deadline:
            assert proc.poll() is None, "the render ended before its kernel started"
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    (left,) = tmp.glob("tanktest-report-*")
    assert left.name.startswith(f"tanktest-report-{proc.pid}-")
    assert "key" in json.loads((left / "kernel.json").read_text())       # what a killed render leaves
    # its kernel does not outlive it (ipykernel watches its parent): no process runs on that file
    deadline = time.monotonic() + 30           # a bound on the wait, not a measured time
    while _processes_using(left / "kernel.json") and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _processes_using(left / "kernel.json")
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert (out / "indices-tiny.html").is_file()
    assert list(tmp.glob("tanktest-report-*")) == []
    assert not list(runtime.glob("kernel-*.json"))
