"""How many examples a property test draws: its stated number under `make test` (the `ci` Hypothesis
profile, derandomised, see conftest.py), ten times that under `make fuzz` (fresh random draws)."""

from __future__ import annotations

import os

FUZZ = os.environ.get("TANKTEST_HYPOTHESIS") == "fuzz"


def examples(n: int) -> int:
    """Number of Hypothesis examples for a test that draws ``n`` in CI."""
    return n * 10 if FUZZ else n
