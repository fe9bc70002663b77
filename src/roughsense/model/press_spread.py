"""How far a surface read from few presses strays from its reading on many: the flag margins of the law's domain.

The law's domain is fitted on surfaces: each training surface's period, peak strength, shape and clarity are read
on the mean spectrum of all its presses (ten in the built-in study). A surface read from fewer presses (one press
alone at worst) reads them with more scatter: the bench's mounts magnify by a few percent each, a press's second
harmonic is read on one line's noise, and a fingerprint press can lose its grating at low force. A range fitted on
ten-press means and applied to one press therefore flags the training presses themselves.

The scatter is measured on the training presses: each press read alone against its surface's reading. Its robust
SD (median absolute deviation about the surface's reading / 0.6745) ignores the presses that read another peak
altogether (a shading hump, a ridge sideband): those are what reading a surface's presses together exists to
override, and a press read alone that shows them *should* be flagged. On the twin a surface of k presses scatters
as 1/sqrt(k) (3-press subsets: about 0.55 of one press's robust SD, seeds 0-2), so a row whose surface has k
presses is flagged only beyond ``PRESS_Z * spread / sqrt(k)`` of the range, or the surface margins
(:func:`~roughsense.model.peak_law.domain_margins`), whichever is wider. Only the flag widens: a prediction is still
held at the surface domain, since a press's scatter is noise about a trained surface, not a new one. A shape that
cannot be read only because the period's scatter put its second harmonic past the band's end (a 2 mm press read
a little short) is not flagged as unreadable either.
"""
from __future__ import annotations

import numpy as np

#: Robust SDs of a surface's scatter a reading may lie beyond the trained range before it is flagged (a normal's
#: 99.7 %: with the ~1000 training presses of a study, about 3 false flags per feature).
PRESS_Z = 3.0
#: The spread's columns: the law's three features (peak_law.FEATURE_NAMES), then the peak's clarity.
N_SPREAD = 4
#: Median absolute deviation of a normal, in SDs.
_MAD_PER_SD = 0.6744897501960817


def deviations(alone: np.ndarray, clarity_alone: np.ndarray, surface: np.ndarray, clarity_surface: np.ndarray
               ) -> np.ndarray:
    """(n, 4) each press read alone less its surface's reading: the three features (n, 3) and the clarity (n,)."""
    return np.column_stack([alone - surface, clarity_alone - clarity_surface])


def robust_spread(deviation: np.ndarray, train: np.ndarray) -> np.ndarray:
    """(F, 4) robust SD of the deviations (n, 4) over each mask's training rows (F, n); 0 where none is readable (a
    shape no press shows), so that column keeps the surface margins."""
    absolute = np.where(train[:, :, None], np.abs(deviation)[None], np.inf)  # (F, n, 4); inf: not counted
    absolute[np.isnan(absolute)] = np.inf
    ordered = np.sort(absolute, axis=1)  # the counted values first (np.nanmedian is ten times slower here)
    count = np.isfinite(absolute).sum(axis=1)  # (F, 4)
    low = np.take_along_axis(ordered, np.maximum(count - 1, 0)[:, None, :] // 2, axis=1)[:, 0]
    high = np.take_along_axis(ordered, (count // 2)[:, None, :], axis=1)[:, 0]
    with np.errstate(invalid="ignore"):
        median = 0.5 * (low + high)
    return np.where(count > 0, median / _MAD_PER_SD, 0.0)


def widening(spread, presses) -> np.ndarray:
    """(..., n, 4) how far each row may lie beyond the trained range: ``PRESS_Z * spread / sqrt(presses)`` for
    ``spread`` (..., 4) and each row's count of presses in its surface ``presses`` (n,)."""
    spread = np.asarray(spread, dtype=np.float64)
    presses = np.maximum(np.asarray(presses, dtype=np.float64), 1.0)
    return PRESS_Z * spread[..., None, :] / np.sqrt(presses)[:, None]
