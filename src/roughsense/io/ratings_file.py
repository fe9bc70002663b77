"""ratings.csv: the one reader and validator of participants' magnitude estimates, used by every command.

Files (``roughsense ratings``, ``study``, ``fit``) and frames built in memory (the simulated panel of a sweep cell)
pass the same checks with the same messages, so the aggregation downstream takes a clean frame and checks nothing.
"""
from __future__ import annotations

import math
import os
import re
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from ..paper import REFERENCE_SPECIMEN
from .csv_read import MAX_CSV_BYTES, csv_line, missing_columns, read_table, read_text, refuse_unknown
from .names import check_name_column
from .numbers import NumberError, parse_number
from .problems import Problems, flag

RATING_COLUMNS = ("participant", "session", "specimen", "rating")
KEY_COLUMNS = ("participant", "session", "specimen")


def natural_key(name: object) -> tuple:
    """Sort "R2.5" before "R10" and numbers as numbers ("P2" < "P10", session "2" < "10")."""
    parts = re.split(r"(\d+(?:\.\d+)?)", str(name))
    return tuple((0, float(p), "") if i % 2 else (1, 0.0, p) for i, p in enumerate(parts) if p != "")


def drop_unrated(frame: pd.DataFrame) -> pd.DataFrame:
    """The one rule for blank rating cells: a trial not (yet) done, dropped; aggregation warns about the gap.

    Used by every ratings reader (``roughsense ratings``, ``study``, ``fit``), so a file means the same to all.
    Frames keep their index (``index + 2`` is the file line) for later errors.
    """
    if "rating" not in frame.columns:
        return frame
    blank = np.fromiter((_is_blank(v) for v in frame["rating"].to_numpy(object)), dtype=bool, count=len(frame))
    return frame[~blank]


def _is_blank(value: object) -> bool:
    if isinstance(value, str):
        return not value.strip()
    return value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value))


def read_ratings_table(path: str | os.PathLike[str], *, reference: str = REFERENCE_SPECIMEN,
                       specimens: Iterable[str] | None = None, unknown_hint: str | None = None,
                       allow_empty: bool = False, problems: Problems | None = None) -> pd.DataFrame:
    """Read and validate ratings.csv (or a filled-in schedule CSV): see :func:`validate_ratings`.

    Blank rating cells follow :func:`drop_unrated`; a file with no rating left is refused unless ``allow_empty``
    (a study of the reference specimen alone has nothing to rate, and only the analysis needs ratings).
    Rating cells are read as text, so an error quotes the cell as written.
    """
    path = Path(path)
    frame = read_table(path, (), text=(*KEY_COLUMNS, "rating"), problems=problems)
    frame = drop_unrated(frame)
    if frame.empty and allow_empty and "rating" in frame.columns:
        return frame.assign(rating=pd.Series(dtype=float))
    if frame.empty and set(RATING_COLUMNS) <= set(frame.columns):
        raise InputError("has no ratings (no row, or every rating cell is empty)", path=path)
    return validate_ratings(frame, path=path, reference=reference, specimens=specimens, unknown_hint=unknown_hint,
                            problems=problems)


def _line(frame: pd.DataFrame, position: int) -> int | None:
    """File line of the row at ``position`` (frames keep ``index + 2 == line``)."""
    label = frame.index[position]
    return csv_line(label) if isinstance(label, (int, np.integer)) else None


def validate_ratings(frame: pd.DataFrame, *, path: str | os.PathLike[str] | None = None,
                     reference: str = REFERENCE_SPECIMEN, specimens: Iterable[str] | None = None,
                     unknown_hint: str | None = None, problems: Problems | None = None) -> pd.DataFrame:
    """The checks every ratings table passes; returns a clean copy (text keys, float ratings), index kept.

    Columns present, keys non-empty and obeying the name rule, ratings numbers within ``BOUNDS["rating"]``
    (:mod:`.numbers`: the spelling every reader accepts, 1e-6 to 1e6), the reference
    never rated, specimens known (``specimens``; ``unknown_hint`` says where names come from), and no
    participant rating a specimen twice in a session. Errors name the file line (``index + 2``): the first is
    raised, or each is added to ``problems`` (a missing column is raised all the same).
    """
    missing = [c for c in RATING_COLUMNS if c not in frame.columns]
    if missing:
        raise missing_columns(missing, frame.columns, path)
    frame = frame.copy()
    for column in KEY_COLUMNS:
        text = frame[column].map(lambda v: "" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v).strip())
        flag(problems, text == "",
             lambda i, column=column: InputError("empty value", path=path, row=_line(frame, i), column=column))
        frame[column] = text
        check_name_column(frame, column, Path(path) if path is not None else None, line=lambda i: _line(frame, i),
                          problems=problems)
    frame["rating"] = _rating_values(frame, path, problems)
    flag(problems, frame["specimen"] == reference, lambda i: InputError(
        f"{reference} is the reference (fixed at 1.0 by definition) and must not be rated",
        path=path, row=_line(frame, i), column="specimen"))
    if specimens is not None:
        known = set(specimens)
        refuse_unknown(frame, "specimen", known, path, line=lambda i: _line(frame, i), problems=problems,
                       hint=unknown_hint or f"expected one of {', '.join(sorted(known, key=natural_key))}")
    _refuse_repeats(frame, path, problems)
    return frame


