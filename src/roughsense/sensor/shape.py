"""Features of shape: how the contact is distributed within one period, read from a spectrum at its fundamental.

Two gratings of one period differ in how much of each period is in contact. A rectangular grating's lands fill half
of it (duty cycle 1/2: a square wave, whose even harmonics vanish); touching semi-cylinders touch only at their
crests (a narrow contact, whose harmonics are all about as strong as the fundamental). The spectrum therefore
carries the shape in its **second harmonic**: for a pulse train of duty cycle d,

    A(2 f0) / A(f0) = |cos(pi d)|,

so the log ratio is very negative for d near 1/2 and near 0 for a narrow contact. The contact image is not a pulse
train (its gray level follows the gap smoothly, and lens blur lowers 2 f0 more than f0), so :func:`duty_cycle` is the
pulse train's *equivalent* duty cycle, a reading of the ratio in geometric words, not a measured land width.

The ratio can only be read where 2 f0 lies in the band and outside the pad's own ridge frequency: on the paper's
band (to 1.0 mm^-1) every period from 2 mm up, but on a fingerprint pad (ridges at 1 mm^-1) not for periods near
2 mm, whose second harmonic sits on the ridges. Such a row gets NaN, never a number read off the pad. The contact
fraction before normalisation is not in a spectrum (it is normalised to unit area), so it is not read here.
"""
from __future__ import annotations

import numpy as np

from .band import RIDGE_EXCLUSION_PER_MM
from .grid import grid_step


def lobe_height(log_spectra, freq_per_mm, near_per_mm) -> np.ndarray:
    """Each row's log height of the spectral lobe nearest its own frequency: the highest of the three bins around it,
    refined by a parabola through its neighbours (an end bin is read as it is). A line's Hann-windowed lobe spans
    about two bins, so a height read between bins by interpolation would fall short by up to a log unit; the
    parabola's vertex does not. NaN outside the grid."""
    log_spectra = np.atleast_2d(np.asarray(log_spectra, dtype=np.float64))
    freq = np.asarray(freq_per_mm, dtype=np.float64)
    near = np.asarray(near_per_mm, dtype=np.float64)
    n, k_bins = log_spectra.shape
    rows = np.arange(n)
    step = grid_step(freq)
    centre_bin = np.clip(np.rint((near - freq[0]) / step).astype(int), 0, k_bins - 1)
    around = np.clip(centre_bin[:, None] + np.array([-1, 0, 1]), 0, k_bins - 1)
    peak = around[rows, np.argmax(np.take_along_axis(log_spectra, around, axis=1), axis=1)]
    left = log_spectra[rows, np.maximum(peak - 1, 0)]
    centre = log_spectra[rows, peak]
    right = log_spectra[rows, np.minimum(peak + 1, k_bins - 1)]
    curvature = left - 2 * centre + right
    concave = (peak > 0) & (peak < k_bins - 1) & (curvature < 0)
    offset = np.zeros(n)
    offset[concave] = np.clip(0.5 * (left[concave] - right[concave]) / curvature[concave], -0.5, 0.5)
    height = centre - 0.25 * (left - right) * offset
    height[(near < freq[0] - step) | (near > freq[-1] + step)] = np.nan
    return height


def readable(freq_per_mm, at_per_mm, pad_ridge_period_mm: float | None = None,
             exclusion_per_mm: float = RIDGE_EXCLUSION_PER_MM) -> np.ndarray:
    """Whether each frequency lies in the band (one grid step of slack: a peak is read to about half a step, and
    its second harmonic doubles that, so a 2 mm grating's may read just past 1.0 mm^-1 and still sits on the last
    bin) and farther than
    ``exclusion_per_mm`` from the pad's ridge frequency (1 / ``pad_ridge_period_mm``; a smooth pad has none), where
    the pad's own relief, not the surface, sets the amplitude."""
    freq = np.asarray(freq_per_mm, dtype=np.float64)
    at = np.asarray(at_per_mm, dtype=np.float64)
    slack = grid_step(freq)
    inside = (at >= freq[0] - slack) & (at <= freq[-1] + slack)
    if pad_ridge_period_mm is None:
        return inside
    return inside & (np.abs(at - 1.0 / float(pad_ridge_period_mm)) > float(exclusion_per_mm))


def harmonic_ratio(log_spectra, freq_per_mm, fundamental_per_mm, pad_ridge_period_mm: float | None = None,
                   exclusion_per_mm: float = RIDGE_EXCLUSION_PER_MM) -> np.ndarray:
    """log A(2 f0) - log A(f0) of each row (``log_spectra`` (n, K) on the grid, ``fundamental_per_mm`` (n,));
    NaN where 2 f0 cannot be read (outside the band, or on the pad's ridges, :func:`readable`)."""
    f0 = np.asarray(fundamental_per_mm, dtype=np.float64)
    ratio = lobe_height(log_spectra, freq_per_mm, 2 * f0) - lobe_height(log_spectra, freq_per_mm, f0)
    ratio[~readable(freq_per_mm, 2 * f0, pad_ridge_period_mm, exclusion_per_mm)] = np.nan
    return ratio


def duty_cycle(log_ratio) -> np.ndarray:
    """The duty cycle (0-1/2) of the pulse train whose second harmonic has this log ratio to its fundamental."""
    ratio = np.exp(np.asarray(log_ratio, dtype=np.float64))
    return np.arccos(np.clip(ratio, 0.0, 1.0)) / np.pi
