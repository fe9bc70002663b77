"""CSV and TOML as the study folder uses them: line-numbered reads, checked columns, a small TOML writer.
"""
from __future__ import annotations

import csv
import io
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError


def csv_line(index: int) -> int:
    """Line number in the file of DataFrame row ``index`` (line 1 is the header)."""
    return int(index) + 2


def refuse_unknown(frame: pd.DataFrame, column: str, known, path: Path | None, *, hint: str,
                   line=csv_line) -> None:
    """Refuse the first value of ``column`` not in ``known``, naming its line; ``hint`` says where names come from."""
    known = set(known)
    unknown = ~frame[column].isin(known)
    if unknown.any():
        i = int(np.flatnonzero(unknown)[0])
        raise InputError(f"unknown {column} {frame[column].iloc[i]!r} ({hint})", path=path, row=line(i), column=column)


def read_text(path: Path, *, max_bytes: int | None = None) -> str:
    """The file as UTF-8 text (a BOM is dropped); anything else is one InputError naming the line."""
    try:
        if max_bytes is not None and path.stat().st_size > max_bytes:
            raise InputError(f"is larger than {max_bytes // 1_000_000} MB; refusing to read it", path=path)
        raw = path.read_bytes()
    except IsADirectoryError:
        raise InputError("is a folder, expected a file", path=path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path=path) from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise InputError(f"is not UTF-8 text (byte 0x{raw[exc.start]:02x}); save it as UTF-8",
                         path=path, row=line) from None


def _check_row_widths(path: Path, text: str) -> None:
    """Refuse a data row with non-empty fields beyond the header's, naming its line.

    pandas would take the first column as the index and shift every value one column left (or, with
    ``index_col=False``, drop the extras with only a warning). Empty extra fields -- a spreadsheet's
    trailing delimiter -- are accepted. Undecodable or malformed files are left for pandas to report.
    """
    try:
        with io.StringIO(text, newline="") as handle:
            reader = csv.reader(handle, skipinitialspace=True)
            header = next(reader, None)
            if header is None:
                return
            while header and not header[-1].strip():
                header.pop()  # the header's own trailing delimiter names no column
            width = len(header)
            start = reader.line_num + 1
            for row in reader:
                extra = [value for value in row[width:] if value.strip()]
                if extra:
                    raise InputError(
                        f"{len(row)} fields but the header has {width} (extra value {extra[0].strip()!r})",
                        path=path, row=start,
                    )
                start = reader.line_num + 1
    except csv.Error:
        return


def read_table(
    path: str | os.PathLike[str],
    required: Sequence[str],
    *,
    numeric: Sequence[str] = (),
    positive: Sequence[str] = (),
    integer: Sequence[str] = (),
    text: Sequence[str] = (),
    maximum: Mapping[str, float] | None = None,
) -> pd.DataFrame:
    """Read a CSV and check columns and values, naming the line of the first bad cell.

    ``text`` columns are kept as strings (so specimen "3" stays "3", and participant IDs keep leading zeros).
    ``maximum`` bounds numeric columns from above (an absurd force, a repetition number that overflows).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    # Numeric columns are read as text too, so an error quotes the cell as written ('inf', not np.float64(inf)).
    dtypes = dict.fromkeys({*text, *numeric, *positive, *integer, "image", "specimen", "pad", "participant", "shape"}, str)
    frame = _parse_csv(path, dtypes)
    missing = [c for c in required if c not in frame.columns]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}; found {', '.join(frame.columns)}", path=path)
    for column in required:
        blank = frame[column].isna()
        if blank.any():
            raise InputError("empty value", path=path, row=csv_line(np.flatnonzero(blank)[0]), column=column)
    for column in dict.fromkeys([*numeric, *positive, *integer]):
        if column in frame.columns:
            frame[column] = _numeric_column(frame[column], path, positive=column in positive,
                                            integer=column in integer, limit=(maximum or {}).get(column))
    for column in text:
        if column in frame.columns:
            frame[column] = frame[column].str.strip()
    return frame


def _parse_csv(path: Path, dtypes: dict) -> pd.DataFrame:
    """The file as a frame whose row i is file line i + 2; blank lines at the end dropped, inside refused."""
    content = read_text(path)
    _check_row_widths(path, content)
    try:
        # index_col=False: a trailing delimiter on data rows must not turn the first column into the index.
        # skip_blank_lines=False keeps DataFrame row i on file line i + 2, so every error names the right line.
        frame = pd.read_csv(io.StringIO(content), dtype=dtypes, skipinitialspace=True, keep_default_na=False, na_values=[""],
                            index_col=False, skip_blank_lines=False)
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


def _numeric_column(cells: pd.Series, path: Path, *, positive: bool, integer: bool, limit: float | None) -> pd.Series:
    """A column of number cells as floats (or int64 for ``integer``), refusing the first bad cell by its line."""
    column = cells.name
    try:
        values = pd.to_numeric(cells, errors="coerce").astype(float)
    except (OverflowError, ValueError, TypeError):
        values = cells.map(to_float)
    bad = values.isna() & cells.notna()
    bad |= ~np.isfinite(values.fillna(0.0))
    if bad.any():
        i = np.flatnonzero(bad)[0]
        raise InputError(f"not a finite number: {cells.iloc[i]!r}", path=path, row=csv_line(i), column=column)
    if positive:
        nonpos = values <= 0
        if nonpos.any():
            i = np.flatnonzero(nonpos)[0]
            raise InputError(f"must be positive, got {values.iloc[i]:g}", path=path, row=csv_line(i), column=column)
    if limit is not None:
        high = values > limit
        if high.any():
            i = np.flatnonzero(high)[0]
            raise InputError(f"must be at most {limit:g}, got {cells.iloc[i]}", path=path, row=csv_line(i), column=column)
    if not integer:
        return values.astype(float)
    frac = values.notna() & (values != np.round(values))
    if frac.any():
        i = np.flatnonzero(frac)[0]
        raise InputError(f"must be a whole number, got {values.iloc[i]:g}", path=path, row=csv_line(i), column=column)
    return values.astype("Int64") if values.isna().any() else values.astype(np.int64)


def to_float(text: object) -> float:
    try:
        return float(text)
    except (TypeError, ValueError, OverflowError):
        return float("nan")


def has_column(path: Path, column: str) -> bool:
    try:
        with path.open(encoding="utf-8-sig") as handle:
            header = handle.readline(100_000)
    except (OSError, UnicodeDecodeError):
        return False  # read_table then names the real problem
    return column in [c.strip() for c in header.strip().split(",")]


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, str):  # a TOML basic string: quotes, backslashes and control characters escaped
        escaped = "".join(
            "\\" + ch if ch in '"\\' else f"\\u{ord(ch):04X}" if ord(ch) < 0x20 or ord(ch) == 0x7F else ch
            for ch in value
        )
        return f'"{escaped}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def dump_toml(tables: Mapping[str, Mapping[str, object]]) -> str:
    """Tiny TOML writer for flat tables of scalars and lists (all study.toml needs)."""
    lines: list[str] = []
    for table, values in tables.items():
        lines.append(f"[{table}]")
        for key, value in values.items():
            lines.append(f"{key} = {_toml_value(value)}")
        lines.append("")
    return "\n".join(lines)
