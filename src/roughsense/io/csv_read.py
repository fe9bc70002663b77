"""Reading the study folder's CSV files: line-numbered reads, the dialects (a semicolon and a decimal comma),
checked shapes and columns, every number through the one parser (:mod:`.numbers`).
"""
from __future__ import annotations

import codecs
import csv
import io
import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from .._util.files import read_regular
from ..errors import InputError, RoughsenseWarning
from .numbers import BOUNDS, COMMA_NUMBER, POINT_NUMBER, NumberError, parse_number
from .problems import Problems, flag, report, same_but_case

#: Columns holding names, never numbers: a decimal comma is not looked for there ("1,5" stays a (bad) name).
NAME_COLUMNS = frozenset({"image", "specimen", "pad", "participant", "session", "shape"})


def csv_line(index: int) -> int:
    """Line number in the file of DataFrame row ``index`` (line 1 is the header)."""
    return int(index) + 2


def refuse_unknown(frame: pd.DataFrame, column: str, known, path: Path | None, *, hint: str,
                   line=csv_line, problems: Problems | None = None) -> None:
    """Refuse each value of ``column`` not in ``known``, naming its line; ``hint`` says where names come from.

    A name that differs from a known one only by case (``r4`` for ``R4``) is named: it is the usual slip.
    """
    known = set(known)
    unknown = ~frame[column].isin(known)
    if problems is not None:
        unknown &= frame[column].notna() & (frame[column] != "")  # a blank cell is its own problem

    def error(i: int) -> InputError:
        value = frame[column].iloc[i]
        match = same_but_case(value, known)
        guess = f"; did you mean {match!r}?" if match is not None else ""
        return InputError(f"unknown {column} {value!r} ({hint}{guess})", path=path, row=line(i), column=column)

    flag(problems, unknown.to_numpy(bool), error)


#: Columns whose bounds are another quantity's (a nominal force is a force).
COLUMN_QUANTITY = {"nominal_force_n": "force_n"}


def missing_columns(missing: Sequence[str], found: Sequence[object], path: Path | None) -> InputError:
    """The error for absent columns, naming those found; a header that mixes ``;`` and ``,`` is told what to do."""
    found = [str(c) for c in found]
    fix = ("; the header mixes ',' and ';' separators: use one throughout, e.g. save it as CSV UTF-8 (comma delimited)"
           if any(";" in c for c in found) else "")
    return InputError(f"missing column(s) {', '.join(missing)}; found {', '.join(found) or 'nothing'}{fix}", path=path)


def read_text(path: Path, *, max_bytes: int | None = None) -> str:
    """The file as UTF-8 text (a BOM is dropped); anything else is one InputError naming the line."""
    try:
        raw = read_regular(path, limit=None if max_bytes is None else max_bytes + 1)  # a FIFO: refused, no wait
        if max_bytes is not None and len(raw) > max_bytes:
            raise InputError(f"is larger than {max_bytes // 1_000_000} MB; refusing to read it", path=path)
    except IsADirectoryError:
        raise InputError("is a folder, expected a file", path=path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path=path) from None
    wide = _wide_encoding(raw)
    if wide is not None:  # UTF-16 decodes as UTF-8 full of NULs (without a BOM): say what it is, not garbage
        raise InputError(f"is {wide} text, not UTF-8; save it as UTF-8 (e.g. CSV UTF-8 in Excel)", path=path)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise InputError(f"is not UTF-8 text (byte 0x{raw[exc.start]:02x}); save it as UTF-8",
                         path=path, row=line) from None


def _wide_encoding(raw: bytes) -> str | None:
    """``"UTF-16LE"`` (or BE, or UTF-32) if the bytes are text in a wide encoding, with or without a BOM, else None."""
    for bom, name in ((codecs.BOM_UTF32_LE, "UTF-32"), (codecs.BOM_UTF32_BE, "UTF-32"),
                      (codecs.BOM_UTF16_LE, "UTF-16"), (codecs.BOM_UTF16_BE, "UTF-16")):
        if raw.startswith(bom):
            return name
    head = raw[:4096]
    if b"\x00" not in head:
        return None
    odd, even = head[1::2].count(0), head[0::2].count(0)
    if odd > len(head) // 4 and even == 0:
        return "UTF-16LE (no byte-order mark)"
    if even > len(head) // 4 and odd == 0:
        return "UTF-16BE (no byte-order mark)"
    return None


