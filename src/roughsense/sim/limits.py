"""What the twin can compute: the bounds of a simulated design, stated once for ``simulate`` and ``explore``.

Each bound keeps a design's work and numbers finite, and says why it is where it is. Lengths are checked against the
contact solver's grid (``contact.GRID_STEP_MM``) and the specimen's length: a period finer than a few grid steps is
aliased (and a fingerprint period of 1e-6 mm asks for 5e7 ridge height errors per mount), a period longer than the
specimen is no grating and grows the contact domain (1000 mm is a minute per trial). The functions return the
problem in words (or None) so that each caller names where the value came from: an option or a sweep file's key.
"""
from __future__ import annotations

import math

from .contact import GRID_STEP_MM
from .specimens import SPECIMEN_LENGTH_MM, Specimen

#: Shortest specimen wavelength or pad ridge period: four points of the contact grid per period.
MIN_PERIOD_MM = 4 * GRID_STEP_MM
#: Longest: the specimen's own length (a longer period is no grating, and the contact domain grows with it).
MAX_PERIOD_MM = SPECIMEN_LENGTH_MM
#: Deepest relief (groove depth, amplitude, rms height, pad ridge height): ten times the paper's 1 mm grooves.
MAX_RELIEF_MM = 10.0
#: The pad's Young's modulus: a 1 kPa gel to a 1 GPa plastic (the paper's PVC gel: 0.17 MPa); outside, the
#: contact solver's numbers overflow or the pad never touches the grooves.
PAD_MODULUS_PA = (1e3, 1e9)
#: Largest simulated panel, participants x sessions (the paper: 10 x 3 = 30). The panel's calibration draws 4000
#: panels of that size per rated specimen: 2000 peaks near 200 MB and takes a few seconds; 1000 x 100 took 6.5 GB.
MAX_PANEL_SIZE = 2000


def panel_problem(participants: int, sessions: int, names: tuple[str, str] = ("participants", "sessions")) -> str | None:
    """Why the twin will not simulate a panel this large, or None."""
    if participants * sessions > MAX_PANEL_SIZE:
        return (f"{names[0]} x {names[1]} = {participants} x {sessions} = {participants * sessions}, above the "
                f"simulated panel's limit of {MAX_PANEL_SIZE}")
    return None


def _outside(value: float, low: float, high: float, *, low_open: bool = False) -> bool:
    if not math.isfinite(value):
        return True
    return (value <= low if low_open else value < low) or value > high


def period_problem(value_mm: float, what: str) -> str | None:
    """Why ``value_mm`` cannot be a period the twin resolves, or None."""
    if _outside(value_mm, MIN_PERIOD_MM, MAX_PERIOD_MM):
        return (f"{what} must be from {MIN_PERIOD_MM:g} to {MAX_PERIOD_MM:g} mm (4 points of the contact grid per "
                f"period; at most the specimen's length), got {value_mm:g}")
    return None


def relief_problem(value_mm: float, what: str) -> str | None:
    if _outside(value_mm, 0.0, MAX_RELIEF_MM, low_open=True):
        return f"{what} must be above 0 and at most {MAX_RELIEF_MM:g} mm, got {value_mm:g}"
    return None


def specimen_problem(specimen: Specimen) -> str | None:
    """Why the twin cannot simulate ``specimen`` (its wavelength or relief out of bounds), or None."""
    name = f"specimen {specimen.name!r}:"
    problems = [period_problem(specimen.wavelength_mm, f"{name} the wavelength")]
    for what, value in (("groove depth", specimen.groove_depth_mm), ("amplitude", specimen.amplitude_mm)):
        if not math.isnan(value):
            problems.append(relief_problem(value, f"{name} the {what}"))
    return next((p for p in problems if p is not None), None)


def pad_problem(*, period_mm: float | None = None, ridge_height_mm: float | None = None,
                modulus_pa: float | None = None, names: tuple[str, str, str] = ("fingerprint period",
                                                                               "ridge height", "pad modulus")) -> str | None:
    """Why a pad design is out of the twin's bounds (each value optional; ``names`` label them), or None."""
    if period_mm is not None and (problem := period_problem(period_mm, names[0])):
        return problem
    if ridge_height_mm is not None and (problem := relief_problem(ridge_height_mm, names[1])):
        return problem
    if modulus_pa is not None and _outside(modulus_pa, *PAD_MODULUS_PA):
        low, high = PAD_MODULUS_PA
        return f"{names[2]} must be from {low / 1e6:g} to {high / 1e6:g} MPa, got {modulus_pa / 1e6:g}"
    return None
