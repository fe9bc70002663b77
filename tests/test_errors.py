"""errors.py: one error family; a message names the file, row and column, fits one bounded line, and tells a Python
caller the keyword (``force=True``) beside the CLI's option."""
from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from roughsense._util import atomic
from roughsense.errors import (
    LINE_MAX_CHARS,
    QUOTE_MAX_CHARS,
    ConfigError,
    InputError,
    OutputExistsError,
    RoughsenseError,
    one_line,
)
from roughsense.io.writer import StudyWriter
from tests.commands import HUGE


@given(st.text(max_size=5000))
def test_one_line_is_one_bounded_line_whatever_it_is_given(text):
    line = one_line(text)
    assert "\n" not in line and "\r" not in line
    assert len(line) <= LINE_MAX_CHARS + 60


@given(st.text(st.characters(blacklist_categories=("Cc", "Cs", "Zl", "Zp", "Zs", "Cf", "Co", "Cn")), max_size=300))
def test_short_messages_are_left_as_they_are(text):
    message = f"ratings.csv, row 2: not a number: {text[:QUOTE_MAX_CHARS]!r}"
    if message.isprintable() and len(message) <= LINE_MAX_CHARS:
        assert one_line(message) == message


def test_a_huge_value_is_quoted_by_its_start_and_its_length():
    line = one_line(f"ratings.csv, row 2, column 'rating': not a number: '{'9' * HUGE}x'")
    assert line.startswith("ratings.csv, row 2, column 'rating': not a number: '999")
    assert f"...({HUGE + 3} characters)" in line and len(line) < 400  # the whole quoted run: '9...9x'


def test_error_names_file_row_and_column(tmp_path):
    err = InputError("not a number", path=tmp_path / "a.csv", row=3, column="rating")
    assert str(err) == f"{tmp_path / 'a.csv'}, row 3, column 'rating': not a number"
    assert isinstance(err, RoughsenseError)


def test_every_refusal_to_overwrite_names_the_cli_option_and_the_python_keyword(tmp_path):
    """One wording, errors.PASS_FORCE: a Python caller is told ``force=True``, not only the CLI's ``--force``."""
    from roughsense import sim
    from roughsense.errors import PASS_FORCE
    from roughsense.io.study_config import write_px_per_mm

    assert PASS_FORCE == "pass --force (force=True in Python)"
    root = tmp_path / "s"
    root.mkdir()
    (root / "notes.txt").write_text("mine")
    (tmp_path / "f.json").write_text("{}")
    (tmp_path / "study.toml").write_text("[sensor]\npx_per_mm = 17.0\n")
    refusals = [lambda: StudyWriter(root), lambda: atomic.check_can_write(tmp_path / "f.json"),
                lambda: sim.simulate_study(root, sim.SimulationConfig(pads=("smooth",), specimens=("R3",))),
                lambda: write_px_per_mm(tmp_path / "study.toml", 20.0, note="measured")]
    for refuse in refusals:
        with pytest.raises((OutputExistsError, ConfigError)) as info:
            refuse()
        assert f"; {PASS_FORCE} to " in str(info.value)
    assert (root / "notes.txt").read_text() == "mine" and "17.0" in (tmp_path / "study.toml").read_text()
