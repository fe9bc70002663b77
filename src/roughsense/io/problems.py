"""Problems found while reading a study: raised at the first (every reader's default) or collected (``check``).

Each reader takes ``problems=None`` and reports every bad cell through :func:`report` or :func:`flag`. With ``None``
the first one raises, exactly as a reader always did, so ``study`` keeps its message; ``roughsense check`` passes a
:class:`Problems` and gets them all, from the same validators (no second copy of the rules to drift apart).
"""
from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np

from ..errors import InputError, one_line

#: ``check`` lists this many problems, then counts the rest: a file wrong on every row is not a million lines.
MAX_LISTED = 200


class Problems:
    """Every problem reported, the first :attr:`limit` kept in full and the rest counted."""

    def __init__(self, limit: int = MAX_LISTED) -> None:
        self.limit = limit
        self.items: list[InputError] = []
        self.total = 0
        self._whole_rows: set[tuple[str, int]] = set()  # rows wrong as a whole (a field count): their cells mean nothing

    def __len__(self) -> int:
        return self.total

    @property
    def full(self) -> bool:
        return len(self.items) >= self.limit

    def add(self, error: InputError) -> None:
        """Keep ``error``; a cell's problem in a row already wrong as a whole is the same problem, not another."""
        if error.row is not None:
            where = (str(error.path), error.row)
            if error.column is None:
                self._whole_rows.add(where)
            elif where in self._whole_rows:
                return
        self.total += 1
        if not self.full:
            self.items.append(error)

    def lines(self) -> list[str]:
        """One line per problem kept, then ``... and N more`` if any were only counted."""
        lines = [one_line(str(error)) for error in self.items]
        if self.total > len(self.items):
            lines.append(f"... and {self.total - len(self.items)} more")
        return lines


def report(problems: Problems | None, error: InputError) -> None:
    """Raise ``error`` (no collector) or add it to ``problems``."""
    if problems is None:
        raise error
    problems.add(error)


def flag(problems: Problems | None, mask, error_at: Callable[[int], InputError]) -> np.ndarray:
    """Report each row where ``mask`` holds (only the first, raised, without a collector); returns their positions.

    ``error_at(position)`` builds a row's error; past the collector's limit rows are only counted, not built.
    """
    positions = np.flatnonzero(np.asarray(mask, dtype=bool))
    if problems is None:
        if positions.size:
            raise error_at(int(positions[0]))
        return positions
    for k, position in enumerate(positions):
        if problems.full:
            problems.total += positions.size - k
            break
        problems.add(error_at(int(position)))
    return positions


def attempt(problems: Problems | None, read: Callable, /, *args, **kwargs):
    """``read(*args, **kwargs)``; when collecting, a problem that stops it (a file unreadable, a column missing) is
    added and None returned, so ``check`` goes on to the next file."""
    if problems is None:
        return read(*args, **kwargs)
    try:
        return read(*args, **kwargs)
    except InputError as exc:
        problems.add(exc)
        return None


def same_but_case(value: object, known: Iterable[str]) -> str | None:
    """The known name ``value`` equals but for upper/lower case (``r4`` -> ``R4``), else None."""
    if not isinstance(value, str):
        return None
    matches = [name for name in known if isinstance(name, str) and name != value and name.casefold() == value.casefold()]
    return matches[0] if len(matches) == 1 else None
