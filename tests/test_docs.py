"""The repository documents itself: code, tests, notebooks and docs cite ``docs/``, and every cited
``docs/`` file and anchor exists.

A user's clone holds ``docs/`` but not the project's tracker nor its notes outside the repository, so
no file may cite "SPEC section N", the algorithms note (``ALGORITHMS.md``) or an issue number (the
history of where a feature came from is the git log and CHANGELOG.md, the one file allowed to name
them).  Names that are code, not citations, stay legal: ``SPEC.toml`` (a study spec's file name),
the Makefile's ``$(SPEC)`` variable, identifiers such as ``SPEC_KEYS`` or the ``ALGORITHMS`` tuple.
Anchors are GitHub's: the heading lower-cased, punctuation other than ``-`` and ``_`` dropped,
spaces as hyphens, a repeated heading suffixed ``-1``, ``-2``.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"

#: a citation of something outside the repository (the same patterns in words, code or Markdown)
CITES = re.compile(
    r"SPEC\s+sections?\b|\bSPEC [0-9]|\bSPEC\.md\b|\bSPEC(?:'s|:|-signed)|\b(?:the|per|in|of) SPEC\b"
    r"|(?<!\$)\(SPEC\b(?!\))|\bSPEC (?:signs?|units|order|keys|rudder|negative)\b"
    r"|ALGORITHMS\.md|\(ALGORITHMS\b(?!\))|\bALGORITHMS(?:: \w| Eq\b|;)"
    r"|\b[Ii]ssues? #?[0-9]+")

#: files whose citations are mapped later (none: every file cites docs/)
MAPPED_AFTER_MERGE: tuple[str, ...] = ()

#: text files of the repository (what a clone holds, not what a run writes)
TEXT_SUFFIXES = {".py", ".md", ".toml", ".txt", ".cfg", ".ini", ".yml", ".yaml", ".sh"}
TEXT_NAMES = {"Makefile", "run"}
SKIP_DIRS = {".git", ".venv", "__pycache__", ".pytest_cache", ".ruff_cache", ".hypothesis", "build",
             "dist", "processed", "studies_out", ".ipynb_checkpoints", "reports"}
#: the only file that may name issues: the dated record of changes; and this file, whose examples cite
HISTORY = {"CHANGELOG.md", "tests/test_docs.py"}


def repository_files() -> list[str]:
    """Paths (relative, '/'-separated) of the repository's text files; symlinked folders not followed
    (``pipeline/notebooks`` is ``notebooks/``), data folders only for their ``dataset.toml``."""
    out = []
    for folder, dirs, files in os.walk(ROOT):
        rel = Path(folder).relative_to(ROOT)
        in_data_not_raw = rel.parts[:1] == ("data",) and len(rel.parts) >= 2 and rel.parts[1] != "raw"
        dirs[:] = sorted(d for d in dirs
                         if d not in SKIP_DIRS and not d.endswith(".egg-info") and not in_data_not_raw)
        for name in sorted(files):
            p = Path(folder) / name
            if rel.parts[:1] == ("data",) and name != "dataset.toml":
                continue
            if (p.suffix in TEXT_SUFFIXES or name in TEXT_NAMES) and not p.is_symlink():
                out.append(p.relative_to(ROOT).as_posix())
    return out


def citing_lines(paths: list[str]) -> list[str]:
    """'path:line: text' of every line that cites outside the repository, also where the citation
    breaks across two lines ("SPEC" at one line's end, "section 9" at the next one's start)."""
    hits = []
    for rel in paths:
        lines = (ROOT / rel).read_text(encoding="utf-8", errors="replace").split("\n")
        for i, line in enumerate(lines):
            nxt = re.sub(r"^\s*(?:#:?\s*)?", "", lines[i + 1]) if i + 1 < len(lines) else ""
            if CITES.search(line) or (CITES.search(line.rstrip() + " " + nxt) and not CITES.search(nxt)):
                hits.append(f"{rel}:{i + 1}: {line.strip()[:100]}")
    return hits


def _split(paths: list[str]) -> tuple[list[str], list[str]]:
    later = [p for p in paths if p.startswith(MAPPED_AFTER_MERGE)]
    return [p for p in paths if p not in later and p not in HISTORY], later


def test_the_pattern_finds_citations_and_leaves_code_names():
    """Known answers for the pattern itself, so the scans below can fail."""
    for cited in ("(SPEC section 2)", "SPEC sections 2, 4, 8", "the SPEC's signs", "SPEC\n section 9",
                  "see ALGORITHMS.md", "(issue 14 item 5)", "issue #11's bar", "Issue 13 blocker",
                  "(ALGORITHMS; HSVA runs 30 %)", "SPEC signs in every form", "SPEC: r = d(psi)/dt"):
        assert CITES.search(re.sub(r"\s*\n\s*", " ", cited)), cited
    for code in ("python -m pipeline study SPEC.toml", "$(PY) -m pipeline study $(SPEC) --out",
                 "SPEC ?= x", "SPEC_KEYS = {}", "ALGORITHMS = ('srukf-ffm',)", "join(ALGORITHMS)",
                 "for a in ALGORITHMS:", "make study SPEC=studies/autopilot.toml", "an issue with the file",
                 "docs/contract.md#run-data"):
        assert not CITES.search(code), code


def test_repository_files_are_found():
    files = repository_files()
    for expected in ("pipeline/config.py", "tests/test_docs.py", "docs/contract.md", "Makefile",
                     "data/raw/hsva/dataset.toml"):
        assert expected in files
    assert not any(f.startswith(("pipeline/notebooks/", ".venv/", "data/processed/")) for f in files)


def test_no_file_cites_outside_the_repository():
    """Every file (CHANGELOG.md apart, and the files other branches rewrite now: next test) cites docs/."""
    mine, _ = _split(repository_files())
    hits = citing_lines(mine)
    assert not hits, "cite docs/ instead:\n" + "\n".join(hits)


def github_anchors(markdown: str) -> set[str]:
    """The anchors GitHub gives the headings of a Markdown text (fenced code blocks skipped)."""
    seen: dict[str, int] = {}
    out = set()
    fenced = False
    for line in markdown.splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        m = re.match(r"^(#{1,6})\s+(.*?)\s*#*\s*$", line)
        if fenced or not m:
            continue
        slug = re.sub(r"[^\w\- ]", "", m.group(2).strip().lower().replace("`", "")).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


def test_anchor_rule_known_answers():
    text = ("# Title\n## Run data\n### identify/ALGORITHM/ (identify)\n## 6. `control/metrics.json`\n"
            "## Run data\n")
    assert github_anchors(text) == {"title", "run-data", "identifyalgorithm-identify", "6-controlmetricsjson",
                                    "run-data-1"}
    assert github_anchors("```\n# not a heading\n```\n## Yes\n") == {"yes"}


#: 'docs/x.md#anchor' in code and text; '](x.md#anchor)' relative links inside docs/
DOCS_REF = re.compile(r"(?<![\w/.])docs/([A-Za-z0-9_.-]+\.md)(?:#([A-Za-z0-9_-]+))?")
MD_LINK = re.compile(r"\]\(([A-Za-z0-9_.-]+\.md)(?:#([A-Za-z0-9_-]+))?\)")


def cited_docs() -> list[tuple[str, str, str | None]]:
    """(citing file, docs file, anchor or None) for every docs/ citation in the repository."""
    refs = []
    for rel in repository_files():
        if rel in HISTORY:
            continue
        text = (ROOT / rel).read_text(encoding="utf-8", errors="replace")
        refs += [(rel, f, a) for f, a in DOCS_REF.findall(text)]
        if rel.startswith("docs/"):
            refs += [(rel, f, a) for f, a in MD_LINK.findall(text)]
    return [(rel, f, a or None) for rel, f, a in refs]


def test_every_cited_docs_file_and_anchor_exists():
    refs = cited_docs()
    assert len(refs) > 50       # the code cites docs/ throughout; a broken pattern would find none
    anchors = {p.name: github_anchors(p.read_text(encoding="utf-8")) for p in DOCS.glob("*.md")}
    missing = sorted({f"{rel}: docs/{f}" + (f"#{a}" if a else "") for rel, f, a in refs
                      if f not in anchors or (a is not None and a not in anchors[f])})
    assert not missing, "cited but not in docs/:\n" + "\n".join(missing)


def test_runtime_messages_cite_existing_docs():
    """The words written into outputs and printed to users name docs/ anchors that exist."""
    from pipeline.cli import build_parser
    from pipeline.config import FilterConfig
    from pipeline.identify.core import trust_flags
    from pipeline.indices.trust import sign_flags

    anchors = github_anchors((DOCS / "contract.md").read_text(encoding="utf-8"))
    assert "run-data" in anchors
    (flag,) = sign_flags({"K": -0.05})
    assert "docs/contract.md#run-data" in flag["reason"] and not CITES.search(flag["reason"])
    consistent = {"nis_mean": 3.0, "nis_95_band": (2.7, 3.3), "nis_expected": 3.0, "nis_n_eff": 100.0,
                  "level": 0.95, "whiteness": {}}
    flags = trust_flags(consistent, {"K": -0.05}, None, np.array([-20.0, 20.0]), FilterConfig())
    assert [f["check"] for f in flags] == ["nomoto_K"]
    reasons = [f["reason"] for f in flags]
    assert reasons and "docs/contract.md#run-data" in reasons[0] and not CITES.search(reasons[0])
    description = build_parser().description
    assert "docs/index.md" in description and not CITES.search(description)
