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
as 1/sqrt(k) (3-press subsets: 0.4-0.65 of one press's robust SD, seeds 0-2). The trained range already holds the
scatter of surfaces of the trained presses' count K (the median over training surfaces), so a surface of k presses
scatters beyond it by ``PRESS_Z * spread * sqrt(1/k - 1/K)`` (nothing where k >= K), added in quadrature to the
surface margins (:func:`~roughsense.model.readout_domain.domain_margins`): a row is flagged only beyond both. Only the flag
widens: a prediction is still held at the surface domain, since a press's scatter is noise about a trained
surface, not a new one. A shape that cannot be read only because the period's scatter put its second harmonic past
the band's end (a 2 mm press read a little short) is not flagged as unreadable either.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Robust SDs of a surface's scatter a reading may lie beyond the trained range before it is flagged (a normal's
#: 99.7 %: with the ~1000 training presses of a study, about 3 false flags per feature).
PRESS_Z = 3.0
#: The spread's columns: the law's three features (peak_law.FEATURE_NAMES), then the peak's clarity.
N_SPREAD = 4
#: Median absolute deviation of a normal, in SDs.
MAD_PER_SD = 0.6744897501960817


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
    return np.where(count > 0, median / MAD_PER_SD, 0.0)


@dataclass(frozen=True)
class PressScatter:
    """The training presses' robust scatter about their surfaces (``spread``: log frequency, log amplitude, harmonic
    ratio, clarity) and the presses per trained surface (``trained_presses``, the median)."""

    spread: np.ndarray
    trained_presses: float

    def excess(self, presses) -> np.ndarray:
        """(n, 4) how much further a surface of ``presses`` (n,) presses scatters than a trained one, in
        :data:`PRESS_Z` robust SDs: ``PRESS_Z * spread * sqrt(1/k - 1/K)``, 0 where k >= K."""
        presses = np.maximum(np.asarray(presses, dtype=np.float64), 1.0)
        share = np.sqrt(np.maximum(1.0 / presses - 1.0 / max(float(self.trained_presses), 1.0), 0.0))
        return PRESS_Z * np.asarray(self.spread, dtype=np.float64)[None, :] * share[:, None]

    def to_dict(self) -> dict:
        return {"spread": [float(v) for v in self.spread], "trained_presses": float(self.trained_presses)}


def trained_presses(codes: np.ndarray, train: np.ndarray) -> np.ndarray:
    """(F,) the median count of presses per training surface of each mask (F, n); ``codes`` (n,) surface codes."""
    members = np.zeros((codes.size, int(codes.max()) + 1 if codes.size else 0))
    members[np.arange(codes.size), codes] = 1.0
    counts = train.astype(float) @ members  # (F, S)
    return np.array([np.median(row[row > 0]) if np.any(row > 0) else 1.0 for row in counts])