def _semicolon_header(text: str) -> bool:
    header = text.split("\n", 1)[0]
    return ";" in header and "," not in header


def _from_semicolons(path: Path, text: str) -> str:
    """A semicolon-separated file (European Excel's CSV) as the comma-separated text it means, with one warning.

    Decimal commas are turned into points where every number cell agrees; a file mixing ``0,5`` and ``1.25`` is
    ambiguous (``1.250`` may be a thousands separator) and refused. Lines keep their numbers.
    """
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=";", skipinitialspace=True)
    rows, starts = [], []
    try:
        for row in reader:
            rows.append(row)
            starts.append(reader.line_num - sum(row_text.count("\n") for row_text in row))
    except csv.Error:
        return text  # pandas names the malformed file
    header = [name.strip() for name in rows[0]] if rows else []
    comma = point = None
    for row, line in zip(rows[1:], starts[1:]):
        for k, cell in enumerate(row):
            if k < len(header) and header[k] in NAME_COLUMNS:
                continue
            cell = cell.strip()
            if comma is None and COMMA_NUMBER.fullmatch(cell):
                comma = (cell, line)
            elif point is None and POINT_NUMBER.fullmatch(cell):
                point = (cell, line)
    if comma is not None and point is not None:
        raise InputError(f"is semicolon-separated but mixes decimal commas ({comma[0]!r}, row {comma[1]}) and "
                         f"decimal points ({point[0]!r}, row {point[1]}); write every number with the same decimal mark",
                         path=path)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    for number, row in enumerate(rows):
        if comma is not None and number > 0:
            row = [cell.strip().replace(",", ".") if COMMA_NUMBER.fullmatch(cell.strip())
                   and not (k < len(header) and header[k] in NAME_COLUMNS) else cell for k, cell in enumerate(row)]
        writer.writerow(row)
    decimals = " with decimal commas" if comma is not None else ""
    warnings.warn(f"{path}: read as semicolon-separated{decimals} (as European Excel saves it)",
                  RoughsenseWarning, stacklevel=4)
    return out.getvalue()


#: A study's CSVs are a few MB (a manifest of 10^5 images is about 10 MB); far larger is not a study file, and is
#: refused before it is read (a 6 GB sparse file would exhaust memory).
MAX_CSV_BYTES = 100_000_000
#: More columns than any study file needs (manifest: 5 required, a few optional, a user's notes): a header of
#: millions of columns is refused before pandas spends minutes and gigabytes on it.
MAX_CSV_COLUMNS = 1000


def _header_of(path: Path, reader) -> list[str] | None:
    """The header's column names (stripped); its own trailing delimiters name no column and are not counted.

    Too many columns, or one name twice (pandas would read the second ``force_n`` as ``force_n.1`` and ignore it),
    is a problem with the whole file: raised even when collecting.
    """
    header = next(reader, None)
    if header is None:
        return None
    header = [name.strip() for name in header]
    if len(header) > MAX_CSV_COLUMNS:
        raise InputError(f"has {len(header)} columns; a study file has at most {MAX_CSV_COLUMNS}", path=path)
    seen: dict[str, int] = {}
    for position, name in enumerate(header, start=1):
        if name and name in seen:
            raise InputError(f"column {name!r} appears twice in the header (columns {seen[name]} and {position}); "
                             "remove or rename one", path=path)
        seen[name] = position
    return header


