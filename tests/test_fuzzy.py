"""Fuzzy forgetting factor: range, rule table at the term peaks, clipping, partition of unity."""

from __future__ import annotations

import numpy as np
import pytest
from fuzzing import examples  # the example count: CI-sized, or ten times under make fuzz
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.config import FuzzyConfig
from pipeline.identify.fuzzy import RULE_TABLE_TEXT, TERMS_OUT, forgetting_factor, memberships

PEAKS = (-0.5, -0.25, 0.0, 0.25, 0.5)        # NB NM ZO PM PB on the paper's domain
CENTRES = dict(zip(TERMS_OUT, (0.95, 0.9625, 0.975, 0.9875, 1.0), strict=True))


def test_rule_table_at_term_peaks():
    # at a pair of term peaks only one rule fires, so f is that rule's singleton (paper Table 1)
    for i, de in enumerate(PEAKS):
        for j, e in enumerate(PEAKS):
            assert forgetting_factor(e, de) == pytest.approx(CENTRES[RULE_TABLE_TEXT[i][j]], abs=1e-15)


def test_rule_meaning_on_hand_made_inputs():
    assert forgetting_factor(0.0, 0.0) == 1.0                      # no surprise: keep memory
    assert forgetting_factor(0.5, 0.5) == 0.95                     # large and growing error: forget
    assert forgetting_factor(-0.5, -0.5) == 0.95
    # large error shrinking (e de < 0) keeps more memory than the same error growing
    assert forgetting_factor(0.5, -0.5) > forgetting_factor(0.5, 0.5)
    assert forgetting_factor(-0.4, 0.3) > forgetting_factor(-0.4, -0.3)
    # larger |e| (de = 0) lowers f
    assert forgetting_factor(0.1, 0.0) > forgetting_factor(0.3, 0.0) > 0.95


def test_inputs_outside_domain_are_clipped():
    assert forgetting_factor(7.0, -3.0) == forgetting_factor(0.5, -0.5)
    assert forgetting_factor(-1e9, 1e9) == forgetting_factor(-0.5, 0.5)
    assert forgetting_factor(np.nan, 0.0) == 1.0                   # no innovation: no forgetting


def test_between_peaks_interpolates_neighbouring_rules():
    # halfway between ZO and PM in e, at de = ZO: mean of BB and M
    assert np.isclose(forgetting_factor(0.125, 0.0), 0.5 * (1.0 + 0.975))


def test_other_range_and_domain():
    cfg = FuzzyConfig(e_domain=(-2.0, 2.0), de_domain=(-1.0, 1.0), f_range=(0.9, 1.0))
    assert forgetting_factor(2.0, 1.0, cfg) == 0.9
    assert forgetting_factor(0.0, 0.0, cfg) == 1.0
    assert forgetting_factor(-1.0, 0.0, cfg) == pytest.approx(0.95, abs=1e-15)   # NM x ZO -> M


@settings(max_examples=examples(300), deadline=None)
@given(st.floats(-5, 5), st.floats(-5, 5))
def test_factor_always_in_range(e, de):
    f = forgetting_factor(e, de)
    assert 0.95 <= f <= 1.0


@settings(max_examples=examples(100), deadline=None)
@given(st.floats(-1, 1))
def test_memberships_partition_of_unity(x):
    m = memberships(x, (-0.5, 0.5))
    assert np.all(m >= 0) and np.isclose(m.sum(), 1.0)
    assert np.count_nonzero(m) <= 2
