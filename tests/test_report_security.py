"""Reports: data-derived strings never become markup; the same inputs give the same bytes.

Run ids come from file names and test/ship names from CSV headers (issue 14, items 1 and 12), so a
dataset is made whose run ids, ship and test names carry HTML payloads; every report is rendered
from it twice.  The pages are parsed (stdlib HTMLParser): no element or attribute of a payload
may exist, and the two renders must be byte-identical once the one provenance line (wall-clock
time of rendering) is masked.
"""

from __future__ import annotations

import re
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest

from pipeline.cli import main

sys.path.insert(0, str(Path(__file__).parent))
from report_catalog import make_catalog  # noqa: E402

EVIL_IDS = ("evil<svg onload=alert(1)>zz20", "x<img src=x onerror=alert(2)>zz10")
EVIL_SHIP = "KCS<script>alert(3)</script>"
EVIL_TESTS = ("zigzag 20/20 <b onmouseover=alert(4)>starboard</b>",
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


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("evil")
    root = tmp / "proc"
    make_catalog(root, "evil", "virtual", ids=EVIL_IDS, ship=EVIL_SHIP, test_names=EVIL_TESTS,
                 rich_diagnosis=True)   # every section of the diagnosis report, hostile run ids in it
    outs = []
    for k in range(2):
        out = tmp / f"reports{k}"
        assert main(["report", "--datasets", "evil", "--root", str(root), "--out", str(out)]) == 0
        outs.append(out)
    return outs


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


@pytest.mark.slow
def test_same_inputs_same_bytes(rendered):
    a, b = rendered
    for name in [f"{n}-evil.html" for n in NOTEBOOKS] + ["index.html"]:
        pa = (a / name).read_text(encoding="utf-8")
        pb = (b / name).read_text(encoding="utf-8")
        assert len(TIME_LINE.findall(pa)) == 1, name       # exactly one wall-clock line
        assert TIME_LINE.sub("", pa) == TIME_LINE.sub("", pb), name