def _row_width_problem(row: list[str], width: int, raw_width: int) -> str | None:
    """Why a data row's field count is not the header's (blanks included), or None.

    A row wider than the header, even by empty fields, is how a decimal comma shifts values (``2,0104,2`` read as
    force 2, repetition 104); a shorter row leaves a value under the wrong column. The header's own trailing
    delimiters (a spreadsheet's) may be repeated by the rows.
    """
    extra = [value.strip() for value in row[width:] if value.strip()]
    if extra:  # a nameless column (the header's trailing delimiter) holds no data either
        decimal = "; a decimal comma? write numbers with a point (0.5, not 0,5)" if extra[0].isdigit() else ""
        return f"{len(row)} fields but the header has {width} (extra value {extra[0]!r}){decimal}"
    if len(row) in (width, raw_width):
        return None
    if len(row) < width:
        return f"{len(row)} fields but the header has {width}; write one field per column (an empty one as ,,)"
    return (f"{len(row)} fields but the header has {width} (extra empty field); a decimal comma (write 0.5, not 0,5) "
            "or a trailing delimiter? every row needs the header's number of fields")


def _check_shape(path: Path, text: str, problems: Problems | None = None) -> str:
    """Refuse duplicate or too many columns, and each data row whose field count is not the header's, by its line.

    pandas would take the first column as the index and shift every value one column left (or, with
    ``index_col=False``, drop the extras with only a warning, and fill a short row with blanks). Blank lines are
    left to :func:`_parse_csv`; malformed files to pandas. Returns the text to parse: when collecting, a reported
    row is cut to the header's width, so pandas does not stop at it ("C error") and ``check`` lists the rest
    (the row's cells are not reported again: :class:`Problems` keeps one problem per row that is wrong as a whole).
    """
    lines = text.split("\n")
    try:
        with io.StringIO(text, newline="") as handle:
            reader = csv.reader(handle, skipinitialspace=True)
            header = _header_of(path, reader)
            if header is None:
                return text
            raw_width = len(header)
            while header and not header[-1]:
                header.pop()  # the header's own trailing delimiter names no column
            start = reader.line_num + 1
            for row in reader:
                problem = _row_width_problem(row, len(header), raw_width) if row else None
                if problem is not None:
                    report(problems, InputError(problem, path=path, row=start))
                    if reader.line_num == start:  # one physical line: cut to the header's width
                        lines[start - 1] = _csv_row((row + [""] * raw_width)[:raw_width])
                start = reader.line_num + 1
    except csv.Error:
        return text
    return "\n".join(lines)


def _csv_row(row: list[str]) -> str:
    with io.StringIO() as handle:
        csv.writer(handle, lineterminator="").writerow(row)
        return handle.getvalue()


def read_table(
    path: str | os.PathLike[str],
    required: Sequence[str],
    *,
    numeric: Sequence[str] = (),
    positive: Sequence[str] = (),
    integer: Sequence[str] = (),
    text: Sequence[str] = (),
    maximum: Mapping[str, float] | None = None,
    problems: Problems | None = None,
) -> pd.DataFrame:
    """Read a CSV and check columns and values, naming the line of the first bad cell (or of each, into ``problems``).

    ``text`` columns are kept as strings (so specimen "3" stays "3", and participant IDs keep leading zeros).
    Every number cell is read by :func:`~roughsense.io.numbers.parse_number`; a column named in its ``BOUNDS``
    (force_n, repetition, wavelength_mm, ...) is bounded there, any other by ``positive`` and ``maximum``.
    A problem with the whole file (unreadable, a column missing) is raised even when collecting: nothing else in
    it can be checked. A semicolon-separated file is read as comma-separated, with a warning (see ``_from_semicolons``).
    """
    path = Path(path)
    if not path.exists():  # a FIFO or a folder there is named by read_text, not "not found"
        raise InputError("file not found", path=path)
    # Numeric columns are read as text too, so an error quotes the cell as written ('inf', not np.float64(inf)).
    dtypes = dict.fromkeys({*text, *numeric, *positive, *integer, "image", "specimen", "pad", "participant", "shape"}, str)
    frame = _parse_csv(path, dtypes, problems)
    missing = [c for c in required if c not in frame.columns]
    if missing:
        raise missing_columns(missing, frame.columns, path)
    for column in required:
        flag(problems, frame[column].isna(),
             lambda i, column=column: InputError("empty value", path=path, row=csv_line(i), column=column))
    for column in dict.fromkeys([*numeric, *positive, *integer]):
        if column in frame.columns:
            frame[column] = _numeric_column(frame[column], path, positive=column in positive,
                                            integer=column in integer, limit=(maximum or {}).get(column),
                                            problems=problems)
    for column in text:
        if column in frame.columns:
            frame[column] = frame[column].str.strip()
    return frame


