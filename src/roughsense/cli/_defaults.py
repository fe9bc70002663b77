"""The CLI's old copy of the defaults, now only a pointer to their one home, :mod:`roughsense.defaults`.

cli/study_report.py still imports from here until its own package rewires it; the lead deletes this module then.
"""
from __future__ import annotations

from ..defaults import MAX_PERMUTATIONS  # re-exported for one release

__all__ = ["MAX_PERMUTATIONS"]
