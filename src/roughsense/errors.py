"""One error family for everything a user can get wrong.

The CLI turns any :class:`RoughsenseError` into a single line on stderr and exit code 2, so every
message must make sense on its own and name the file, row or column it is about.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

#: Longest run of non-blank characters an error line shows: a 100 MB cell or path is quoted by its start.
QUOTE_MAX_CHARS = 200
#: Longest error line: a message quoting many values (or one full of blanks) keeps its start and its end.
LINE_MAX_CHARS = 2000
_LONG_RUN = re.compile(rf"\S{{{QUOTE_MAX_CHARS + 1},}}")


def _cut(text: str, limit: int) -> str:
    """``text`` cut to about ``limit`` characters, saying how long it was (so the user knows what they have)."""
    return text if len(text) <= limit else f"{text[:limit]}...({len(text)} characters)"


def _cap_runs(text: str) -> str:
    """Every run of non-blank characters longer than :data:`QUOTE_MAX_CHARS` cut to its start."""
    return _LONG_RUN.sub(lambda run: _cut(run.group(), QUOTE_MAX_CHARS), text)


def _cap_line(text: str) -> str:
    """The whole line cut to :data:`LINE_MAX_CHARS`: start and end kept (where and what to do), the middle dropped."""
    if len(text) <= LINE_MAX_CHARS:
        return text
    tail = LINE_MAX_CHARS // 4
    return f"{text[:LINE_MAX_CHARS - tail]} ...({len(text) - LINE_MAX_CHARS} characters)... {text[-tail:]}"


def one_line(text: str) -> str:
    """``text`` as one short line: control characters escaped, echoed input capped (:data:`QUOTE_MAX_CHARS`).

    Every error and warning line goes through here, so a message quoting a user's cell stays one line, and a
    100 MB cell costs neither a 100 MB line on stderr nor the memory to escape it character by character.
    """
    capped = _cap_line(_cap_runs(str(text)))
    return _cap_line("".join(ch if ch.isprintable() or ch == " " else repr(ch)[1:-1] for ch in capped))


class RoughsenseError(Exception):
    """A problem with the user's input, files or options (never a bug in roughsense).

    Catch this one class to handle every failure a user can fix; the CLI prints it as one line and exits 2.

    Parameters
    ----------
    message : str
        What is wrong, in words that make sense on their own.
    path : str or os.PathLike, optional
        The file or folder it is about; ``str(error)`` starts with it.
    row : int, optional
        The row of that file.
    column : str, optional
        The column of that file.

    Examples
    --------
    >>> import roughsense as rs
    >>> error = rs.RoughsenseError("not a number: 'abc'", path="ratings.csv", row=3, column="rating")
    >>> print(error)
    ratings.csv, row 3, column 'rating': not a number: 'abc'
    >>> error.row, error.message
    (3, "not a number: 'abc'")
    """

    def __init__(
        self,
        message: str,
        *,
        path: str | os.PathLike[str] | None = None,
        row: int | None = None,
        column: str | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.path = Path(path) if path is not None else None
        self.row = row
        self.column = column

    def __str__(self) -> str:
        where = []
        if self.path is not None:
            where.append(str(self.path))
        if self.row is not None:
            where.append(f"row {self.row}")
        if self.column is not None:
            where.append(f"column '{self.column}'")
        prefix = ", ".join(where)
        return f"{prefix}: {self.message}" if prefix else self.message


class InputError(RoughsenseError):
    """Bad data: an unreadable image, a malformed CSV row, NaN features, an unknown specimen.

    Parameters
    ----------
    message, path, row, column
        As :class:`RoughsenseError`.

    Examples
    --------
    >>> import roughsense as rs
    >>> try:
    ...     rs.read_study("no-such-folder")
    ... except rs.InputError as error:
    ...     print(error)
    no-such-folder: study folder not found
    """


class ConfigError(RoughsenseError):
    """Bad options or parameters: a non-positive px-per-mm, an ROI outside the image, too many components.

    Parameters
    ----------
    message, path, row, column
        As :class:`RoughsenseError`.

    Examples
    --------
    >>> import roughsense as rs
    >>> try:
    ...     rs.SpreadModel(kind="linear").fit([1.0, 2.0], [0.2, 0.4])
    ... except rs.ConfigError as error:
    ...     print(error)
    SpreadModel: kind must be one of weber, constant, got 'linear'
    """


class ModelFileError(RoughsenseError):
    """A model document that is damaged, truncated, of an unknown version, or does not match its input.

    Parameters
    ----------
    message, path, row, column
        As :class:`RoughsenseError`.

    Examples
    --------
    >>> import roughsense as rs
    >>> try:
    ...     rs.load_model("no-such-model.json")
    ... except rs.ModelFileError as error:
    ...     print(error)
    no-such-model.json: model file not found
    """


#: How every refusal to overwrite names the way through, in the command line's words and in Python's: one wording.
PASS_FORCE = "pass --force (force=True in Python)"


class OutputExistsError(RoughsenseError):
    """Refusing to overwrite something the user made; ``--force`` (``force=True``) is the way through.

    Parameters
    ----------
    message, path, row, column
        As :class:`RoughsenseError`.

    Examples
    --------
    >>> from pathlib import Path
    >>> import roughsense as rs
    >>> Path("old-study").mkdir()
    >>> _ = (Path("old-study") / "notes.txt").write_text("mine")
    >>> try:
    ...     rs.StudyWriter("old-study")
    ... except rs.OutputExistsError as error:
    ...     print(error)
    old-study: folder exists and is not empty; pass --force (force=True in Python) to write into it
    """


class RoughsenseWarning(UserWarning):
    """Something the user should know where the work can still go on (a participant missed a session).

    The CLI prints each as one ``roughsense: warning: ...`` line on stderr.
    """