def _parse_csv(path: Path, dtypes: dict, problems: Problems | None = None) -> pd.DataFrame:
    """The file as a frame whose row i is file line i + 2; blank lines at the end dropped, inside refused."""
    content = read_text(path, max_bytes=MAX_CSV_BYTES)
    if _semicolon_header(content):
        content = _from_semicolons(path, content)
    content = _check_shape(path, content, problems)
    try:
        # index_col=False: a trailing delimiter on data rows must not turn the first column into the index.
        # skip_blank_lines=False keeps DataFrame row i on file line i + 2, so every error names the right line.
        with warnings.catch_warnings():  # rows too wide were reported above (only when collecting do we get here)
            warnings.simplefilter("ignore", pd.errors.ParserWarning)
            frame = pd.read_csv(io.StringIO(content), dtype=dtypes, skipinitialspace=True, keep_default_na=False,
                                na_values=[""], index_col=False, skip_blank_lines=False)
    except pd.errors.EmptyDataError:
        raise InputError("is empty; expected a header line", path=path) from None
    except (pd.errors.ParserError, ValueError, OverflowError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"is not a readable CSV ({first})", path=path) from None
    frame.columns = [str(c).strip() for c in frame.columns]
    # A trailing delimiter on the header too gives a nameless, empty column: drop it.
    nameless = [c for c in frame.columns if c.startswith("Unnamed: ") and frame[c].isna().all()]
    frame = frame.drop(columns=nameless)
    blank_rows = frame.isna().all(axis=1).to_numpy()
    if blank_rows.any():
        last = len(blank_rows) - np.argmin(blank_rows[::-1]) if not blank_rows.all() else 0
        if blank_rows[:last].any():
            raise InputError("blank line inside the table; remove it", path=path, row=csv_line(np.flatnonzero(blank_rows)[0]))
        frame = frame.iloc[:last]  # blank lines at the end of the file are harmless
    return frame


def _column_bounds(column: str, *, positive: bool, integer: bool, limit: float | None) -> dict:
    """How :func:`parse_number` checks a column: its quantity's row of ``BOUNDS`` if it has one, else the caller's."""
    quantity = COLUMN_QUANTITY.get(column, column)
    if quantity in BOUNDS:
        return {"quantity": quantity, "whole": integer}
    return {"low": 0.0 if positive else None, "low_open": positive, "high": limit, "whole": integer}


def _numeric_column(cells: pd.Series, path: Path, *, positive: bool, integer: bool, limit: float | None,
                    problems: Problems | None = None) -> pd.Series:
    """A column of number cells as floats (or int64 for ``integer``), each read by :func:`parse_number` and
    refused by its line with its message.

    When collecting, a bad cell becomes missing, so it is reported once and not again by a later check.
    """
    column = cells.name
    bounds = _column_bounds(str(column), positive=positive, integer=integer, limit=limit)
    values = np.full(len(cells), np.nan)
    messages: dict[int, str] = {}
    for i, cell in enumerate(cells.to_numpy(object)):
        if cell is None or (isinstance(cell, float) and np.isnan(cell)):
            continue  # a blank cell: reported as empty by read_table when the column is required
        try:
            values[i] = parse_number(cell, **bounds)
        except NumberError as exc:
            messages[i] = exc.message
    flag(problems, [i in messages for i in range(len(cells))],
         lambda i: InputError(messages[i], path=path, row=csv_line(i), column=column))
    values = pd.Series(values, index=cells.index, name=column)
    if not integer:
        return values
    return values.astype("Int64") if values.isna().any() else values.astype(np.int64)
