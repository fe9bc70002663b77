"""A fingerprint of the code a cell's numbers depend on: the twin and the analysis that a cell runs.

It is part of every cell's id, so results computed by another version are never mistaken for finished cells, and a
worker whose roughsense differs from the client's refuses the cell instead of mixing versions in one dataset.
"""
from __future__ import annotations

from .._util.fingerprint import code_fingerprint as _fingerprint

#: Where a cell's computation starts; everything it imports is covered (explore/cell.py reaches sim and analysis).
ENTRY_POINTS = ("roughsense.explore.cell",)
DATA_PACKAGES = ("roughsense.data.paper",)


def code_fingerprint() -> str:
    return _fingerprint(*ENTRY_POINTS, data_packages=DATA_PACKAGES)
