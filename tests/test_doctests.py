"""The Examples sections of the public API run as doctests, so what the documentation shows is what
the code does (docs/contract.md for the units and signs they use)."""

from __future__ import annotations

import doctest
import importlib

import pytest

#: modules whose public functions carry checked examples, and the least number of examples each holds
#: (a lost Examples section fails here, not silently)
MODULES = {
    "pipeline.units": 4,
    "pipeline.model": 8,
    "pipeline.io": 7,
    "pipeline.paper": 1,
    "pipeline.ingest.core": 7,
    "pipeline.ingest.formats": 1,
    "pipeline.validate": 2,
    "pipeline.tank.simulate": 1,
}


@pytest.mark.parametrize("name", sorted(MODULES))
def test_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)           # an example that writes a file writes it here
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    tests = [t for t in finder.find(module) if t.examples]
    assert len(tests) >= MODULES[name], [t.name for t in tests]
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    for test in tests:
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.attempted > 0 and result.failed == 0, f"{result.failed} of {result.attempted} failed"
