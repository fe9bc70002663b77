"""The one number parser: every CSV cell, TOML value and command-line option that holds a number is read here.

Python's ``float()`` reads ``1_0`` as 10 and ``١`` (an Arabic-Indic one) as 1, and takes ``inf`` and ``nan``;
pandas accepts other spellings again. A study must mean the same to every command, so every reader calls
:func:`parse_number`: ASCII digits with an optional sign, decimal point and exponent (``2``, ``-0.5``, ``.5``,
``1e-3``), surrounding spaces ignored, nothing else -- no digit separators, no other scripts' digits, no hex,
no ``inf``/``nan``. The value must then be finite and within its quantity's :data:`BOUNDS`, stated once here so
that every computation downstream (a geometric mean, an SD, a reciprocal, a prediction) stays finite.

No numpy here: the command-line option type imports this module while parsing ``--help``-light commands.
"""
from __future__ import annotations

import math
import re

from .._util.checks import SEED, Integer, Real, short_repr, shown

# The grammar's fragments, the one spelling of each part of a number (``[0-9]``, not ``\d``: with ``re.ASCII``
# or without it, no other script's digits). Every number pattern of roughsense is built from them.
SIGN = r"[+-]"
#: Digits with an optional point and fraction, or a point and digits (``2``, ``2.``, ``2.5``, ``.5``).
UNSIGNED_DECIMAL = r"(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)"
EXPONENT = r"(?:[eE][+-]?[0-9]+)"
_NUMBER = rf"{SIGN}?{UNSIGNED_DECIMAL}{EXPONENT}?"

#: The accepted spelling (``re.ASCII``).
NUMBER = re.compile(_NUMBER, re.ASCII)
_WHOLE = re.compile(rf"{SIGN}?[0-9]+", re.ASCII)
#: A whole number written with a leading zero (``0104``): no count is written so, but a decimal comma in a
#: comma-separated file leaves one (``2,0104`` split into ``2`` and ``0104``).
_LEADING_ZERO = re.compile(rf"{SIGN}?0[0-9]", re.ASCII)
#: A decimal comma (``2,5``, ``-,5``, ``1,5e3``): a digit must follow it.
COMMA_NUMBER = re.compile(rf"{SIGN}?[0-9]*,[0-9]+{EXPONENT}?", re.ASCII)
#: A decimal point with a digit after it (``2.5``, ``.5``; not ``2`` or ``2.``): what tells a file's decimal mark.
POINT_NUMBER = re.compile(rf"{SIGN}?[0-9]*\.[0-9]+{EXPONENT}?", re.ASCII)
#: A number followed by a unit or symbol (``2 N``, ``5mm``, ``3%``); letters of any script, so not ``re.ASCII``.
NUMBER_WITH_UNIT = re.compile(rf"({_NUMBER})\s*([^\W\d_]|[%\u00b0\u00b5]).*")
#: Whole numbers written with a point or an exponent are exact up to here (2**53); larger ones need digits only.
_EXACT_WHOLE = 2.0**53
_LARGEST_FLOAT = 1.7976931348623157e308


