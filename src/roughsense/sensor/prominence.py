"""How far a line's spectrum stands above its own surroundings at a frequency: the test a scale reading must pass.

A peak's height means nothing alone: a line of noise has a local maximum everywhere, and a photograph's spectrum
falls as 1/f. So the amplitude at a frequency is compared with the line's *noise floor* there, the median
amplitude of the DFT bins within a factor :data:`FLOOR_SPAN` either side (the peak's own Hann main lobe, +-2 bins,
left out). On white noise each DFT bin's amplitude is Rayleigh distributed, whose median is sqrt(2 ln 2) sigma,
so P(amplitude > k x median) = 2^(-k^2): 1.5e-5 at k = 4, 3e-8 at k = 5. A peak is *clear* at
:data:`CLEAR_PROMINENCE` (5): a line of noise shows one somewhere in a search over ~1000 bins with probability
about 3e-5, and the twin's presses show their pad's ridges and their gratings 10-1000x above the floor
(BENCHMARKS.md, "scale check").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .period import ZOOM, amplitude_scan

#: The noise floor at f is the median amplitude over [f / FLOOR_SPAN, f * FLOOR_SPAN]: wide enough to hold a dozen
#: bins at the coarsest period a line resolves (5 periods), narrow enough that a 1/f spectrum's slope barely moves it,
#: and short of a square wave's 3rd harmonic (x3).
FLOOR_SPAN = 1.6
#: The floor leaves out this many DFT bins either side of f: a Hann window's main lobe is +-2 bins.
LOBE_BINS = 3
#: The fewest bins a floor is taken over (near DC a factor-of-1.6 window holds too few).
MIN_FLOOR_BINS = 8
#: A peak is the largest amplitude within this many DFT bins either side: a Hann window's first two side lobes (-31 and
#: -41 dB, at 2.5 and 3.5 bins) of a strong peak would otherwise stand clear of a quiet line's floor.
PEAK_BINS = 4
#: A peak this many times its noise floor is clear (module docstring).
CLEAR_PROMINENCE = 5.0


@dataclass(frozen=True)
class LineSpectrum:
    """A line's zero-padded amplitude scan (cycles per px) and its noise floor on the same frequencies."""

    freq_px: np.ndarray
    amplitude: np.ndarray
    floor: np.ndarray
    line_px: int
    #: The largest amplitude within :data:`PEAK_BINS` of each frequency: a peak is the largest of its neighbourhood.
    dominated: np.ndarray

    @classmethod
    def of(cls, line) -> LineSpectrum:
        line = np.asarray(line, dtype=np.float64)
        freq, amplitude = amplitude_scan(line)
        from scipy.ndimage import maximum_filter1d

        coarse = amplitude[::ZOOM]  # the plain DFT's bins: independent on noise, unlike the padded ones
        return cls(freq, amplitude, np.interp(freq, freq[::ZOOM], _floor(coarse)), int(line.size),
                   maximum_filter1d(amplitude, size=2 * PEAK_BINS * ZOOM + 1, mode="nearest"))

    def prominence(self, low_px: np.ndarray, high_px: np.ndarray) -> np.ndarray:
        """The largest amplitude over floor of a peak (:data:`PEAK_BINS`) within each [low, high] (cycles per px); 0
        where there is none."""
        ratio = np.divide(self.amplitude, self.floor, out=np.zeros_like(self.amplitude), where=self.floor > 0)
        ratio[self.amplitude < self.dominated] = 0.0  # a strong peak's flanks and side lobes are no peaks of their own
        start = np.searchsorted(self.freq_px, low_px, side="left")
        stop = np.maximum(np.searchsorted(self.freq_px, high_px, side="right"), start + 1)
        start, stop = np.clip(start, 1, ratio.size - 1), np.clip(stop, 1, ratio.size)
        best = np.maximum.reduceat(np.append(ratio, 0.0), np.ravel(np.column_stack([start, stop])))[::2]
        return np.where(start < stop, best, 0.0)


