"""The period of known structure along a gray line, measured below the DFT's bin: the camera's scale from it.

Every spectrum is in mm^-1, so px/mm is the one number all of them depend on. A target of known period (a grating,
the reference specimen, a fingerprint pad's ridges) tells it: its period in pixels over its period in mm.

The line is mean-removed and Hann-tapered (as the spectrum's line is), its amplitude spectrum is scanned on an
FFT zero-padded :data:`ZOOM` times, and the strongest peak in the searched range is refined by maximising the
windowed DTFT's amplitude itself (a bounded scalar search over +-1 padded bin). The refinement has no
interpolation bias: a pure sinusoid of many cycles reads its own frequency to 1e-4 (tests/sensor/test_band.py).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

#: Zero-padding of the coarse scan: a peak is found to 1/8 of a DFT bin before the refinement.
ZOOM = 8
#: How far (relative) a known period is searched either side of where the stated scale puts it: beyond the
#: scale errors a moved camera makes (a few %), short of the next structure (a grating's 2nd harmonic is x2).
CHECK_WINDOW = 0.15
#: The finest period read for calibration, in px: 2 is the Nyquist limit, 3 keeps the peak clear of it.
MIN_PX_PER_PERIOD = 3.0
#: The fewest periods on the line for calibration: a coarser target is lost among the illumination's slow variation.
MIN_PERIODS_PER_LINE = 5.0


def _tapered(line) -> np.ndarray:
    line = np.asarray(line, dtype=np.float64)
    if line.ndim != 1 or line.size < 16:
        raise InputError(f"a line of at least 16 px is needed to measure a period, got shape {line.shape}")
    return (line - line.mean()) * np.hanning(line.size)


def amplitude_scan(line, zoom: int = ZOOM) -> tuple[np.ndarray, np.ndarray]:
    """(cycles per px, amplitude) of the tapered line on an FFT zero-padded ``zoom`` times."""
    tapered = _tapered(line)
    n = zoom * tapered.size
    return np.fft.rfftfreq(n), np.abs(np.fft.rfft(tapered, n))


def _dtft_amplitude(tapered: np.ndarray, cycles_per_px: float) -> float:
    phase = -2j * np.pi * cycles_per_px * np.arange(tapered.size)
    return float(np.abs(np.exp(phase) @ tapered))


def refine_peak(tapered: np.ndarray, coarse_cycles_per_px: float) -> float:
    """The windowed DTFT's amplitude maximum within one padded bin of ``coarse_cycles_per_px`` (cycles per px)."""
    from scipy.optimize import minimize_scalar

    step = 1.0 / (ZOOM * tapered.size)
    low, high = max(coarse_cycles_per_px - step, step / 4), min(coarse_cycles_per_px + step, 0.5)
    best = minimize_scalar(lambda f: -_dtft_amplitude(tapered, f), bounds=(low, high), method="bounded",
                           options={"xatol": step * 1e-3})  # 1e-3 of a padded bin: < 1e-4 of any period's frequency
    return float(best.x)


def strongest_peak(line, low_cycles_per_px: float, high_cycles_per_px: float) -> tuple[float, float]:
    """(refined frequency in cycles per px, its amplitude) of the strongest local maximum in [low, high]; NaN for
    both where the range holds no local maximum (a monotone slope): an edge is never taken for a peak."""
    if np.ptp(np.asarray(line, dtype=np.float64)) == 0:  # a flat line: only rounding would peak
        return float("nan"), float("nan")
    freq, amplitude = amplitude_scan(line)
    inside = np.flatnonzero((freq >= low_cycles_per_px) & (freq <= high_cycles_per_px))
    inside = inside[(inside > 0) & (inside < freq.size - 1)]
    local = inside[(amplitude[inside] >= amplitude[inside - 1]) & (amplitude[inside] >= amplitude[inside + 1])]
    if local.size == 0:
        return float("nan"), float("nan")
    best = int(local[np.argmax(amplitude[local])])
    return refine_peak(_tapered(line), float(freq[best])), float(amplitude[best])


