"""Text for people: counts in words ("1 specimen", "2 specimens", never "1 specimens" or "(s)"), and CSV cells a
spreadsheet will not run as formulas."""
from __future__ import annotations


def counted(n: int, singular: str, plural: str | None = None) -> str:
    """``n`` and the noun in the number that agrees with it (``plural`` defaults to ``singular`` + "s")."""
    return f"{n} {singular if n == 1 else plural or singular + 's'}"


#: What makes a spreadsheet read a cell as a formula (OWASP's list: = + - @, and a tab or CR before them).
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def _is_formula(value: object) -> bool:
    if not isinstance(value, str) or len(value) < 2 or not value.startswith(_FORMULA_START):
        return False  # a lone "-" (a blank in a table) is no formula
    try:
        float(value)  # -0.5 and +3 are numbers, shown as numbers
    except ValueError:
        return True
    return False


def spreadsheet_safe(frame):
    """``frame`` with every text cell a spreadsheet would run as a formula (an image named ``=HYPERLINK(...).png``)
    prefixed with ``'``, which spreadsheets show as text; numbers, and frames with no such cell, are unchanged."""
    safe = frame
    for column in frame.select_dtypes(include=["object", "string"]).columns:
        risky = frame[column].map(_is_formula).astype(bool)
        if risky.any():
            safe = safe.copy() if safe is frame else safe
            safe[column] = frame[column].where(~risky, "'" + frame[column].astype(str))
    return safe