class NumberError(ValueError):
    """A value that is not an accepted number, or is out of its bounds; the caller adds where it was read."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


#: Every bounded quantity a user writes, with why its bounds are where they are: an interval of the one constraint
#: vocabulary (``_util.checks``). Readers name a key of this table; a bound defined elsewhere (the protocol's force
#: limit) is quoted from here, never restated.
BOUNDS: dict[str, Real | Integer] = {
    # A magnitude estimate is a ratio to the reference (1.0): a million times rougher or smoother is no
    # estimate, and within 1e-6..1e6 every gmean, SD and reciprocal of a panel's ratings is finite.
    "rating": Real(1e-6, 1e6),
    # A fingertip presses with a few newtons (the paper: 1-3 N); 100 N on a specimen is about the pad's modulus.
    "force_n": Real(0.0, 100.0, low_open=True),
    # The paper's 10 repetitions; the limit bounds the work a manifest or an option can ask for.
    "repetition": Integer(0, 10_000),
    "contact_fraction": Real(0.0, 1.0),
    # Specimen wavelengths are millimetres (the paper: 2-5 mm); 1 um to 1 m covers every macroscopic texture.
    "wavelength_mm": Real(1e-3, 1e3),
    # Camera scale: 1 px per 10 cm up to 10 nm per px (the paper: 34.9 px/mm).
    "px_per_mm": Real(1e-2, 1e5),
    # Seeds are stored as signed 64-bit integers (see _util.checks.MAX_SEED).
    "seed": SEED,
    # A pad's ridge period: 1 um (finer is no ridge a camera sees) to 100 mm (coarser than any specimen).
    "ridge_period_mm": Real(1e-3, 100.0),
}
#: What a quantity's messages start with, where a bare "must be positive" would not say what was wrong.
NOUNS = {"rating": "a magnitude estimate"}


def spelling_hint(text: str) -> str:
    """What to write instead of a cell that is almost a number (`` (drop the unit: write 2.01)``), or ``""``."""
    text = text.strip()
    if "_" in text and NUMBER.fullmatch(text.replace("_", "")):
        return f" (no '_' between digits: write {text.replace('_', '')})"
    if any(ch.isdigit() and not ch.isascii() for ch in text):
        return " (write the digits 0-9)"
    if COMMA_NUMBER.fullmatch(text):
        return f" (a decimal comma: write {text.replace(',', '.')})"
    unit = NUMBER_WITH_UNIT.fullmatch(text)
    if unit is not None and not text.lower().startswith(("0x", "-0x", "+0x")):
        return f" (drop the unit: write {unit.group(1)})"
    return ""


def _from_text(text: str, whole: bool) -> float | int:
    stripped = text.strip(" \t")
    if not NUMBER.fullmatch(stripped):
        lowered = stripped.lower().lstrip("+-")
        if lowered in ("inf", "infinity", "nan"):
            raise NumberError(f"not a finite number: {short_repr(text)}")
        raise NumberError(f"not a number: {short_repr(text)}{spelling_hint(stripped)}")
    if whole and _LEADING_ZERO.match(stripped):
        plain = stripped.lstrip("+-").lstrip("0") or "0"
        raise NumberError(f"not a number: {short_repr(text)} (a whole number with a leading zero: write {plain}; "
                          "or a decimal comma split a number here?)")
    if whole and _WHOLE.fullmatch(stripped):
        return int(stripped)  # exact, however many digits (a seed)
    value = float(stripped)
    if not math.isfinite(value):
        raise NumberError(f"not a finite number: {short_repr(text)}")
    return value


def parse_number(value: object, *, quantity: str = "", low: float | None = None, high: float | None = None,
                 low_open: bool = False, whole: bool = False) -> float | int:
    """``value`` (text as written, or a number a TOML or JSON parser made) as a checked float (int if ``whole``).

    ``quantity`` names a row of :data:`BOUNDS` whose range applies unless ``low``/``high`` are given. Raises
    :class:`NumberError` with one of the messages every reader shows: ``not a number: '1_0' (...)``, ``not a
    finite number: 'inf'``, ``must be positive, got 0``, ``must be at most 100, got 1e308``.
    """
    bounds = BOUNDS.get(quantity, Real())
    whole = whole or isinstance(bounds, Integer)
    if low is not None or high is not None or low_open:
        bounds = Real(low, high, low_open)
    if isinstance(value, str):
        number = _from_text(value, whole)
    elif isinstance(value, (int, float)) and not isinstance(value, bool) or _is_numpy_number(value):
        number = value if isinstance(value, int) else float(value)
        if isinstance(number, int) and abs(number) > _LARGEST_FLOAT:
            raise NumberError(f"not a finite number: {short_repr(number)}")
        if not math.isfinite(number):
            raise NumberError(f"not a finite number: {number}")
    else:
        raise NumberError(f"not a number: {short_repr(value)}")
    return _within(number, bounds, whole, NOUNS.get(quantity, ""), value)


def _is_numpy_number(value: object) -> bool:
    kind = type(value).__module__ == "numpy" and getattr(value, "dtype", None)
    return bool(kind) and kind.kind in "iuf"


def _within(number: float | int, bounds: Real | Integer, whole: bool, noun: str, written: object) -> float | int:
    """``number`` if in ``bounds`` (and whole, if asked); else the one message of each kind of miss."""
    lead = f"{noun} " if noun else ""
    if whole and number != math.floor(number):
        raise NumberError(f"{lead}must be a whole number, got {shown(number)}")
    problem = bounds.miss(number)
    if problem is not None:
        raise NumberError(f"{lead}{problem}, got {shown(number)}")
    if whole:
        if isinstance(number, float) and abs(number) > _EXACT_WHOLE:
            raise NumberError(f"{lead}must be written with digits only above 2**53, got {short_repr(written)}")
        return int(number)
    return float(number)


# TOML has number spellings of its own (``1_000``, ``0x10``, ``0o7``, ``0b1``, ``inf``, ``nan``) that its parser turns into
# numbers before any reader of ours sees the text; a study.toml or sweep file is held to the CSV's spellings instead.
# tomllib keeps no spelling, so the document it accepted is walked again here, value by value: keys, table headers,
# strings (escapes and multi-line ones included) and comments are stepped over by TOML's own grammar, never matched
# with a pattern, so ``\"""`` inside a string, ``1_000`` in a name or a key named ``inf`` is never taken for a number.
_BARE_END = frozenset(",]}#\n\r\t ")


def _foreign(token: str) -> bool:
    """A TOML number token that no CSV cell may use: digit groups, a base prefix, inf or nan."""
    bare = token.lstrip("+-")
    return "_" in bare or bare[:2] in ("0x", "0o", "0b") or bare in ("inf", "nan")


def _string_end(text: str, pos: int) -> int:
    """Where the TOML string starting at ``pos`` ends (past its closing quote); the text is valid TOML."""
    quote = text[pos]
    if text.startswith(quote * 3, pos):
        cursor = pos + 3
        while True:
            if quote == '"' and text[cursor] == "\\":
                cursor += 2  # an escape: an escaped quote never closes the string
                continue
            if text.startswith(quote * 3, cursor):
                run = len(text[cursor:cursor + 5]) - len(text[cursor:cursor + 5].lstrip(quote))
                return cursor + run  # up to two quotes before the delimiter belong to the string
            cursor += 1
    cursor = pos + 1
    while text[cursor] != quote:
        cursor += 2 if quote == '"' and text[cursor] == "\\" else 1
    return cursor + 1


def _skip_blank(text: str, pos: int, *, lines: bool = True) -> int:
    """Past spaces, tabs, comments and (with ``lines``) newlines."""
    while pos < len(text):
        if text[pos] == "#":
            end = text.find("\n", pos)
            pos = len(text) if end < 0 else end
        elif text[pos] in " \t" or (lines and text[pos] in "\r\n"):
            pos += 1
        else:
            break
    return pos


def _key_end(text: str, pos: int, stop: str) -> int:
    """Past a (dotted, maybe quoted) key, at the ``stop`` character that follows it (``=`` or ``]``)."""
    while text[pos] != stop:
        pos = _string_end(text, pos) if text[pos] in "\"'" else pos + 1
    return pos


def _value_tokens(text: str, pos: int, found: list[tuple[int, str]]) -> int:
    """Walk one value at ``pos``, adding each bare token (a number, bool or date) to ``found``; returns its end."""
    pos = _skip_blank(text, pos)
    if text[pos] in "\"'":
        return _string_end(text, pos)
    if text[pos] in "[{":
        close, pos = "]" if text[pos] == "[" else "}", pos + 1
        while True:
            pos = _skip_blank(text, pos)
            if text[pos] == close:
                return pos + 1
            if text[pos] == ",":
                pos += 1
                continue
            if close == "}":
                pos = _key_end(text, pos, "=") + 1
            pos = _value_tokens(text, pos, found)
    end = pos
    while end < len(text) and text[end] not in _BARE_END:
        end += 1
    if text[end:end + 1] == " " and re.fullmatch(r"\d{4}-\d\d-\d\d", text[pos:end]):  # a date, a space, a time
        end += 1
        while end < len(text) and text[end] not in _BARE_END:
            end += 1
    found.append((pos, text[pos:end]))
    return end


def _bare_values(text: str) -> list[tuple[int, str]]:
    """(offset, spelling) of every bare value (number, bool, date) of a TOML text that tomllib accepted."""
    found: list[tuple[int, str]] = []
    pos = _skip_blank(text, 0)
    while pos < len(text):
        if text[pos] == "[":  # a table header: [a."b.c"] or [[a]]
            pos = _key_end(text, pos + 1, "]") + 1
            pos += text[pos] == "]"
        else:
            pos = _value_tokens(text, _key_end(text, pos, "=") + 1, found)
        pos = _skip_blank(text, pos)
    return found


def toml_spelling_problem(text: str) -> str | None:
    """The first number in a TOML text written in a spelling a CSV cell may not use, as a one-line problem, or None.

    ``text`` must be a document tomllib accepted (the caller parses first): the walk relies on its grammar.
    """
    match = next(((pos, token) for pos, token in _bare_values(text) if _foreign(token)), None)
    if match is None:
        return None
    line = text.count("\n", 0, match[0]) + 1
    token = match[1]
    hint = spelling_hint(token) or " (write plain digits 0-9, a point and an optional exponent)"
    return f"line {line}: {token!r} is not a number as roughsense reads one{hint}"
