"""The one number parser (issue 22, item 4): every reader of numbers accepts exactly the same spellings.

The truth here is the grammar written out by hand (ASCII digits, optional sign, point and exponent), checked
against the parser, against every CSV reader and against the command-line options.
"""
from __future__ import annotations

import math
import re
import shutil

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense.errors import InputError
from roughsense.io.csv_read import read_table
from roughsense.io.numbers import BOUNDS, NumberError, parse_number
from roughsense.io.ratings_file import read_ratings
from roughsense.io.sensor_settings import parse_roi
from tests.fuzzing import EXAMPLES, FUZZ, NUMBER_CHARS

ACCEPTED = {"2": 2.0, "-0.5": -0.5, "+3": 3.0, ".5": 0.5, "5.": 5.0, "1e-3": 1e-3, "2.5E+2": 250.0, " 7 ": 7.0,
            "\t1.25": 1.25}
REFUSED = ["1_0", "1_000.5", "\u0661", "\u0967\u0968", "\uff11", "0x10", "inf", "-Infinity", "nan", "NaN", "1e999",
           "", " ", "-", ".", "e5", "1e", "1,5", "2 N", "1.2.3", "++1", "\u00b9", "1\u00a0000", "true"]


@pytest.mark.parametrize("text, value", ACCEPTED.items())
def test_the_accepted_spellings(text, value):
    assert parse_number(text) == value


@pytest.mark.parametrize("text", REFUSED)
def test_everything_else_is_refused_though_float_may_take_it(text):
    with pytest.raises(NumberError):
        parse_number(text)


def test_messages_say_what_to_write():
    cases = {"1_0": "not a number: '1_0' (no '_' between digits: write 10)",
             "\u0661": "not a number: '\u0661' (write the digits 0-9)",
             "0,5": "not a number: '0,5' (a decimal comma: write 0.5)",
             "2.01 N": "not a number: '2.01 N' (drop the unit: write 2.01)",
             "0x10": "not a number: '0x10'",  # a hex number is no '0' with a unit 'x10'
             "inf": "not a finite number: 'inf'", "1e999": "not a finite number: '1e999'"}
    for text, message in cases.items():
        with pytest.raises(NumberError) as caught:
            parse_number(text)
        assert caught.value.message == message


def test_bounds_come_from_the_table_and_are_named():
    assert parse_number("1e6", quantity="rating") == 1e6
    for text, message in [("1e308", "a magnitude estimate must be at most 1e+06, got 1e+308"),
                          ("0", "a magnitude estimate must be positive, got 0"),
                          ("1e-9", "a magnitude estimate must be at least 1e-06, got 1e-09")]:
        with pytest.raises(NumberError) as caught:
            parse_number(text, quantity="rating")
        assert caught.value.message == message
    assert parse_number("3.0", quantity="repetition") == 3 and isinstance(parse_number("3.0", quantity="repetition"), int)
    with pytest.raises(NumberError, match="must be a whole number, got 2.5"):
        parse_number("2.5", quantity="repetition")


def test_whole_numbers_of_many_digits_stay_exact():
    assert parse_number("123456789012345678901234567", whole=True) == 123456789012345678901234567
    with pytest.raises(NumberError, match="digits only"):
        parse_number("1e30", whole=True)  # 1e30 as a float is not the integer 10**30


def test_numbers_from_toml_or_json_are_checked_alike():
    import numpy as np

    assert parse_number(np.float64(2.5)) == 2.5 and parse_number(3) == 3.0
    for value in (True, float("inf"), float("nan"), 10**400, None, [1]):
        with pytest.raises(NumberError):
            parse_number(value)


def test_every_bound_is_a_finite_range():
    for name, bounds in BOUNDS.items():
        assert bounds.low is not None and bounds.high is not None and bounds.low < bounds.high, name
        assert math.isfinite(bounds.low) and math.isfinite(bounds.high), name
    # Every rating within bounds keeps a panel's statistics finite: the extremes' product and squares.
    low, high = BOUNDS["rating"].low, BOUNDS["rating"].high
    assert math.isfinite(high * high * 1e6) and 1 / low < math.inf and math.log(low) > -math.inf


