"""The groove model's applicability domain: the land and groove widths it was trained on, each on its own axis.

A half-and-half grating and its mirror (land 2 / groove 1 mm against land 1 / groove 2 mm) share one duty cycle
about 1/2 and one period; a domain on the duty or the period could not tell them apart. This one holds the two
widths apart: each axis (log groove width, log land width, means over forces) has its own trained range (from the
lowest to the highest trained specimen's median over its presses) and its own margin, a few of its presses' robust
scatter about their specimen (:data:`PRESS_SDS`; at least :data:`MIN_LOG_MARGIN`), so a geometry outside training
on either axis is flagged while a press of a trained geometry read with ordinary noise is not. A press whose width
cannot be read is flagged too (its term was put at the training mean: its prediction says nothing of it).
"""
from __future__ import annotations

import math

import numpy as np

#: The two axes, as terms (model/groove/terms.py), and what a reason calls them.
AXES = ("log_groove_mm", "log_land_mm")
AXIS_WORDS = ("groove width", "land width")
#: The margin is this many robust press scatters (a press of a trained geometry reads within it nearly always) ...
PRESS_SDS = 3.0
#: ... and at least this much in log width (5 %: the reading's own precision on a clean line).
MIN_LOG_MARGIN = 0.05
_MAD_TO_SD = 1.4826


def axis_values(terms: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """Each row's values on the domain's axes (n, 2): log groove and log land width (NaN: unreadable)."""
    return np.column_stack([terms[:, names.index(axis)] for axis in AXES])


def trained_box(values: np.ndarray, codes: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The domain of the training ``rows`` (a mask): low and high (2,) over the specimens' medians, and the margin
    (2,) of each axis."""
    low, high, margin = np.full(2, -np.inf), np.full(2, np.inf), np.full(2, MIN_LOG_MARGIN)
    for axis in range(2):
        readable = rows & np.isfinite(values[:, axis])
        if not readable.any():
            continue
        mine, owners = values[readable, axis], codes[readable]
        medians = {s: float(np.median(mine[owners == s])) for s in np.unique(owners)}
        deviations = mine - np.array([medians[s] for s in owners])
        low[axis], high[axis] = min(medians.values()), max(medians.values())
        margin[axis] = max(MIN_LOG_MARGIN, PRESS_SDS * _MAD_TO_SD * float(np.median(np.abs(deviations))))
    return low, high, margin


def domain_reasons(values: np.ndarray, low: np.ndarray, high: np.ndarray, margin: np.ndarray) -> list[str]:
    """Per row, what lies outside the trained widths, in a user's words ('' where nothing does)."""
    reasons = []
    for row in np.asarray(values, dtype=np.float64):
        words = []
        for axis, value in enumerate(row):
            name = AXIS_WORDS[axis]
            if not math.isfinite(value):
                words.append(f"{name} unreadable in this press")
            elif not low[axis] - margin[axis] <= value <= high[axis] + margin[axis]:
                words.append(f"{name} {_mm(math.exp(value))} mm outside the trained "
                             f"{math.exp(low[axis]):.2f}-{math.exp(high[axis]):.2f} mm")
        reasons.append("; ".join(words))
    return reasons


def _mm(width: float) -> str:
    """A width as a reason shows it: two decimals, or three significant digits beyond a metre or below 0.01 mm."""
    return f"{width:.2f}" if 0.01 <= width < 1000 else f"{width:.3g}"


def held_out_flags(values: np.ndarray, specimens: np.ndarray, folds: np.ndarray) -> np.ndarray:
    """Whether each row lies outside the domain trained without its fold (``folds``: one label per row, each label a
    fold left out): the flag a user would have seen for a geometry the model never saw."""
    codes = np.unique(np.asarray(specimens).astype(str), return_inverse=True)[1].ravel()
    fold_of = np.unique(np.asarray(folds), return_inverse=True)[1].ravel()
    flags = np.zeros(len(values), dtype=bool)
    for fold in range(int(fold_of.max()) + 1):
        held = fold_of == fold
        box = trained_box(values, codes, ~held)
        flags[held] = [bool(r) for r in domain_reasons(values[held], *box)]
    return flags

