"""io/csv_read.py: a study table is read cell by cell or refused naming the row and column -- field counts,
quoted headers, a column named twice, size and width bounds, the encoding."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense.errors import ConfigError, InputError
from roughsense.io import csv_read
from roughsense.io.csv_read import read_table
from roughsense.io.problems import Problems
from roughsense.io.sensor_settings import SensorSettings, parse_roi
from roughsense.io.study import load_study, read_study
from tests.commands import check_output, manifest_lines, write_lines
from tests.fuzzing import EXAMPLES, FUZZ
from tests.studies import write_minimal_study


def test_a_decimal_comma_before_a_blank_optional_column_is_refused(tiny_copy):
    """28.3: ``2,0104,2`` under force_n,repetition,timestamp read as repetition 104 and `check` said OK."""
    lines = manifest_lines(tiny_copy)
    header = lines[0].split(",")
    assert header[-2:] == ["force_n", "repetition"]
    lines[0] += ",timestamp"
    fields = lines[1].split(",")
    lines[1] = ",".join([*fields[:-2], "2,0104", fields[-1], ""])  # force 2,0104 (decimal comma), timestamp blank
    lines[2:] = [line + "," for line in lines[2:]]
    write_lines(tiny_copy / "manifest.csv", lines)
    with pytest.raises(InputError, match=r"7 fields but the header has 6 \(extra empty field\)") as info:
        read_study(tiny_copy)
    assert info.value.row == 2
    lines[1] = ",".join([*fields[:-2], "2", "0104", ""])  # the same count as the header: the leading zero is refused
    write_lines(tiny_copy / "manifest.csv", lines)
    with pytest.raises(InputError, match=r"not a number: '0104' \(a whole number with a leading zero: write 104") as info:
        read_study(tiny_copy)
    assert info.value.row == 2 and info.value.column == "repetition"


@pytest.mark.parametrize("cell, message", [
    ("\u0661", "(write the digits 0-9)"), ("\uff13", "(write the digits 0-9)"),
    ('"1,0"', "(a decimal comma: write 1.0)"), ("0", "must be positive"),
])
def test_a_quoted_header_is_read_by_the_number_parser(tiny_copy, cell, message):
    """28.6: ``"nominal_force_n"`` (R's write.csv quotes every name) skipped the parser: 1 and 3 in other scripts."""
    lines = manifest_lines(tiny_copy)
    lines[0] = ",".join(f'"{name}"' for name in lines[0].split(",")) + ',"nominal_force_n"'
    lines[1:] = [line + ",2" for line in lines[1:]]
    lines[1] = lines[1][: -len(",2")] + f",{cell}"
    write_lines(tiny_copy / "manifest.csv", lines)
    with pytest.raises(InputError) as info:
        read_study(tiny_copy)
    assert message in info.value.message and info.value.column == "nominal_force_n" and info.value.row == 2


@pytest.mark.parametrize("file, column", [("manifest.csv", "force_n"), ("ratings.csv", "rating"),
                                          ("specimens.csv", "wavelength_mm")])
def test_a_column_named_twice_is_refused(run_cli, tiny_copy, file, column):
    """28.7: pandas read the second force_n or rating as force_n.1 and it was ignored."""
    path = tiny_copy / file
    lines = path.read_text().splitlines()
    lines[0] += f", {column}"
    lines[1:] = [line + ",7" for line in lines[1:]]
    write_lines(path, lines)
    line = check_output(run_cli, tiny_copy)
    assert f"{path}: column '{column}' appears twice in the header" in line


def test_a_csv_too_large_or_too_wide_is_refused_before_it_is_read(run_cli, tiny_copy, monkeypatch):
    """28.12: 2 million columns took 97 s and 3.7 GB; a 6 GB sparse ratings.csv ran `check` out of memory."""
    ratings = tiny_copy / "ratings.csv"
    with ratings.open("r+b") as handle:
        handle.truncate(csv_read.MAX_CSV_BYTES + 1)  # sparse: costs no disk
    line = check_output(run_cli, tiny_copy)
    assert f"{ratings}: is larger than 100 MB; refusing to read it" in line
    manifest = tiny_copy / "manifest.csv"
    manifest.write_text(",".join(f"c{i}" for i in range(200_000)) + "\n")
    line = check_output(run_cli, tiny_copy)
    assert f"{manifest}: has 200000 columns; a study file has at most {csv_read.MAX_CSV_COLUMNS}" in line


@pytest.mark.parametrize("encoding, name", [("utf-16-le", "UTF-16LE (no byte-order mark)"), ("utf-16", "UTF-16"),
                                            ("utf-16-be", "UTF-16BE (no byte-order mark)")])
def test_a_wide_encoding_is_named(tiny_copy, encoding, name):
    path = tiny_copy / "ratings.csv"
    path.write_bytes(path.read_text().encode(encoding))
    problems = Problems()
    load_study(tiny_copy, problems=problems)
    messages = problems.lines()
    assert any(f"ratings.csv: is {name} text, not UTF-8; save it as UTF-8" in m for m in messages), messages


def test_read_table_names_the_line_of_a_bad_value(tmp_path):
    path = tmp_path / "ratings.csv"
    path.write_text("participant,session,specimen,rating\nP1,1,R2,0.5\nP1,2,R2,abc\n")
    with pytest.raises(InputError) as info:
        read_table(path, ["participant", "session", "specimen", "rating"], positive=["rating"])
    assert info.value.row == 3 and info.value.column == "rating"


def test_manifest_with_trailing_commas_reads_as_without(tmp_path):
    write_minimal_study(tmp_path / "s")
    plain = read_study(tmp_path / "s")
    for name in ("manifest.csv", "specimens.csv"):
        path = tmp_path / "s" / name
        path.write_text("".join(line + ",\n" for line in path.read_text().splitlines()))
    commas = read_study(tmp_path / "s")
    pd.testing.assert_frame_equal(commas.manifest, plain.manifest)
    pd.testing.assert_frame_equal(commas.specimens, plain.specimens)
    assert list(commas.manifest["image"]) == ["images/R2.png", "images/R3.png"]


def test_manifest_row_with_an_extra_value_names_its_line(tmp_path):
    write_minimal_study(tmp_path / "s")
    manifest = tmp_path / "s" / "manifest.csv"
    lines = manifest.read_text().splitlines()
    lines[2] += ",smooth"  # one row too long: pandas would have shifted it under the header
    manifest.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as info:
        read_study(tmp_path / "s")
    assert info.value.path == manifest and info.value.row == 3
    assert info.value.message == "6 fields but the header has 5 (extra value 'smooth')"


def test_number_errors_quote_the_cell_not_numpy(tmp_path):
    path = tmp_path / "specimens.csv"
    path.write_text("specimen,shape,wavelength_mm\nR2,rectangular,2\nR3,rectangular,inf\n")
    with pytest.raises(InputError) as info:
        read_table(path, ["specimen", "shape", "wavelength_mm"], positive=["wavelength_mm"])
    assert info.value.message == "not a finite number: 'inf'" and info.value.row == 3
    with pytest.raises(ConfigError, match=r"px_per_mm must be a positive number, got inf$"):
        SensorSettings(px_per_mm=np.float64("inf"))
    with pytest.raises(ConfigError, match=r"got 0,0,-1,5$"):
        parse_roi([np.int64(0), np.int64(0), np.int64(-1), np.int64(5)])


def test_blank_lines_keep_line_numbers_honest(tmp_path):
    path = tmp_path / "ratings.csv"
    path.write_text("participant,session,specimen,rating\nP1,1,R2,0.5\n\nP1,2,R2,abc\n")
    with pytest.raises(InputError) as info:
        read_table(path, ["participant", "session", "specimen", "rating"], positive=["rating"])
    assert info.value.row == 3 and "blank line" in str(info.value)
    path.write_text("participant,session,specimen,rating\nP1,1,R2,0.5\nP1,2,R2,abc\n\n\n")
    with pytest.raises(InputError) as info:
        read_table(path, ["participant", "session", "specimen", "rating"], positive=["rating"])
    assert info.value.row == 3 and info.value.column == "rating"  # trailing blank lines are ignored
    path.write_text("participant,session,specimen,rating\nP1,1,R2,0.5\n\n")
    assert len(read_table(path, ["participant", "session", "specimen", "rating"], positive=["rating"])) == 1


@pytest.mark.slow
@settings(FUZZ, max_examples=max(100, EXAMPLES))
@given(header=st.integers(1, 5), rows=st.lists(st.lists(st.sampled_from(["1", ""]), min_size=0, max_size=6).map(
    lambda r: ["1", *r]), min_size=1, max_size=5))
def test_a_row_is_read_iff_its_field_count_is_the_headers(tmp_path_factory, header, rows):
    """Issue 28.3: blanks count; a row wider or narrower than the header is refused, never shifted or padded."""
    from roughsense.errors import InputError
    from roughsense.io.csv_read import read_table

    path = tmp_path_factory.mktemp("widths") / "t.csv"
    path.write_text("\n".join([",".join(f"c{i}" for i in range(header)), *(",".join(r) for r in rows)]) + "\n")
    try:
        read_table(path, [])
        read = True
    except InputError as exc:
        read = False
        assert "fields but the header has" in exc.message, exc.message
    assert read == all(len(r) == header for r in rows), (header, rows)


def test_the_reader_drops_a_bom_and_names_a_mixed_separator_and_a_names_case(tmp_path):
    """io/csv_read.py's own helpers: UTF-8 text without its BOM; absent columns told the separator fix; an unknown
    name that is a known one in another case named as the slip it is, on its file line (row 0 is line 2)."""
    from roughsense.io.csv_read import csv_line, missing_columns, read_text, refuse_unknown

    path = tmp_path / "ratings.csv"
    path.write_bytes("\ufeffspecimen;rating\nR2;0.5\n".encode())
    assert read_text(path) == "specimen;rating\nR2;0.5\n"
    error = missing_columns(["specimen", "rating"], ["specimen;rating"], path)
    assert error.message == ("missing column(s) specimen, rating; found specimen;rating; the header mixes ',' and ';' "
                             "separators: use one throughout, e.g. save it as CSV UTF-8 (comma delimited)")
    frame = pd.DataFrame({"specimen": ["R2", "r4", "R3"]})
    with pytest.raises(InputError) as info:
        refuse_unknown(frame, "specimen", {"R2", "R3", "R4"}, path, hint="specimens.csv lists them")
    assert info.value.row == csv_line(1) == 3 and info.value.column == "specimen"
    assert info.value.message == "unknown specimen 'r4' (specimens.csv lists them; did you mean 'R4'?)"