_GRAMMAR = re.compile(r"\s*[+-]?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?\s*", re.ASCII)


@given(st.text(alphabet=st.sampled_from("0123456789+-.eE_ ,\u0661\u00a0xinfa"), max_size=12))
@settings(max_examples=400)
def test_the_parser_is_the_grammar_and_agrees_with_float_where_both_accept(text):
    try:
        value = parse_number(text)
    except NumberError:
        assert not _GRAMMAR.fullmatch(text) or not math.isfinite(float(text))
        return
    assert _GRAMMAR.fullmatch(text) and value == float(text)


@pytest.mark.parametrize("cell", ["1_0", "\u0661", "1e308", "0x10"])
def test_ratings_study_and_manifest_readers_refuse_the_same_cells(tmp_path, cell):
    """One parser: ratings.csv (as `ratings` and `study` read it) and a manifest's force column agree."""
    ratings = tmp_path / "ratings.csv"
    ratings.write_text(f"participant,session,specimen,rating\nP1,1,R2,0.5\nP1,1,C2,{cell}\n", encoding="utf-8")
    with pytest.raises(InputError) as by_command:
        read_ratings(ratings)
    from roughsense.io.ratings_file import read_ratings_table

    with pytest.raises(InputError) as by_study:
        read_ratings_table(ratings)
    assert str(by_command.value) == str(by_study.value) and by_study.value.row == 3
    forces = tmp_path / "forces.csv"
    forces.write_text(f"image,force_n\na.png,1.0\nb.png,{cell}\n", encoding="utf-8")
    with pytest.raises(InputError) as by_table:
        read_table(forces, ["image", "force_n"], positive=["force_n"])
    assert by_table.value.row == 3 and by_table.value.column == "force_n"


@pytest.mark.parametrize("roi", ["1_0,0,5,5", "\u0661,0,5,5", "0x1,0,5,5"])
def test_a_roi_reads_its_numbers_with_the_same_parser(roi):
    from roughsense.errors import ConfigError

    with pytest.raises(ConfigError, match="ROI must be"):
        parse_roi(roi)
    assert parse_roi(" 10 , 0 , 5 , 5 ") == (10, 0, 5, 5)


@pytest.mark.parametrize("args, option", [
    (["features", "--out", "OUT", "--seed", "1_0", "X.png"], "--seed"),
    (["features", "--out", "OUT", "--rows", "\u0661", "X.png"], "--rows"),
    (["features", "--out", "OUT", "--px-per-mm", "3_4.9", "X.png"], "--px-per-mm"),
    (["simulate", "--out", "OUT", "--repetitions", "1_0"], "--repetitions"),
    (["simulate", "--out", "OUT", "--forces-n", "1,2_0"], "--forces"),
    (["simulate", "--out", "OUT", "--jobs", "\u0662"], "--jobs"),
    (["fit", "--study", "builtin", "--pad", "smooth", "--condition", "1N", "--out", "OUT", "--max-components", "1_0"],
     "--max-components"),
    (["predict", "M.json", "X.png", "--px-per-mm", "\u0663\u0664"], "--px-per-mm"),
    (["study", "--out", "OUT", "--permutations", "1_99"], "--permutations"),
])
def test_command_line_numbers_are_spelled_as_in_a_csv(run_cli, tmp_path, args, option):
    """typer read '1_0' as 10 and '\u0661' as 1; every numeric option now refuses them in one line, exit 2."""
    args = [str(tmp_path / a) if a in ("OUT", "X.png", "M.json") else a for a in args]
    code, out, err = run_cli(*args)
    assert code == 2 and "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.startswith("roughsense: error: ")]
    assert len(lines) == 1 and option in lines[0] and "not a number" in lines[0], err
    assert not (tmp_path / "OUT").exists()


@pytest.mark.parametrize("args, message", [
    (["predict", "M.json", "X.png", "--px-per-mm", "inf"], "--px-per-mm must be a positive number (px/mm) from 0.01"),
    (["predict", "M.json", "X.png", "--px-per-mm", "1e-300"], "got '1e-300'"),
    (["simulate", "--out", "OUT", "--fingerprint-period-mm", "1e-300"], "--fingerprint-period-mm must be a positive"),
    (["simulate", "--out", "OUT", "--seed", "1e400"], "--seed must be a finite number"),
])
def test_command_line_numbers_are_finite_and_bounded(run_cli, tmp_path, args, message):
    args = [str(tmp_path / a) if a in ("OUT", "X.png", "M.json") else a for a in args]
    code, _, err = run_cli(*args)
    assert code == 2 and message in err and "Traceback" not in err, err


