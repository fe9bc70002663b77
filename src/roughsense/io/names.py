"""The one name rule: which names from data may become parts of file names.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import pandas as pd

from ..errors import InputError
from .csv_read import csv_line
from .problems import Problems, flag

#: Longest name (see :func:`check_name`): file names built from two names and a suffix stay far below the
#: 255-byte limit of common file systems.
NAME_MAX_CHARS = 64


_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")


NAME_RULE = (f"letters, digits, '.', '_' and '-' only, starting with a letter or digit, "
             f"at most {NAME_MAX_CHARS} characters")


def is_safe_name(value: object) -> bool:
    """True if ``value`` may become part of a file name (see :data:`NAME_RULE`).

    Names from data (pad, specimen, participant, session, condition) end up in file names: in images the
    rig and the simulator write, in report figures. The rule leaves no room for a separator, ``..``, a
    hidden file, an option-like leading ``-``, a control character or a name too long for the disk.
    """
    return isinstance(value, str) and len(value) <= NAME_MAX_CHARS and _NAME.fullmatch(value) is not None


def check_name(value: object, *, path: str | os.PathLike[str] | None = None, row: int | None = None,
               column: str | None = None, what: str = "name") -> str:
    """Return ``value`` if it obeys the name rule, else raise one :class:`InputError` naming file, row, column.

    The one gate for every name that can reach a path: readers call it where a name is read, and every
    writer that builds a file name from data calls it again just before (a name can come from an option).
    """
    if is_safe_name(value):
        return value
    raise _name_error(value, path=path, row=row, column=column, what=what)


def _name_error(value: object, *, path, row, column, what) -> InputError:
    shown = repr(value) if len(str(value)) <= 80 else repr(str(value)[:77] + "...")
    return InputError(f"{what} {shown} is not allowed: use {NAME_RULE} (names become parts of file names)",
                      path=path, row=row, column=column)


def check_name_column(frame: pd.DataFrame, column: str, path: Path | None, *, line=None,
                      problems: Problems | None = None) -> None:
    """Refuse each value of ``column`` that breaks the name rule, naming its line (the first only, raised,
    without ``problems``; when collecting, a blank cell is left to the "empty value" check)."""
    line = csv_line if line is None else line
    if column not in frame.columns:
        return
    bad = ~frame[column].map(is_safe_name).to_numpy(bool)
    if problems is not None:
        bad &= (frame[column].notna() & (frame[column] != "")).to_numpy(bool)

    flag(problems, bad, lambda i: _name_error(frame[column].iloc[i], path=path, row=line(i), column=column, what=column))
