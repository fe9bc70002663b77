"""Every family's numerics, in the registry's order: the one module that imports the family engines.

It sits above them, and :mod:`roughsense.model.families` (the names, light enough for ``--help``) below them, so
the engines can take their names from the registry without a loop of imports.
"""
from __future__ import annotations

from .families import Family, family
from .peak_law.family import PeakLawFamily
from .pls.family import PLSFamily


def engines() -> tuple:
    """Every family's numerics (:class:`roughsense.model.family.FamilyEngine`), in the registry's order: fresh,
    stateless objects, so a test may append one."""
    return PLSFamily(), PeakLawFamily()


def engine(name: str | Family):
    """The numerics of the family called ``name`` (or of the :class:`Family` given)."""
    wanted = family(name).name
    return next(e for e in engines() if e.name == wanted)