@pytest.mark.parametrize("old, new, token", [
    ("px_per_mm = 34.9", "px_per_mm = 34.9_0", "34.9_0"),
    ("    2.0,\n", "    0x2,\n", "0x2"),  # tomli-w writes one array item a line
    ("    3.0,\n", "    inf,\n", "inf"),
])
def test_study_toml_numbers_are_spelled_as_a_csv_cell(tmp_path, old, new, token):
    """TOML's parser turns 1_0, 0x2 and inf into numbers before any reader sees them; the text is checked first."""
    from roughsense.errors import InputError
    from roughsense.io.study_config import read_config
    from roughsense.io.toml_write import dump_toml

    text = dump_toml({"study": {"name": "s"}, "sensor": {"px_per_mm": 34.9}, "protocol": {"forces_n": [1.0, 2.0, 3.0]}})
    assert old in text
    (tmp_path / "study.toml").write_text(text.replace(old, new) + '\n[notes]\n# 1_0 in a comment, "0x2" in a string\n')
    with pytest.raises(InputError, match=f"line [0-9]+: '{token}' is not a number") as info:
        read_config(tmp_path / "study.toml")
    assert "study.toml" in str(info.value)


def test_a_sweep_file_number_is_spelled_as_a_csv_cell(tmp_path):
    from roughsense.errors import ConfigError
    from roughsense.explore.sweep import read_sweep

    (tmp_path / "s.toml").write_text('[sweep]\nname = "n_1"\nseeds = [0, 1_0]\n')
    with pytest.raises(ConfigError, match=r"line 3: '1_0' is not a number .*write 10"):
        read_sweep(tmp_path / "s.toml")


