"""Whether a press's structure lies in the spectrum's band: the one test every model family applies.

The spectrum is read on f_min..f_max (the paper's 0.1-1.0 mm^-1: periods of 1-10 mm). A surface finer or coarser
than that has no peak of its own in the band, and whatever the band then holds (harmonics, the pad's ridges,
shading) would be read as a surface it is not. So the whole line is looked at, not the band: its strongest
structure (the strongest peak from f_min / ``COARSEST_FACTOR`` to Nyquist, a fingerprint pad's own ridge frequency
left out as the peak law leaves it out) must lie inside the band by at least 1 / line length (half the Hann main
lobe): a peak whose lobe the band's edge cuts at its middle is no clear in-band peak. The reason names the period
measured on the whole line, never one read inside the band.
"""
from __future__ import annotations

import numpy as np

from .period import amplitude_scan

#: The scan looks down to f_min / COARSEST_FACTOR (periods up to 2 / f_min = 20 mm for the paper's band): coarser
#: still is the illumination's shading, not a surface.
COARSEST_FACTOR = 2.0
#: Zero-padding of the band test's scan: a period to a quarter bin, refined by a parabola through the log amplitudes
#: (the verdict needs the period to a few %; the scale check refines its own to 1e-4).
BAND_ZOOM = 4
#: Half-width (mm^-1) around the pad's ridge frequency left out of the search: the peak law's own exclusion
#: (model/peak_law.py ``DEFAULT_EXCLUSION_PER_MM``; the same reasoning, written here as the sensor's).
RIDGE_EXCLUSION_PER_MM = 0.1


def dominant_period_mm(line, px_per_mm: float, f_min_per_mm: float, *, ridge_period_mm: float | None = None
                       ) -> float:
    """The period (mm) of the line's strongest structure from f_min / :data:`COARSEST_FACTOR` to Nyquist, the pad's
    ridge frequency +-:data:`RIDGE_EXCLUSION_PER_MM` left out; NaN for a line with no peak (flat)."""
    if np.ptp(np.asarray(line, dtype=np.float64)) == 0:
        return float("nan")
    freq_px, amplitude = amplitude_scan(line, zoom=BAND_ZOOM)
    freq_mm = freq_px * px_per_mm
    usable = freq_mm >= f_min_per_mm / COARSEST_FACTOR
    if ridge_period_mm is not None:
        usable &= np.abs(freq_mm - 1.0 / ridge_period_mm) > RIDGE_EXCLUSION_PER_MM
    index = np.flatnonzero(usable[1:-1]) + 1
    local = index[(amplitude[index] >= amplitude[index - 1]) & (amplitude[index] >= amplitude[index + 1])]
    if local.size == 0 or not amplitude[local].max() > 0:
        return float("nan")
    best = int(local[np.argmax(amplitude[local])])
    left, centre, right = np.log(np.maximum(amplitude[best - 1:best + 2], np.finfo(float).tiny))
    curvature = left - 2 * centre + right
    offset = 0.5 * (left - right) / curvature if curvature < 0 else 0.0  # a parabola through the log amplitudes
    return 1.0 / ((freq_px[best] + offset * freq_px[1]) * px_per_mm)


def band_reason(period_mm: float, line_mm: float, f_min_per_mm: float, f_max_per_mm: float) -> str:
    """Why a press's strongest structure, of ``period_mm``, is no clear peak of the band ('' if it is one)."""
    lobe = 1.0 / line_mm  # half the Hann main lobe's half-width (mm^-1) on a line of this length
    finest, coarsest = 1.0 / f_max_per_mm, 1.0 / f_min_per_mm
    if not np.isfinite(period_mm):
        return "no structure along the line (flat gray level)"
    frequency = 1.0 / period_mm
    if frequency > f_max_per_mm - lobe:
        where = (f"below the band's {finest:.3g} mm (1/f_max)" if period_mm < finest else
                 f"at the band's {finest:.3g} mm edge (1/f_max), with no clear peak inside it")
        return f"finer than the sensor resolves: period {period_mm:.2f} mm, {where}"
    if frequency < f_min_per_mm + lobe:
        where = (f"above the band's {coarsest:.3g} mm (1/f_min)" if period_mm > coarsest else
                 f"at the band's {coarsest:.3g} mm edge (1/f_min), with no clear peak inside it")
        return f"coarser than the sensor resolves: period {period_mm:.3g} mm, {where}"
    return ""


def band_reasons(periods_mm, line_mm: float, f_min_per_mm: float, f_max_per_mm: float, surfaces=None) -> list[str]:
    """Per press, why its structure is no clear peak of the band ('' where it is one).

    With ``surfaces``, a surface is read from the median period of its presses: where that lies outside the band,
    every press of the surface says so (and that it is the surface's verdict); a press outside in a surface inside
    keeps its own reason, said to be its own, so a press and its surface never disagree unexplained.
    """
    periods = np.asarray(periods_mm, dtype=np.float64)
    own = [band_reason(p, line_mm, f_min_per_mm, f_max_per_mm) for p in periods]
    if surfaces is None:
        return own
    labels = np.asarray(surfaces)
    out = list(own)
    for label in dict.fromkeys(labels.tolist()):
        rows = np.flatnonzero(labels == label)
        finite = periods[rows][np.isfinite(periods[rows])]
        median = float(np.median(finite)) if finite.size else float("nan")
        surface = band_reason(median, line_mm, f_min_per_mm, f_max_per_mm)
        for i in rows:
            if surface:
                out[i] = f"surface (median of {len(rows)} presses) {surface}"
            elif own[i]:
                out[i] = f"this press alone (its surface lies in the band): {own[i]}"
    return out
