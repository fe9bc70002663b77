"""Which surfaces a study's evidence covers, in a user's words, from its own specimens.

"A surface you never trained on" promises more than a study can hold: a model judged on the paper's 14 gratings,
whose rectangles are all half land and half groove, says nothing about a rectangle of 2 mm land and 0.5 mm groove
(its period stands in for its groove width there). So wherever the report tells a user which model to use for a new
surface, it names the surfaces its evidence covers: the rated specimens' shapes, their periods and, for rectangles,
their land and groove widths, read from specimens.csv (never a fixed sentence), and what lies outside them.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

#: A rectangle's land share of its period within this of 1/2 is "half land, half groove".
HALF_TOLERANCE = 0.02


def _mm(value: float) -> str:
    return f"{value:g}"


def _periods(wavelengths: pd.Series) -> str:
    """'of 7 periods from 2 to 5 mm', 'of period 3 mm' or 'of unstated period'."""
    known = np.unique(pd.to_numeric(wavelengths, errors="coerce").dropna().to_numpy(dtype=float))
    if known.size == 0:
        return "of unstated period"
    if known.size == 1:
        return f"of period {_mm(known[0])} mm"
    return f"of {known.size} periods from {_mm(known[0])} to {_mm(known[-1])} mm"


def _lands(rectangles: pd.DataFrame) -> tuple[str, bool]:
    """How the rectangles share their period between land and groove, and whether all are half and half."""
    if "ridge_width_mm" not in rectangles:
        return "the rectangles' land and groove widths not recorded", False
    share = (pd.to_numeric(rectangles["ridge_width_mm"], errors="coerce")
             / pd.to_numeric(rectangles["wavelength_mm"], errors="coerce")).dropna()
    if share.empty:
        return "the rectangles' land and groove widths not recorded", False
    if (abs(share - 0.5) <= HALF_TOLERANCE).all():
        return "the rectangles half land, half groove", True
    return f"the rectangles' land {float(share.min()):.0%}-{float(share.max()):.0%} of the period", False


def evidence_words(specimens: pd.DataFrame, rated) -> str:
    """The surfaces the evidence covers, said after "surfaces like": the ``rated`` specimens of ``specimens``
    (specimens.csv), their shapes (those of one set of periods together) with the periods and, for rectangles,
    their land share; then what it does not cover ('' without any)."""
    table = specimens[specimens["specimen"].isin(set(map(str, rated)))]
    if table.empty:
        return ""
    by_periods: dict[str, list[str]] = {}
    for shape, group in table.groupby("shape", sort=False):
        by_periods.setdefault(_periods(group["wavelength_mm"]), []).append(str(shape))
    kinds = "; ".join(f"{' and '.join(shapes)} gratings {periods}" for periods, shapes in by_periods.items())
    rectangles = table[table["shape"] == "rectangular"]
    lands, half = _lands(rectangles) if len(rectangles) else ("", False)
    beyond = "other land and groove widths, shapes or periods" if half else "other shapes or periods"
    return f"the study's {len(table)} specimens, {kinds}{f' ({lands})' if lands else ''}, not {beyond}"
