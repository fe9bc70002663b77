"""Declarative parameter checks: a parameter's constraint is stated once, as data, and checked by one function.

In the spirit of scikit-learn's ``_parameter_constraints``: a class or reader states a table, parameter ->
constraint (:class:`Integer`, :class:`Real`, :class:`Options`, :class:`AnyOf`), and :func:`check_params` (or
:func:`check`, for one value) refuses the first value outside it with a message built from the constraint:
``n_blocks must be a whole number >= 1, got 0``. A boolean is never a number here (TOML's ``true`` is not 1),
numpy scalars are, and the error names the parameter. The same interval objects bound the quantities a study's
files hold (``io.numbers.BOUNDS``), whose parser says which bound a value missed (:meth:`Real.miss`).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
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
    """A value or bound as a message quotes it: an int exactly (a seed's 9223372036854775807), a float with ``:g``
    (never ``np.float64(...)``), anything else as a short repr."""
    if is_whole_number(value):
        text = str(int(value))  # Python's own int() of a 400-digit JSON number: still one short line
        return text if len(text) <= 40 else f"{text[:20]}...({len(text)} digits)"
    return f"{value:g}" if is_number(value) else short_repr(value)


def given(value: object) -> str:
    """A value a user gave, as the "got ..." of a message: like :func:`shown`, but a float keeps its decimal point
    (``repetitions = 3.0`` is refused as "got 3.0", never the self-contradicting "got 3")."""
    if is_number(value) and not is_whole_number(value):
        return short_repr(float(value))
    return shown(value)


class Constraint(Protocol):
    def accepts(self, value: object) -> bool: ...

    def describe(self) -> str: ...

    def cast(self, value: object) -> object: ...


def _bounds_text(low, high, low_open: bool = False, high_open: bool = False) -> str:
    if low is not None and high is not None and not (low_open or high_open):
        return f" from {shown(low)} to {shown(high)}"
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {shown(low)}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {shown(high)}")
    return (" " + " and ".join(parts)) if parts else ""


def _miss(number, low, high, low_open: bool, high_open: bool) -> str | None:
    """Which bound ``number`` misses, in the words a reader of a file sees (``must be positive``), or None."""
    if low is not None and (number <= low if low_open else number < low):
        if number <= 0 <= low and (low > 0 or low_open):  # the usual slip: say it plainly
            return "must be positive"
        return f"must be {'above' if low_open else 'at least'} {shown(low)}"
    if high is not None and (number >= high if high_open else number > high):
        return f"must be {'below' if high_open else 'at most'} {shown(high)}"
    return None


@dataclass(frozen=True)
class Integer:
    """A whole number (an int type, not a bool) within ``[low, high]``; either bound may be None."""

    low: int | None = None
    high: int | None = None

    def accepts(self, value: object) -> bool:
        return is_whole_number(value) and self.miss(value) is None

    def miss(self, number: float | int) -> str | None:
        """The bound a number misses (``must be at least 1``), or None; wholeness is the caller's to say."""
        return _miss(number, self.low, self.high, False, False)

    def describe(self) -> str:
        return "a whole number" + _bounds_text(self.low, self.high)

    def cast(self, value: object) -> int:
        return int(value)


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
        return self.miss(value) is None

    def miss(self, number: float | int) -> str | None:
        """The bound a finite number misses (``must be positive``, ``must be at most 100``), or None."""
        return _miss(number, self.low, self.high, self.low_open, self.high_open)

    def describe(self) -> str:
        return "a finite number" + _bounds_text(self.low, self.high, self.low_open, self.high_open)

    def cast(self, value: object) -> float:
        return float(value)


@dataclass(frozen=True)
class Options:
    """One of a fixed set of strings (compared exactly; normalise case before checking if the caller allows it)."""

    values: tuple[str, ...]

    def accepts(self, value: object) -> bool:
        return isinstance(value, str) and value in self.values

    def describe(self) -> str:
        return "one of " + ", ".join(repr(v) for v in self.values)

    def cast(self, value: object) -> object:
        return value


@dataclass(frozen=True)
class AnyOf:
    """Any of several constraints; ``None`` among them accepts None (scikit-learn's ``[Interval(...), None]``)."""

    options: tuple[Constraint | None, ...]

    def __init__(self, *options: Constraint | None) -> None:
        object.__setattr__(self, "options", options)

    def _accepting(self, value: object) -> Constraint | None:
        return next((c for c in self.options if c is not None and c.accepts(value)), None)

    def accepts(self, value: object) -> bool:
        return (value is None and None in self.options) or self._accepting(value) is not None

    def describe(self) -> str:
        return " or ".join("None" if c is None else c.describe() for c in self.options)

    def cast(self, value: object) -> object:
        return None if value is None else self._accepting(value).cast(value)


@dataclass(frozen=True)
class Described:
    """A constraint with a message's own wording (units, what the value is for): ``a positive number of mm``."""

    constraint: Constraint
    must: str

    def accepts(self, value: object) -> bool:
        return self.constraint.accepts(value)

    def describe(self) -> str:
        return self.must

    def cast(self, value: object) -> object:
        return self.constraint.cast(value)


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
        raise error(f"{name} must be {must or constraint.describe()}, got {given(value)}")
    return constraint.cast(value)


def check_params(values: Mapping[str, object], constraints: Mapping[str, Constraint], *,
                 error: type[RoughsenseError] = ConfigError, names: Mapping[str, str] | None = None) -> dict:
    """Every value of ``values`` that the table ``constraints`` names, checked in the table's order and cast.

    The first value outside its constraint raises :func:`check`'s message; ``names`` maps a parameter to the name
    a user knows it by (an option's ``--seed``).
    """
    names = names or {}
    return {key: check(values[key], constraint, name=names.get(key, key), error=error)
            for key, constraint in constraints.items() if key in values}
