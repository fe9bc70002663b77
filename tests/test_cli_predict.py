"""cli/predict.py's lines about a model (issue 44: right after ``fit``, predict advised "refit it with roughsense fit"
when the real cause of a missing interval was too few specimens, 4 < 9)."""
from __future__ import annotations

import pytest

from roughsense.cli.predict import no_interval_line
from roughsense.model.interval import conformal_halfwidth


def test_too_few_specimens_is_named_as_the_cause_and_refitting_is_not_advised():
    line = no_interval_line({"specimens": ["R2", "R3", "C4", "R4"], "interval": {"trial_log_halfwidth": None}})
    assert "fitted on 4 specimens, too few for a 90 % interval (at least 9)" in line
    assert "refit" not in line and "more specimens" in line


def test_nine_is_the_fewest_residuals_a_90_percent_interval_takes():
    """The number the line quotes, against the conformal rank it comes from (independent of the line's code)."""
    assert conformal_halfwidth(range(8)) == float("inf") and conformal_halfwidth(range(9)) < float("inf")


def test_a_design_too_small_to_be_judged_left_out_is_that_cause():
    line = no_interval_line({"specimens": ["R2", "R3"], "unseen": {"failure": "could not be judged"}})
    assert "fitted on 2 specimens, too few" in line and "refit" not in line


@pytest.mark.parametrize("training", [{"specimens": ["R2"] * 12}, {}, None])
def test_only_a_file_written_before_intervals_is_told_to_refit(training):
    assert no_interval_line(training).endswith("written before intervals; refit it with roughsense fit")
