"""_util/text.py: a cell a spreadsheet would run as a formula is written as text; numbers and plain text stay."""
from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.commands import LEGACY_MODEL, grating_png
from tests.fuzzing import EXAMPLES, FUZZ

FORMULAS = ["=HYPERLINK(\"evil\")", "+cmd", "-2+3", "@SUM(A1)", "\t=1"]


@pytest.mark.parametrize("name", FORMULAS)
def test_an_image_name_a_spreadsheet_would_run_is_written_as_text(run_cli, tmp_path, monkeypatch, name):
    """36.12: image names starting with = + - @ went as they are into predict and features CSVs."""
    import csv

    monkeypatch.chdir(tmp_path)
    image = grating_png(Path(f"{name}.png"))
    code, _, err = run_cli("features", "-o", tmp_path / "features.csv", "--", image)
    assert code == 0, err
    code, _, err = run_cli("predict", "-o", tmp_path / "predict.csv", "--", LEGACY_MODEL, image)
    assert code == 0, err
    for table in ("features.csv", "predict.csv"):
        with open(tmp_path / table, newline="", encoding="utf-8") as handle:
            cell = next(csv.DictReader(handle))["image"]
        assert cell == f"'{image}" and not cell.startswith(("=", "+", "-", "@", "\t", "\r"))


def test_spreadsheet_safety_leaves_numbers_and_plain_text_alone():
    """36.12 (the rule): numbers written as text (predict's 3-digit values) keep their sign; only formulas change."""
    import pandas as pd

    from roughsense._util.text import spreadsheet_safe

    frame = pd.DataFrame({"image": ["a.png", "=1+1", "-x", "\r@y"], "low": ["-0.5", "+3", "-", "nan"],
                          "value": [1.0, -2.0, 3.0, 4.0]})
    safe = spreadsheet_safe(frame)
    assert safe["image"].tolist() == ["a.png", "'=1+1", "'-x", "'\r@y"]
    assert safe["low"].tolist() == frame["low"].tolist() and safe["value"].tolist() == [1.0, -2.0, 3.0, 4.0]
    assert spreadsheet_safe(frame.iloc[:1]) is not None and frame["image"].tolist()[1] == "=1+1"  # no side effect


@pytest.mark.slow
@settings(FUZZ, max_examples=max(60, EXAMPLES))
@given(values=st.lists(st.one_of(st.text(max_size=12), st.sampled_from(["=1+1", "-2", "+x", "@a", "\t=", "-", "'=x"])),
                       min_size=1, max_size=8))
def test_no_text_cell_a_spreadsheet_would_run_survives_spreadsheet_safe(values):
    """36.12: after spreadsheet_safe, a text cell starts with = + - @ TAB or CR only if it is a number (or a lone
    sign); every other cell is unchanged, and a second pass changes nothing more."""
    import pandas as pd

    from roughsense._util.text import spreadsheet_safe

    frame = pd.DataFrame({"image": values})
    once = spreadsheet_safe(frame)["image"].tolist()
    for before, after in zip(values, once):
        risky = len(before) > 1 and before.startswith(("=", "+", "-", "@", "\t", "\r"))
        try:
            float(before)
            number = True
        except ValueError:
            number = False
        assert after == (f"'{before}" if risky and not number else before)
    assert spreadsheet_safe(pd.DataFrame({"image": once}))["image"].tolist() == once
