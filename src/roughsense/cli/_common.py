"""Small helpers shared by the command modules: option parsing and progress display."""
from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

from ..errors import ConfigError

T = TypeVar("T")


def parse_float_list(text: str, *, name: str) -> list[float]:
    """Parse "1,2,3" into floats, refusing blanks, non-numbers and non-positive values."""
    values = []
    for part in text.split(","):
        part = part.strip()
        try:
            value = float(part)
        except ValueError:
            raise ConfigError(f"--{name}: {part!r} is not a number") from None
        if not value > 0 or value == float("inf"):
            raise ConfigError(f"--{name}: {part!r} must be positive")
        values.append(value)
    return values


def check_seed(seed: int) -> int:
    """A seed for numpy.random.default_rng: a whole number >= 0 (a negative one is refused by NumPy)."""
    if seed < 0:
        raise ConfigError(f"--seed must be a whole number >= 0, got {seed}")
    return seed


def parse_name_list(text: str) -> list[str]:
    return [p.strip() for p in text.split(",") if p.strip()]


def progress(items: Iterable[T], *, total: int | None = None, description: str = "") -> Iterator[T]:
    """A rich progress bar on an interactive terminal, silence otherwise (logs and CI stay clean)."""
    if not sys.stderr.isatty():
        yield from items
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, transient=True) as bar:
        task = bar.add_task(description, total=total)
        for item in items:
            yield item
            bar.advance(task)
