"""One error family for everything a user can get wrong.

The CLI turns any :class:`RoughsenseError` into a single line on stderr and exit code 2, so every
message must make sense on its own and name the file, row or column it is about.
"""
from __future__ import annotations

import os
from pathlib import Path


def one_line(text: str) -> str:
    """``text`` with line breaks and other control characters escaped: a message quoting a user's cell stays one line."""
    return "".join(ch if ch.isprintable() or ch == " " else repr(ch)[1:-1] for ch in str(text))


class RoughsenseError(Exception):
    """A problem with the user's input, files or options (never a bug in roughsense)."""

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
    """Bad data: an unreadable image, a malformed CSV row, NaN features, an unknown specimen."""


class ConfigError(RoughsenseError):
    """Bad options or parameters: a non-positive px-per-mm, an ROI outside the image, too many components."""


class ModelFileError(RoughsenseError):
    """A model document that is damaged, truncated, of an unknown version, or does not match its input."""


class OutputExistsError(RoughsenseError):
    """Refusing to overwrite something the user made; ``--force`` is the way through."""


class RoughsenseWarning(UserWarning):
    """Something the user should know where the work can still go on (a participant missed a session).

    The CLI prints each as one ``roughsense: warning: ...`` line on stderr.
    """