# --------------------------------------------------------------------------- one grammar, built from fragments
# The patterns as each module spelled them before io/numbers.py's fragments built them all (issue 38), copied here
# as literals: the built ones must accept exactly the same strings and capture the same groups.
_OLD = {
    "NUMBER": (r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?", re.ASCII),
    "COMMA_NUMBER": (r"[+-]?[0-9]*,[0-9]+(?:[eE][+-]?[0-9]+)?", re.ASCII),
    "tables COMMA_NUMBER": (r"[+-]?\d*,\d+(?:[eE][+-]?\d+)?", re.ASCII),
    "POINT_NUMBER": (r"[+-]?\d*\.\d+(?:[eE][+-]?\d+)?", re.ASCII),
    "NUMBER_WITH_UNIT": (r"([+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?)\s*([^\W\d_]|[%\u00b0\u00b5]).*",
                         0),
    "_READING": (r"^(?P<prefix>(?:[A-Za-z]{2}[\s,]+)*)(?P<sign>[+-])?\s*(?P<number>\d+(?:\.\d*)?|\.\d+)\s*"
                 r"(?P<unit>kg|mn|g|n)$", re.IGNORECASE | re.ASCII),
    "_TYPED_UNIT": (r"^(?P<number>.*?\S)\s*(?P<unit>kg|mn|g|n)$", re.IGNORECASE | re.ASCII),
}


def _new_patterns() -> dict[str, re.Pattern]:
    from roughsense.io import numbers
    from roughsense.rig import scale

    return {"NUMBER": numbers.NUMBER, "COMMA_NUMBER": numbers.COMMA_NUMBER, "tables COMMA_NUMBER": numbers.COMMA_NUMBER,
            "POINT_NUMBER": numbers.POINT_NUMBER, "NUMBER_WITH_UNIT": numbers.NUMBER_WITH_UNIT,
            "_READING": scale._READING, "_TYPED_UNIT": scale._TYPED_UNIT}


# Number-like text: digits, signs, points, commas, exponents, spaces, units and a little garbage (other scripts'
# digits and letters, an underscore, a newline, which ``$`` treats specially).
_PIECES = st.sampled_from(["0", "1", "7", "42", "+", "-", ".", ",", "e", "E", "e-", "E+", " ", "\t", "\n", "kg", "g",
                           "N", "mn", "mm", "%", "\u00b0", "\u00b5", "ST,", "US ", "GS", "_", "x", "\u0661", "\u00e9",
                           "\uff11", "\u00a0"])
_NUMBER_LIKE = st.lists(_PIECES, max_size=8).map("".join)


def _groups(match: re.Match | None):
    return None if match is None else (match.group(0), match.groups(), match.groupdict())


@settings(max_examples=600, deadline=None)
@given(text=_NUMBER_LIKE)
def test_the_built_patterns_accept_exactly_what_the_old_spellings_did(text):
    for name, pattern in _new_patterns().items():
        old = re.compile(*_OLD[name])
        assert _groups(pattern.fullmatch(text)) == _groups(old.fullmatch(text)), (name, text)
        assert _groups(pattern.match(text)) == _groups(old.match(text)), (name, text)  # the scale uses match + $


@settings(max_examples=200, deadline=None)
@given(data=st.data())
def test_what_an_old_spelling_generates_the_built_pattern_reads_alike(data):
    for name, pattern in _new_patterns().items():
        old = re.compile(*_OLD[name])
        text = data.draw(st.from_regex(old, fullmatch=True), label=name)
        assert _groups(pattern.fullmatch(text)) == _groups(old.fullmatch(text)), (name, text)


def test_the_fragments_keep_the_grammars_rules():
    from roughsense.io import numbers
    from roughsense.rig import scale

    assert numbers.POINT_NUMBER.fullmatch("2.5") and not numbers.POINT_NUMBER.fullmatch("2.")  # a digit after it
    assert not numbers.POINT_NUMBER.fullmatch("2")
    assert numbers.COMMA_NUMBER.fullmatch("-,5e3") and not numbers.COMMA_NUMBER.fullmatch("2,")
    assert scale._READING.match("ST,+ 12.5 g") and not scale._READING.match("1e3 g")  # a display has no exponent
    assert numbers.NUMBER_WITH_UNIT.fullmatch("2\u00a0\u041d")  # any script's letter is a unit


@pytest.mark.slow
@settings(FUZZ, max_examples=max(200, EXAMPLES * 3))
@given(text=st.text(alphabet=st.sampled_from(NUMBER_CHARS), max_size=10))
def test_every_number_reader_accepts_the_same_spellings(tmp_path_factory, text):
    """A cell, a ratings cell and a command-line option take exactly the spellings parse_number takes, with the
    same value: no reader falls back to float() (which takes '1_0' and '\u0661') or to pandas' own parser."""
    import pandas as pd
    import typer

    from roughsense.cli._common import number_option
    from roughsense.errors import ConfigError, InputError
    from roughsense.io.csv_read import read_table
    from roughsense.io.numbers import NumberError, parse_number
    from roughsense.io.ratings_file import validate_ratings

    cell = text.replace(",", ";").strip()  # a comma would split the CSV cell; blank cells are a reader's own case
    if not cell:
        return
    try:
        expected = parse_number(cell)
    except NumberError:
        expected = None
    folder = tmp_path_factory.mktemp("numbers")
    table = folder / "t.csv"
    table.write_text(f"name,value\na,{cell}\n", encoding="utf-8")
    try:
        read = float(read_table(table, ["name", "value"], numeric=["value"])["value"].iloc[0])
    except InputError:
        read = None
    assert read == expected or (read is None and expected is None), (cell, read, expected)
    try:
        option = number_option("--x")(cell)
    except (typer.BadParameter, ConfigError):
        option = None
    assert option == expected, (cell, option, expected)
    frame = pd.DataFrame({"participant": ["P1"], "session": ["1"], "specimen": ["R2"], "rating": [cell]})
    try:
        rating = float(validate_ratings(frame)["rating"].iloc[0])
    except InputError:
        rating = None
    in_bounds = expected is not None and 1e-6 <= expected <= 1e6
    assert rating == (expected if in_bounds else None), (cell, rating, expected)
    shutil.rmtree(folder, ignore_errors=True)
