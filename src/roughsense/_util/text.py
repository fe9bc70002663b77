"""Counts in words: "1 specimen", "2 specimens", so no message a user reads says "1 specimens" or hedges "(s)"."""
from __future__ import annotations


def counted(n: int, singular: str, plural: str | None = None) -> str:
    """``n`` and the noun in the number that agrees with it (``plural`` defaults to ``singular`` + "s")."""
    return f"{n} {singular if n == 1 else plural or singular + 's'}"
