"""report/answer.py: the report's answer lines say what a study can and cannot answer."""
from __future__ import annotations

from types import SimpleNamespace

import pandas as pd

from roughsense.report.answer import answer_lines


def test_a_report_without_loso_says_what_it_cannot_answer():
    analysis = SimpleNamespace(unseen=pd.DataFrame())
    (line,) = answer_lines(analysis)
    assert "predicts a surface left out of training." in line and "never" not in line


def _held(scheme, held_out, bias, flagged):
    return pd.DataFrame({"model": "peak-law", "pad": "smooth", "condition": "combined", "scheme": scheme,
                         "held_out": held_out, "rmse": 0.3, "null_rmse": 0.4, "passes": True, "n_permutations": 199,
                         "bias": bias, "flagged_share": flagged}, index=[0])


def _answer(held, geometry_note=""):
    from roughsense.report.answer import answer_table

    unseen = pd.DataFrame({"model": ["peak-law"], "pad": ["smooth"], "condition": ["combined"], "passes": [True]})
    return answer_table(SimpleNamespace(
        fit_default="peak-law", held_out=held, unseen=unseen, presses=pd.DataFrame(), presses_needed={},
                                        headline_condition="combined", geometry_note=geometry_note))


def test_a_land_groove_geometry_left_out_is_on_the_first_screen_with_its_bias_and_flags():
    held = pd.concat([_held("specimen", "all", 0.0, 0.0), _held("geometry", "land 0.7", 0.72, 0.025)])
    rows = _answer(held)["rows"]
    assert rows[1] == ["peak law", "a land/groove geometry left out: land 0.7",
                       "0.30 vs 0.40, passes, bias +0.72, 2% of presses flagged: biased, mostly unflagged"]


def test_where_the_study_cannot_hold_out_a_geometry_the_first_screen_says_so():
    note = "every rectangle here is land 0.5 of its period (roughsense protocol recommends others)"
    rows = _answer(_held("specimen", "all", 0.0, 0.0), geometry_note=note)["rows"]
    assert rows[-1] == ["every model", "a land/groove geometry left out",
                        f"not applicable: {note}"]
    assert len(_answer(_held("specimen", "all", 0.0, 0.0))["rows"]) == 1  # nothing said where nothing is missing
