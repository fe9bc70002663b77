"""Whether a press's structure lies in the spectrum's band: the one test every model family applies.

The spectrum is read on f_min..f_max (the paper's 0.1-1.0 mm^-1: periods of 1-10 mm). A surface finer or coarser
than that has no peak of its own in the band, and whatever the band then holds (harmonics, the pad's ridges,
shading) would be read as a surface it is not. So the whole line is looked at, not the band: its strongest peak
outside the band's interior (from f_min / ``COARSEST_FACTOR`` to Nyquist; the interior ends 1 / line length inside
each edge, half the Hann main lobe, so a peak the edge cuts at its middle is outside) is compared with its strongest
peak inside. A fingerprint pad's ridge frequency and its odd harmonics (its ridges are a square wave) are left out,
as the peak law leaves the ridges out. The press lies outside the band when the outside peak is :data:`DOMINANCE`
times the inside one or more; the reason names the period measured on the whole line, never one read in the band.

:data:`DOMINANCE` (1.5) separates the twin's presses cleanly on the smooth pad (the 14 built-in gratings' ratios
are at most 0.64; 0.3-10 mm gratings' at least 2.2). On the fingerprint pad the ridges' sidebands and the shading
overlap: built-in gratings' medians are at most 1.15, the out-of-band gratings' at least 1.64, single presses of
both reach 1.2-4.9, so a press read alone can be missed or flagged where its surface, read from its presses'
medians, is not (BENCHMARKS.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .period import amplitude_scan

#: The scan looks down to f_min / COARSEST_FACTOR (periods up to 2 / f_min = 20 mm for the paper's band): coarser
#: still is the illumination's shading, not a surface.
COARSEST_FACTOR = 2.0
#: Zero-padding of the scan: a period to a quarter bin, refined by a parabola through the log amplitudes (the
#: verdict needs it to a few %; the scale check refines its own to 1e-4).
BAND_ZOOM = 4
#: Half-width (mm^-1) around the pad's ridge frequency and its odd harmonics left out: the Hann main lobe of a 54 mm
#: line is +-0.037 mm^-1, widened for the bench's magnification jitter and the ridges' sidebands. The contact's
#: shape (:mod:`.shape`) and the peak law's search leave out the same.
RIDGE_EXCLUSION_PER_MM = 0.1
RIDGE_HARMONICS = (1, 3, 5, 7)
#: How many times stronger than the band's own strongest peak the outside peak must be for the press to lie outside.
DOMINANCE = 1.5
#: Where a family already flags a press, an outside structure at least as strong as the band's own peak is named as
#: the cause in place of the family's reading of the band (which would name a period the surface does not have).
NAMING_DOMINANCE = 1.0


@dataclass(frozen=True)
class BandReading:
    """A press's strongest structure outside the band's interior: its period (mm; NaN if none) and its amplitude
    over the strongest peak inside (inf with nothing inside)."""

    period_mm: float
    dominance: float


def _peak_period(freq_px: np.ndarray, amplitude: np.ndarray, index: np.ndarray, px_per_mm: float) -> float:
    """The period (mm) of the peak at ``index``, refined by a parabola through the log amplitudes of its bins."""
    left, centre, right = np.log(np.maximum(amplitude[index - 1:index + 2], np.finfo(float).tiny))
    curvature = left - 2 * centre + right
    offset = 0.5 * (left - right) / curvature if curvature < 0 else 0.0
    return 1.0 / ((freq_px[index] + offset * freq_px[1]) * px_per_mm)


def band_reading(line, px_per_mm: float, f_min_per_mm: float, f_max_per_mm: float, *,
                 ridge_period_mm: float | None = None) -> BandReading:
    """The :class:`BandReading` of one gray line (module docstring)."""
    line = np.asarray(line, dtype=np.float64)
    if np.ptp(line) == 0:
        return BandReading(float("nan"), 0.0)
    freq_px, amplitude = amplitude_scan(line, zoom=BAND_ZOOM)
    freq_mm = freq_px * px_per_mm
    usable = freq_mm >= f_min_per_mm / COARSEST_FACTOR
    if ridge_period_mm is not None:
        for n in RIDGE_HARMONICS:
            usable &= np.abs(freq_mm - n / ridge_period_mm) > RIDGE_EXCLUSION_PER_MM
    index = np.flatnonzero(usable[1:-1]) + 1
    local = index[(amplitude[index] >= amplitude[index - 1]) & (amplitude[index] >= amplitude[index + 1])]
    margin = 1.0 / (line.size / px_per_mm)
    inside = (freq_mm[local] > f_min_per_mm + margin) & (freq_mm[local] < f_max_per_mm - margin)
    if not (~inside).any():
        return BandReading(float("nan"), 0.0)
    outer = local[~inside][np.argmax(amplitude[local[~inside]])]
    inner = amplitude[local[inside]].max() if inside.any() else 0.0
    dominance = amplitude[outer] / inner if inner > 0 else float("inf")
    return BandReading(_peak_period(freq_px, amplitude, outer, px_per_mm), float(dominance))


def band_reason(reading: BandReading, f_min_per_mm: float, f_max_per_mm: float, *,
                dominance: float = DOMINANCE) -> str:
    """Why a press's structure is no clear peak of the band ('' where it is one): its outside structure is
    ``dominance`` times the band's own peak or more (a lower bar names the cause of a flag a family already raised)."""
    period_mm = reading.period_mm
    if not (np.isfinite(period_mm) and reading.dominance >= dominance):
        return ""
    finest, coarsest = 1.0 / f_max_per_mm, 1.0 / f_min_per_mm
    strength = f"{reading.dominance:.3g}x the band's own strongest peak"
    if 1.0 / period_mm > 0.5 * (f_min_per_mm + f_max_per_mm):
        where = (f"below the band's {finest:.3g} mm (1/f_max)" if period_mm < finest else
                 f"at the band's {finest:.3g} mm edge (1/f_max)")
        return f"finer than the sensor resolves: period {period_mm:.2f} mm, {where}; {strength}"
    where = (f"above the band's {coarsest:.3g} mm (1/f_min)" if period_mm > coarsest else
             f"at the band's {coarsest:.3g} mm edge (1/f_min)")
    return f"coarser than the sensor resolves: period {period_mm:.3g} mm, {where}; {strength}"


