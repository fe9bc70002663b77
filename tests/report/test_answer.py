"""report/answer.py: the report's answer lines say what a study can and cannot answer."""
from __future__ import annotations

from types import SimpleNamespace

import pandas as pd

from roughsense.report.answer import answer_lines


def test_a_report_without_loso_says_what_it_cannot_answer():
    analysis = SimpleNamespace(unseen=pd.DataFrame())
    (line,) = answer_lines(analysis)
    assert "predicts a surface left out of training." in line and "never" not in line