def _rating_values(frame: pd.DataFrame, path, problems: Problems | None = None) -> pd.Series:
    """The rating column as floats: a positive finite magnitude estimate in every row (a bad one, when collecting
    problems, left missing so that it is reported once)."""
    raw = frame["rating"]
    blank = raw.isna() | raw.map(lambda v: isinstance(v, str) and v.strip() == "")
    values = np.full(len(raw), np.nan)
    messages: dict[int, str] = {}
    for i, cell in enumerate(raw.to_numpy(object)):
        if blank.iloc[i]:
            continue
        try:
            values[i] = parse_number(cell, quantity="rating")  # within BOUNDS["rating"]: every gmean and SD finite
        except NumberError as exc:
            messages[i] = exc.message
    flag(problems, [i in messages for i in range(len(raw))],
         lambda i: InputError(messages[i], path=path, row=_line(frame, i), column="rating"))
    flag(problems, blank, lambda i: InputError("empty rating", path=path, row=_line(frame, i), column="rating"))
    return pd.Series(values, index=raw.index, name="rating")


def _refuse_repeats(frame: pd.DataFrame, path, problems: Problems | None = None) -> None:
    """A participant rates each specimen once per session."""
    keys = list(KEY_COLUMNS)
    duplicated = frame.duplicated(keys, keep="first") & (frame[keys] != "").all(axis=1)

    def error(i: int) -> InputError:
        row = frame.iloc[i]
        first = _line(frame, np.flatnonzero((frame[keys] == row[keys]).all(axis=1))[0])
        return InputError(
            f"participant {row['participant']} rated {row['specimen']} twice in session {row['session']}"
            + (f" (first on line {first})" if first is not None else ""),
            path=path, row=_line(frame, i), column="specimen",
        )

    flag(problems, duplicated, error)


def _read_markdown_sheet(path: Path) -> pd.DataFrame:
    """Rows of every Markdown table whose header names the rating columns (a filled-in sheet).

    The frame's index is ``line - 2`` so that errors name the line of the Markdown file.
    """
    lines = read_text(path, max_bytes=MAX_CSV_BYTES).splitlines()  # the CSVs' size and encoding rules
    rows, index, header = [], [], None
    for number, line in enumerate(lines, start=1):
        text = line.strip()
        if not text.startswith("|"):
            header = None
            continue
        cells = [c.strip() for c in text.strip("|").split("|")]
        if header is None:
            header = [c.lower() for c in cells]
            twice = next((c for k, c in enumerate(header) if c and c in header[:k]), None)
            if twice is not None and set(RATING_COLUMNS) <= set(header):
                raise InputError(f"table column {twice!r} appears twice in the header; remove or rename one",
                                 path=path, row=number)
            continue
        if all(re.fullmatch(r":?-+:?", c) for c in cells):
            continue
        if not set(RATING_COLUMNS) <= set(header):
            continue
        if len(cells) != len(header):
            raise InputError(f"table row has {len(cells)} cells, the header has {len(header)}", path=path, row=number)
        rows.append(dict(zip(header, cells)))
        index.append(number - 2)
    if not rows:
        raise InputError(f"no table with columns {', '.join(RATING_COLUMNS)} found", path=path)
    frame = pd.DataFrame(rows, index=index)
    return frame.replace("", np.nan)


def read_ratings(
    path: str | os.PathLike[str],
    *,
    specimens: Iterable[str] | None = None,
    reference: str = REFERENCE_SPECIMEN,
) -> pd.DataFrame:
    """Read and validate ratings.csv -- or a filled-in schedule (CSV or Markdown sheet).

    Rows whose ``rating`` cell is blank are not-yet-rated trials and are dropped (aggregation then warns
    about the gap); anything else wrong is an :class:`InputError` naming the line. The returned frame
    keeps ``index + 2 == line in the file`` and has columns participant, session, specimen (text) and
    rating (float), plus any extra columns of the file.
    """
    path = Path(path)
    if path.suffix.lower() not in (".md", ".markdown"):
        return read_ratings_table(path, reference=reference, specimens=specimens)
    if not path.exists():  # anything else that is not a regular file is named by the reader
        raise InputError("file not found", path=path)
    frame = drop_unrated(_read_markdown_sheet(path))
    if frame.empty:
        raise InputError("has no ratings (no row, or every rating cell is empty)", path=path)
    return validate_ratings(frame, path=path, reference=reference, specimens=specimens)