def band_reasons(readings, f_min_per_mm: float, f_max_per_mm: float, surfaces=None, *,
                 dominance: float = DOMINANCE) -> list[str]:
    """Per press, why its structure is no clear peak of the band ('' where it is one).

    With ``surfaces``, a surface is read from the medians of its presses' periods and dominances, and each press
    takes its surface's verdict (as the peak law reads a grouped press at its surface's period): outside the band,
    every press says so and that it is the surface's verdict; inside, none is flagged for the band, so a press and
    its surface never disagree.
    """
    readings = list(readings)
    if surfaces is None:
        return [band_reason(r, f_min_per_mm, f_max_per_mm, dominance=dominance) for r in readings]
    labels = np.asarray(surfaces)
    out = [""] * len(readings)
    for label in dict.fromkeys(labels.tolist()):
        rows = np.flatnonzero(labels == label)
        surface = band_reason(median_reading([readings[i] for i in rows]), f_min_per_mm, f_max_per_mm,
                              dominance=dominance)
        for i in rows:
            out[i] = f"surface (median of {len(rows)} presses) {surface}" if surface else ""
    return out


def median_reading(readings) -> BandReading:
    """The median period and dominance of several readings (a trial's forces, a surface's presses)."""
    periods = np.array([r.period_mm for r in readings], dtype=np.float64)
    dominance = np.array([r.dominance for r in readings], dtype=np.float64)
    finite = periods[np.isfinite(periods)]
    return BandReading(float(np.median(finite)) if finite.size else float("nan"),
                       float(np.median(dominance)) if dominance.size else 0.0)
