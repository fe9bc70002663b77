"""report/unseen_tables.py: the jackknife+ column says a coverage and a median width, or that too few specimens give
the interval no finite width (an interval of any width covers everything), never "100%, x/÷ inf"."""
from __future__ import annotations

import math

from roughsense.report.unseen_tables import jackknife_phrase


def test_the_jackknife_phrase_says_coverage_and_width_or_why_there_is_none():
    assert jackknife_phrase(0.9, 1.2345) == "90%, x/÷ 1.23"
    assert jackknife_phrase(1.0, math.inf) == "none (too few specimens)"
    assert jackknife_phrase(math.nan, 1.5) == ""  # no check ran
