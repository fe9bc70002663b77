"""io/csv_read.py: a study table is read cell by cell or refused naming the row and column -- field counts,
quoted headers, a column named twice, size and width bounds, the encoding."""
from __future__ import annotations

import pytest

from roughsense.errors import InputError
from roughsense.io import tables
from roughsense.io.problems import Problems
from roughsense.io.study import load_study, read_study
from tests.commands import check_output, manifest_lines, write_lines


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
        handle.truncate(tables.MAX_CSV_BYTES + 1)  # sparse: costs no disk
    line = check_output(run_cli, tiny_copy)
    assert f"{ratings}: is larger than 100 MB; refusing to read it" in line
    manifest = tiny_copy / "manifest.csv"
    manifest.write_text(",".join(f"c{i}" for i in range(200_000)) + "\n")
    line = check_output(run_cli, tiny_copy)
    assert f"{manifest}: has 200000 columns; a study file has at most {tables.MAX_CSV_COLUMNS}" in line


@pytest.mark.parametrize("encoding, name", [("utf-16-le", "UTF-16LE (no byte-order mark)"), ("utf-16", "UTF-16"),
                                            ("utf-16-be", "UTF-16BE (no byte-order mark)")])
def test_a_wide_encoding_is_named(tiny_copy, encoding, name):
    path = tiny_copy / "ratings.csv"
    path.write_bytes(path.read_text().encode(encoding))
    problems = Problems()
    load_study(tiny_copy, problems=problems)
    messages = problems.lines()
    assert any(f"ratings.csv: is {name} text, not UTF-8; save it as UTF-8" in m for m in messages), messages
