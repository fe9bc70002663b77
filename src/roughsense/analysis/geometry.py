"""Each specimen's land/groove geometry, read from specimens.csv: what "a land/groove geometry left out" holds out.

People feel the groove (Lederman 1974; Klatzky & Lederman 2007), and in the paper's set every rectangular grating is
half land, half groove, so its period stands in for its groove width. A study that varies the land at a fixed period
can hold out every grating of one land/groove geometry together and predict it from the rest: a model that learned
the period, not the groove, shows it there. A rectangular grating's geometry is its land (``ridge_width_mm``, else
``wavelength_mm - groove_width_mm``) as a fraction of its period, rounded to :data:`LAND_FRACTION_DECIMALS`; every
other shape is one geometry of its own (a circle's contact is fixed by its period). The scheme needs two or more
rectangular geometries: with one, it would only repeat the shape left out.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

#: Land fractions are rounded to this many decimals, to a tenth of the period: 0.33 and 0.3 of the period are both
#: "land 0.3", one geometry (a printed land is never exact).
LAND_FRACTION_DECIMALS = 1
#: The specimens.csv columns a rectangular grating's geometry is read from (io/study.py: optional geometry columns).
LAND_COLUMN, GROOVE_COLUMN = "ridge_width_mm", "groove_width_mm"
RECTANGULAR = "rectangular"
#: Land and groove given both may miss the period by this fraction of it (printing and measuring, not a typo).
WIDTHS_TOLERANCE = 0.02


def land_label(fraction: float) -> str:
    """A rectangular geometry's label: ``land 0.3`` is a land of 0.3 of the period (the groove the rest)."""
    return f"land {round(float(fraction), LAND_FRACTION_DECIMALS):g}"


#: The paper's rectangles' geometry: half land, half groove (its claims compare circles with these).
PAPER_GEOMETRY = land_label(0.5)


def land_fractions(specimens: pd.DataFrame) -> pd.Series:
    """Each specimen's land width over its period (NaN where specimens.csv gives no land or groove width strictly
    between 0 and the wavelength); the land column wins where both are given."""
    wavelength = pd.to_numeric(specimens["wavelength_mm"], errors="coerce")

    def fraction(column: str) -> pd.Series:
        width = pd.to_numeric(specimens.get(column, pd.Series(np.nan, index=specimens.index)), errors="coerce")
        return (width / wavelength).where((width > 0) & (width < wavelength))

    return fraction(LAND_COLUMN).fillna(1.0 - fraction(GROOVE_COLUMN))


def specimen_geometries(specimens: pd.DataFrame) -> tuple[dict[str, str], str]:
    """(specimen -> geometry label, "") where a land/groove geometry can be held out, else ({}, the reason why not, in a
    few words: the report's first screen quotes it in a table cell).

    Labels: ``land 0.3`` (a rectangular grating whose land is 0.3 of its period), or the shape for any other.
    """
    shapes = specimens["shape"].astype(str)
    rectangular = shapes == RECTANGULAR
    if not rectangular.any():
        return {}, "no rectangular gratings here"
    fractions = land_fractions(specimens[rectangular]).round(LAND_FRACTION_DECIMALS)
    unknown = specimens.loc[rectangular, "specimen"][fractions.isna()]
    if len(unknown):
        return {}, f"no land width ({LAND_COLUMN}) in specimens.csv for {_named(unknown)}"
    both = land_fractions(specimens[rectangular].drop(columns=GROOVE_COLUMN, errors="ignore")) + \
        (1.0 - land_fractions(specimens[rectangular].drop(columns=LAND_COLUMN, errors="ignore")))
    disagree = specimens.loc[rectangular, "specimen"][(both - 1.0).abs() > WIDTHS_TOLERANCE]
    if len(disagree):
        return {}, f"in specimens.csv, {LAND_COLUMN} + {GROOVE_COLUMN} is not wavelength_mm for {_named(disagree)}"
    labels = shapes.copy()
    labels[rectangular] = [land_label(f) for f in fractions]
    geometries = dict(zip(specimens["specimen"].astype(str), labels))
    distinct = sorted(set(labels[rectangular]))
    if len(distinct) < 2:
        return {}, f"every rectangle here is {distinct[0]} of its period (roughsense protocol recommends others)"
    return geometries, ""


def _named(specimens: pd.Series, shown: int = 1) -> str:
    """The first ``shown`` names, and how many more: a reason that fits a table cell."""
    names = list(map(str, specimens))
    return ", ".join(names[:shown]) + (f" and {len(names) - shown} more" if len(names) > shown else "")