@dataclass(frozen=True)
class ScaleMeasurement:
    """px/mm measured from a target of known period on several lines: each line's value (NaN where the line shows
    no peak of the target), their median and how precisely it is known.

    ``mounts`` labels the lines taken in one mount of the target: their magnification is one, so they are one
    measurement for the precision (a bench's mount-to-mount magnification varies; presses of one mount do not).
    """

    period_mm: float
    px_per_mm_each: np.ndarray
    mounts: np.ndarray | None = None

    @property
    def measured(self) -> np.ndarray:
        return self.px_per_mm_each[np.isfinite(self.px_per_mm_each)]

    @property
    def n_measured(self) -> int:
        return int(self.measured.size)

    @property
    def mount_values(self) -> np.ndarray:
        """The median of each mount's measured lines (each line its own mount without ``mounts``)."""
        if self.mounts is None:
            return self.measured
        ok = np.isfinite(self.px_per_mm_each)
        labels = np.asarray(self.mounts)[ok]
        return np.array([np.median(self.px_per_mm_each[ok][labels == m]) for m in dict.fromkeys(labels.tolist())])

    @property
    def n_mounts(self) -> int:
        return int(self.mount_values.size)

    @property
    def px_per_mm(self) -> float:
        """The median over the lines that show the target (NaN if none does)."""
        return float(np.median(self.measured)) if self.n_measured else float("nan")

    @property
    def standard_error(self) -> float:
        """Relative standard error (SD / sqrt(n) / median) over the mounts that show the target; NaN below two."""
        values = self.mount_values
        if values.size < 2:
            return float("nan")
        return float(np.std(values, ddof=1) / np.sqrt(values.size) / self.px_per_mm)


def check_scale(lines: Sequence, period_mm: float, px_per_mm: float, *, window: float = CHECK_WINDOW
                ) -> ScaleMeasurement:
    """px/mm measured on each line from structure of ``period_mm``, searched within +-``window`` of where the
    stated ``px_per_mm`` puts it (so a neighbouring structure, a harmonic or a pad's ridges, is not taken for it)."""
    expected = 1.0 / (period_mm * px_per_mm)
    each = [1.0 / (period_mm * strongest_peak(line, expected / (1 + window), expected / (1 - window))[0])
            for line in lines]
    return ScaleMeasurement(float(period_mm), np.asarray(each, dtype=np.float64))


def resolvable_scales(line_px: int, period_mm: float) -> tuple[float, float]:
    """The px/mm at which a target of ``period_mm`` can be read on a line of ``line_px``: from
    :data:`MIN_PX_PER_PERIOD` px per period (finer aliases) to :data:`MIN_PERIODS_PER_LINE` periods on the line
    (coarser is lost among the illumination's own slow variation). A new rig's scale is searched over all of it."""
    return MIN_PX_PER_PERIOD / period_mm, line_px / (MIN_PERIODS_PER_LINE * period_mm)


def calibrate_scale(lines: Sequence, period_mm: float, *, px_per_mm_range: tuple[float, float] | None = None,
                    ridge_period_mm: float | None = None) -> ScaleMeasurement:
    """px/mm measured from a target of ``period_mm`` on each line, the scale not yet known (a new rig).

    Each line's scale is found first on a log grid over ``px_per_mm_range``, scoring the amplitude where the target
    would peak at that scale (plus, on a pad with ridges of ``ridge_period_mm``, where the ridges would peak: their
    relief can outshine a grating, and only the right scale puts both in place); the target's peak there is then
    refined as :func:`check_scale` refines it. A press whose scale lands beyond :data:`CHECK_WINDOW` of the
    presses' median (it read a harmonic or other structure) is read again within that window of the median.
    """
    if px_per_mm_range is None:
        px_per_mm_range = resolvable_scales(min(np.asarray(line).size for line in lines), period_mm)
    low, high = (float(v) for v in px_per_mm_range)
    if not 0 < low < high:
        raise InputError(f"the scale range must satisfy 0 < low < high px/mm, got {low:g}, {high:g}")
    scales = np.geomspace(low, high, 2000)
    each = []
    for line in lines:
        freq, amplitude = amplitude_scan(line)
        relative = amplitude / amplitude[1:].max()
        score = np.interp(1.0 / (period_mm * scales), freq, relative)
        if ridge_period_mm is not None and not np.isclose(ridge_period_mm, period_mm):
            score = score + np.interp(1.0 / (ridge_period_mm * scales), freq, relative)
        guess = float(scales[int(np.argmax(score))])
        each.append(check_scale([line], period_mm, guess, window=0.05).px_per_mm_each[0])
    each = np.asarray(each, dtype=np.float64)
    consensus = float(np.nanmedian(each)) if np.isfinite(each).any() else float("nan")
    strays = np.flatnonzero(~(np.abs(each / consensus - 1) <= CHECK_WINDOW))  # a press that read another structure
    if strays.size and np.isfinite(consensus):
        each[strays] = check_scale([lines[i] for i in strays], period_mm, consensus).px_per_mm_each
    return ScaleMeasurement(float(period_mm), each)
