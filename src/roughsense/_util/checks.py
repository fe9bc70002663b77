"""Declarative parameter checks: a parameter's constraint is stated once, as data, and checked by one function.

In the spirit of scikit-learn's parameter constraints: ``check(value, Integer(1, 100), name="--repetitions")``
instead of a hand-written ``isinstance(x, bool) or not isinstance(x, int) or ...`` at every place a count is read.
A boolean is never a number here (TOML's ``true`` is not 1), numpy scalars are, and the error names the parameter.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..errors import ConfigError, RoughsenseError


def is_number(value: object) -> bool:
    """A real number that is not a boolean (TOML's ``true`` is not 1 here)."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def is_whole_number(value: object) -> bool:
    """An integer type (Python or numpy), not a boolean and not a float that happens to be whole."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def short_repr(value: object, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters: an error line quoting user input stays short."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def shown(value: object) -> str:
    """A value as an error message quotes it: numbers with ``:g`` (never ``np.float64(...)``), the rest as repr."""
    return f"{value:g}" if is_number(value) else short_repr(value)


class Constraint(Protocol):
    def accepts(self, value: object) -> bool: ...

    def describe(self) -> str: ...


def _bounds_text(low, high, low_open: bool = False, high_open: bool = False) -> str:
    if low is not None and high is not None and not (low_open or high_open):
        return f" from {low:g} to {high:g}"
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {high:g}")
    return (" " + " and ".join(parts)) if parts else ""


@dataclass(frozen=True)
class Integer:
    """A whole number (an int type, not a bool) within ``[low, high]``; either bound may be None."""

    low: int | None = None
    high: int | None = None

    def accepts(self, value: object) -> bool:
        return (is_whole_number(value) and (self.low is None or value >= self.low)
                and (self.high is None or value <= self.high))

    def describe(self) -> str:
        return "a whole number" + _bounds_text(self.low, self.high)


@dataclass(frozen=True)
class Real:
    """A finite real number (not a bool) within the bounds; ``low_open``/``high_open`` exclude a bound."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False

    def accepts(self, value: object) -> bool:
        try:  # a 400-digit JSON integer is a number that no float holds: refused, not an OverflowError
            if not is_number(value) or not math.isfinite(value):
                return False
        except OverflowError:
            return False
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return False
        return self.high is None or (value < self.high if self.high_open else value <= self.high)

    def describe(self) -> str:
        return "a finite number" + _bounds_text(self.low, self.high, self.low_open, self.high_open)


@dataclass(frozen=True)
class Options:
    """One of a fixed set of strings (compared exactly; normalise case before checking if the caller allows it)."""

    values: tuple[str, ...]

    def accepts(self, value: object) -> bool:
        return isinstance(value, str) and value in self.values

    def describe(self) -> str:
        return "one of " + ", ".join(repr(v) for v in self.values)


POSITIVE = Real(0.0, low_open=True)
POSITIVE_INT = Integer(1)
#: The largest seed: results store it as a signed 64-bit integer (Parquet, pandas), so a larger one would fail
#: only after the work it seeded. Every reader of a seed (options, sweep files, specs) bounds it here.
MAX_SEED = 2**63 - 1
SEED = Integer(0, MAX_SEED)


def check(value, constraint: Constraint, *, name: str, error: type[RoughsenseError] = ConfigError, must: str | None = None):
    """``value`` if ``constraint`` accepts it (ints as ``int``, reals as ``float``); else one ``error`` naming ``name``.

    ``must`` replaces the constraint's own wording where a message says more (units, what the value is for).
    """
    if not constraint.accepts(value):
        raise error(f"{name} must be {must or constraint.describe()}, got {shown(value)}")
    if isinstance(constraint, Integer):
        return int(value)
    if isinstance(constraint, Real):
        return float(value)
    return value