def _floor(amplitude: np.ndarray) -> np.ndarray:
    """Each bin's noise floor (module docstring), taken at log-spaced bins and interpolated between them; the windows'
    medians at once (sorted rows, the excluded bins sorted last as +inf)."""
    n = amplitude.size
    bins = np.arange(n)
    centres = np.unique(np.geomspace(1, n - 1, 96).round().astype(int))
    low, high = (centres / FLOOR_SPAN).astype(int), np.ceil(centres * FLOOR_SPAN).astype(int)
    narrow = high - low < 2 * LOBE_BINS + MIN_FLOOR_BINS
    low = np.where(narrow, centres - LOBE_BINS - MIN_FLOOR_BINS // 2, low)
    high = np.where(narrow, centres + LOBE_BINS + MIN_FLOOR_BINS // 2, high)
    low, high = np.maximum(low, 1), np.minimum(high, n - 1)
    window = low[:, None] + np.arange(int((high - low).max()) + 1)[None, :]
    keep = (window <= high[:, None]) & (np.abs(window - centres[:, None]) > LOBE_BINS)
    values = np.sort(np.where(keep, amplitude[np.minimum(window, n - 1)], np.inf), axis=1)
    count = keep.sum(axis=1)
    ok = count > 0
    rows = np.flatnonzero(ok)
    middle = 0.5 * (values[rows, (count[ok] - 1) // 2] + values[rows, count[ok] // 2])
    return np.interp(bins, centres[ok], middle) if ok.any() else np.zeros(n)


#: The fewest periods on a line at which the check looks for a peak: half calibrate's 5 (``period.MIN_PERIODS_PER_LINE``,
#: which keeps a new rig's search clear of the shading), so that a short crop still shows two known periods at the true
#: scale (a 400 px line at 34.9 px/mm holds 3.8 periods of R3), where agreement needs them. A peak there is still a
#: peak (the noise floor and :data:`PEAK_BINS` hold at a few bins).
CHECK_PERIODS_PER_LINE = 2.5
#: A mount's magnification differs from another's (the twin's bench: 2.2 % SD), so each line's peak is looked for
#: within this factor either side of where a candidate scale puts it (over 2 SD).
MOUNT_SPREAD = 1.05
#: Neighbouring candidate scales differ by this factor: a fifth of the spread, so no peak falls between two.
SCALE_STEP = 1.01


def scale_grid(periods_mm, lines_px) -> np.ndarray:
    """Every scale (px/mm) at which some line resolves some of the periods (3 px per period to
    :data:`CHECK_PERIODS_PER_LINE` periods on the line), their union, log-spaced by :data:`SCALE_STEP`."""
    from .period import MIN_PX_PER_PERIOD

    bounds = np.array([(MIN_PX_PER_PERIOD / float(p), int(n) / (CHECK_PERIODS_PER_LINE * float(p)))
                       for p, n in zip(periods_mm, lines_px)])
    low, high = float(bounds[:, 0].min()), float(bounds[:, 1].max())
    return np.geomspace(low, high, max(2, int(np.ceil(np.log(high / low) / np.log(SCALE_STEP))) + 1))


def peak_heights(spectrum: LineSpectrum, period_mm: float, scales: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(prominence, resolvable) at each scale: the line's highest peak over its floor within :data:`MOUNT_SPREAD` of
    where that scale puts ``period_mm`` (0 where the line cannot show that period), and whether it can."""
    from .period import MIN_PX_PER_PERIOD

    period_px = period_mm * scales
    resolvable = (period_px >= MIN_PX_PER_PERIOD) & (period_px <= spectrum.line_px / CHECK_PERIODS_PER_LINE)
    frequency = 1.0 / period_px
    return np.where(resolvable, spectrum.prominence(frequency / MOUNT_SPREAD, frequency * MOUNT_SPREAD), 0.0), resolvable


def clear_peaks(spectrum: LineSpectrum, period_mm: float, scales: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(clear, resolvable) at each scale: whether the line shows a clear peak (:data:`CLEAR_PROMINENCE`) where that
    scale puts ``period_mm`` (:func:`peak_heights`), and whether the line can show that period there."""
    height, resolvable = peak_heights(spectrum, period_mm, scales)
    return height >= CLEAR_PROMINENCE, resolvable


def peak_prominence(line, cycles_per_px: float) -> float:
    """How many times its noise floor the line's amplitude stands within one DFT bin of ``cycles_per_px`` (0 for a
    NaN frequency): whether a period measured on the line is there at all."""
    if not np.isfinite(cycles_per_px):
        return 0.0
    spectrum = LineSpectrum.of(line)
    step = 1.0 / spectrum.line_px
    return float(spectrum.prominence(np.array([cycles_per_px - step]), np.array([cycles_per_px + step]))[0])
