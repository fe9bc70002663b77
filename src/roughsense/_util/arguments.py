"""The public calls' arguments, checked at the edge: a wrong one is refused in one line naming it, in Python's words,
before anything deep inside meets it as an AttributeError.

A str (or path) where a list of paths is wanted is one path, never iterated character by character; a str where a
list of names is wanted is one name ("R3", not "R" and "3"). ``n_jobs`` has the CLI's bounds.
"""
from __future__ import annotations

import os
from collections.abc import Iterable

from ..errors import ConfigError
from .checks import short_repr


def path_argument(value, name: str, what: str = "a path"):
    """``value`` if it is a str or os.PathLike; refused otherwise."""
    if isinstance(value, (str, os.PathLike)) and str(value):
        return value
    raise ConfigError(f"{name} must be {what} (str or os.PathLike), got {short_repr(value)}")


def paths_argument(value, name: str) -> list:
    """A list of images: one str/path/array is one image; any other iterable is a list of them."""
    import numpy as np

    if isinstance(value, (str, os.PathLike, np.ndarray)):
        return [value]
    if isinstance(value, (bytes, dict)) or not isinstance(value, Iterable):
        raise ConfigError(f"{name} must be image paths (a list, or one path), got {short_repr(value)}")
    items = list(value)
    for item in items:
        if not isinstance(item, (str, os.PathLike, np.ndarray)):
            raise ConfigError(f"{name} must hold image paths or pixel arrays, got {short_repr(item)}")
    return items


def names_argument(value, name: str) -> list[str]:
    """A list of names: one str is one name."""
    if isinstance(value, str):
        return [value]
    if isinstance(value, (bytes, dict)) or not isinstance(value, Iterable):
        raise ConfigError(f"{name} must be a name or a list of names, got {short_repr(value)}")
    items = list(value)
    if not all(isinstance(item, str) for item in items):
        raise ConfigError(f"{name} must hold names (str), got {short_repr(items)}")
    return items


def jobs_argument(value, name: str = "n_jobs") -> int:
    """A whole number from 1 to the CLI's --jobs limit (``MAX_JOBS_PER_CORE`` per usable core)."""
    from .workers import MAX_JOBS_PER_CORE, usable_cores

    limit = MAX_JOBS_PER_CORE * usable_cores()
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= limit:
        raise ConfigError(f"{name} must be a whole number from 1 to {limit} ({MAX_JOBS_PER_CORE} per usable core), "
                          f"got {short_repr(value)}")
    return int(value)


def callable_argument(value, name: str = "progress"):
    """None or a callable."""
    if value is not None and not callable(value):
        raise ConfigError(f"{name} must be None or a callable like progress(iterable, total=, description=), got "
                          f"{short_repr(value)}")
    return value


def flag_argument(value, name: str) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(f"{name} must be True or False, got {short_repr(value)}")
    return value
