"""The contact's geometry read from the whole contact band: land (contact) and groove (gap) widths in mm.

A grating's land touches the pad and shows bright; its groove leaves a gap and shows dark. Fingers feel the groove
(Lederman 1974; Klatzky & Lederman 2007), and the spectrum's period cannot tell a 3 mm groove from a 1 mm one at the
same period, so the widths are measured on the image itself:

1. **The band profile** (:func:`band_profile`): the crop's rows from its top down to the line (the rows the spectrum
   already decoded; the grating's lines run down the columns) averaged into one gray profile: pixel noise falls by
   the square root of their number, and a speck of dust on one row barely moves it.
2. **Contact vs gap against local envelopes** (:func:`read_contact`). The grating's period P is read from the
   profile's own spectrum (or given). The upper and lower envelopes are the profile's running maximum and minimum
   over one period; a point is contact where the profile lies above their midpoint, so shading, a smudge or a lighter
   mount moves the threshold with it. Where the envelopes are close (below :data:`MIN_RELATIVE_RANGE` of the line's
   typical range, or :data:`MIN_DEPTH` of the upper envelope) there is no contact pattern -- the crop's ends outside
   the contact patch are a flat, dark baseline -- and nothing there counts, least of all as groove.
3. **Whole periods only.** Edges are found with hysteresis (the profile must move :data:`HYSTERESIS` of the local
   range past the midpoint) and placed at the midpoint crossing, interpolated between samples (pairs of pixels,
   :data:`BIN_FROM_PX_PER_MM`). Only runs bounded by edges on both sides count (the first and last of each patterned
   stretch are cut off by it), a land only between two complete grooves (the contact patch may end inside a land, and
   its dark baseline reads as gap), and of those only runs of typical width (within :data:`PERIOD_TOLERANCE` of a
   period from their median: a land split by a smudge is no whole land); ``land_mm`` and ``groove_mm`` are their
   means.

**On a fingerprint pad** the profile is dominated by the pad's ridges (1 mm^-1): each ridge crest in contact with a
land is bright, a crest over a groove shows only as bright as the pad's own relief seen through it, and the pad's
grooves between ridges are dark on land and groove alike. The land/groove pattern is therefore read on the **crest
envelope**: a grey closing (running maximum then running minimum) over one ridge period fills the dark gaps between
neighbouring crests and keeps the crests' brightness, and steps 2-3 run on it. A land then reads as the hull of its
bright crests: it can read short by up to the part of a ridge period where its edge falls between two crests (the
tests bound the error); the reading adds :data:`RIDGE_HULL_SHORTFALL` ridge periods, the hull's mean shortfall, to
each land and takes it from each groove. A groove narrower than one ridge period cannot be told from a gap between
crests at all. The crest envelope may also beat: a grating harmonic near the ridge frequency makes a moire, so on a
ridged pad the period read on the envelope must agree with the raw profile's. Where the crests over the grooves are
nearly as bright as those on the lands (the relief seen strongly), the modulation is below :data:`MIN_DEPTH` and the
press reads NaN.

A measure that cannot be read with confidence is NaN: fewer than :data:`MIN_RUNS` complete lands or grooves, or runs
that do not repeat at the period (a land and its groove off it by more than :data:`PERIOD_TOLERANCE` too often: no
grating's runs).

Precision (``tests/sensor/test_contact_geometry.py`` asserts each bound): a smooth pad's synthetic bands within
0.02 mm, the twin's smooth pad within 0.15 mm of every rectangle (its mounts' ~2 % magnification jitter); a
fingerprint-like pad within 0.8 mm (median 0.35 mm) where read, the twin's fingerprint pad reading a third to two
fifths of its presses.

Cached feature tables hold these measures: a change to the reading bumps ``_util/cache.CACHE_FORMAT``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter1d, minimum_filter1d

from ..io.images import GRAY_WEIGHTS_RGB, intensity_scale
from .descriptors import _hann

#: Every contact measure a press yields, in order (units in the names): the mean complete land and groove widths,
#: land / (land + groove), and the standard error of the two means (the larger), a precision per press.
CONTACT_MEASURES = ("land_mm", "groove_mm", "land_fraction", "width_se_mm")
#: A point belongs to the contact pattern where the local range is at least this share of the line's typical
#: (90th-percentile) local range ...
MIN_RELATIVE_RANGE = 0.4
#: ... and at least this share of the upper envelope (the land's brightness over the groove's).
MIN_DEPTH = 0.15
#: ... and this many times the profile's noise (from its mean absolute second difference, :func:`_noise_sd`).
MIN_NOISE_MULTIPLE = 8.0
#: An edge is an excursion past the midpoint by this share of the local range on both sides.
HYSTERESIS = 0.15
#: The fewest complete lands and grooves a reading needs.
MIN_RUNS = 2
#: A land and the groove beside it must span the period within this fraction, for this share of such pairs.
PERIOD_TOLERANCE = 0.15
REGULAR_SHARE = 0.8
#: Where the period is searched (mm^-1) when it is not given: the spectrum's band; on a ridged pad only up to
#: RIDGE_GUARD of its ridge frequency (the ridges' own peak is no grating's).
PERIOD_BAND_PER_MM = (0.1, 1.0)
RIDGE_GUARD = 0.8
#: On a ridged pad a land reads as the hull of its bright crests: on average half a ridge period short of the land
#: (its outermost crests' outer halves, and the pad's grooves beyond them, lie outside the hull). The reading widens
#: each land by this many ridge periods (half on each side) and narrows each groove as much.
RIDGE_HULL_SHORTFALL = 0.5
#: Pixels are read in pairs (their mean) where the scale is this fine or finer: 2 px at 34.9 px/mm are 0.06 mm, the
#: edges are placed between samples by interpolation (the tests bound the error), and it halves the reading's cost.
BIN_FROM_PX_PER_MM = 20.0


@dataclass(frozen=True)
class ContactReading:
    """One press's contact reading: its measures (:data:`CONTACT_MEASURES`), the period used (mm) and, for drawing,
    the complete land and groove spans (start, stop in mm along the profile), the profile it was read on (the crest
    envelope on a ridged pad) and the threshold."""

    values: np.ndarray
    period_mm: float
    lands_mm: tuple[tuple[float, float], ...] = ()
    grooves_mm: tuple[tuple[float, float], ...] = ()
    read_on: np.ndarray | None = None
    threshold: np.ndarray | None = None
    #: The spacing (mm) of ``read_on`` and ``threshold``'s samples.
    step_mm: float = math.nan

    def as_dict(self) -> dict[str, float]:
        return {name: float(v) for name, v in zip(CONTACT_MEASURES, self.values)}


def unreadable() -> np.ndarray:
    """The measures of a press that cannot be read: all NaN."""
    return np.full(len(CONTACT_MEASURES), np.nan)


def band_profile(pixels: np.ndarray, box: tuple[int, int, int, int], rows: int) -> np.ndarray:
    """Gray profile (w,) 0-1: the mean of the crop's rows from its top down to the last row of the line (the rows a
    PNG is decoded to). Rows are summed before the gray weights are applied (the two commute), so only one row of
    colour is converted; 8- and 16-bit rows are summed in whole numbers (exact, and the cheapest sum)."""
    x, y, w, h = box
    stop = y + (h - rows) // 2 + rows
    block = pixels[y:stop, x:x + w]
    exact = block.dtype in (np.uint8, np.uint16)
    total = np.add.reduce(block, axis=0, dtype=np.uint32 if exact else np.float64).astype(np.float64)
    if total.ndim == 2:
        total = total[:, :3] @ np.asarray(GRAY_WEIGHTS_RGB, dtype=np.float64)
    return total / (block.shape[0] * intensity_scale(pixels.dtype))


def grating_period_px(profile: np.ndarray, px_per_mm: float, ridge_period_mm: float | None = None,
                      band_per_mm: tuple[float, float] = PERIOD_BAND_PER_MM) -> float:
    """The strongest period of the profile within the band (px; NaN if the band holds no bin): the Hann-tapered
    profile's FFT zero-padded twice, its peak refined by a parabola through the log amplitudes (a few % at worst,
    ample for the envelopes' windows and the regularity check, the only uses of the period)."""
    n = profile.size
    high = band_per_mm[1] if ridge_period_mm is None else min(band_per_mm[1], RIDGE_GUARD / ridge_period_mm)
    padded = 2 * n
    amplitude = np.abs(np.fft.rfft((profile - profile.mean()) * _hann(n), padded))
    low_bin, high_bin = math.ceil(band_per_mm[0] * padded / px_per_mm), math.floor(high * padded / px_per_mm)
    if high_bin - low_bin < 2 or high_bin >= amplitude.size - 1:
        return math.nan
    best = low_bin + int(np.argmax(amplitude[low_bin:high_bin + 1]))
    left, centre, right = np.log(np.maximum(amplitude[best - 1:best + 2], 1e-300))
    curvature = left - 2 * centre + right
    offset = 0.5 * (left - right) / curvature if curvature < 0 else 0.0
    return padded / (best + offset)


def _period_px(profile: np.ndarray, read_on: np.ndarray, px_per_mm: float, ridge_period_mm: float | None) -> float:
    """The grating's period (px) read on ``read_on``; on a ridged pad only where the raw profile's own strongest
    period in the band agrees within :data:`PERIOD_TOLERANCE` (the crest envelope alone may lock onto a moire of the
    ridges with a harmonic of the grating: a 2.5 mm grating's 0.8 mm^-1 against 1 mm^-1 ridges beats at 5 mm)."""
    period = grating_period_px(read_on, px_per_mm, ridge_period_mm)
    if ridge_period_mm is None:
        return period
    raw = grating_period_px(profile, px_per_mm, ridge_period_mm)
    return period if abs(raw - period) <= PERIOD_TOLERANCE * period else math.nan


def _noise_sd(profile: np.ndarray) -> float:
    """The profile's noise SD from the mean absolute second difference (white noise: sqrt(6) sd, times sqrt(2/pi)
    for the mean absolute value); the few edges add little to a mean over the whole line."""
    second = profile[2:] - 2.0 * profile[1:-1] + profile[:-2]
    return float(np.abs(second).mean()) / (math.sqrt(6.0) * math.sqrt(2.0 / math.pi))


def _runs(d: np.ndarray, band: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The complete runs, in order, as (start px, stop px, +1 land / -1 groove) arrays: hysteresis on d = profile -
    midpoint with half-band ``band`` where ``mask`` holds, each edge placed where d crosses 0 (interpolated between
    pixels); a run counts when edges bound it on both sides within one stretch of the mask."""
    state = np.where(d > band, 1, np.where(d < -band, -1, 0)) * mask
    confident = np.flatnonzero(state)
    empty = np.empty(0)
    if confident.size < 2:
        return empty, empty, empty.astype(int)
    stretch = np.cumsum(~mask)[confident]  # two confident points with a masked point between lie in two stretches
    states = state[confident]
    same = stretch[1:] == stretch[:-1]
    change = np.flatnonzero((states[1:] != states[:-1]) & same)
    crossings = np.flatnonzero(np.signbit(d[:-1]) != np.signbit(d[1:]))  # d changes sign between i and i + 1
    first = crossings[np.searchsorted(crossings, confident[change])]  # the first crossing after the last confident
    before, after = d[first], d[first + 1]
    position = first + before / (before - after)
    # an edge's run continues to the next edge unless a stretch ends first (the last confident point before a break)
    run_end = np.append(confident[:-1][~same], confident[-1])
    stops = np.append(position[1:], np.inf)
    complete = stops <= run_end[np.searchsorted(run_end, position)]
    return position[:-1][complete[:-1]], stops[:-1][complete[:-1]], states[change + 1][:-1][complete[:-1]]


def _cycles_regular(starts: np.ndarray, stops: np.ndarray, period_px: float) -> bool:
    """Whether the runs repeat at the period: each run with the next one beside it spans one period, within
    :data:`PERIOD_TOLERANCE`, for at least :data:`REGULAR_SHARE` of the adjacent pairs."""
    adjacent = starts[1:] == stops[:-1]
    cycles = stops[1:][adjacent] - starts[:-1][adjacent]
    if cycles.size == 0:
        return False
    return float(np.mean(np.abs(cycles - period_px) <= PERIOD_TOLERANCE * period_px)) >= REGULAR_SHARE


def read_contact(profile, px_per_mm: float, *, ridge_period_mm: float | None = None,
                 period_mm: float | None = None) -> ContactReading:
    """The contact reading of one band profile (module docstring): ``profile`` gray along the line (one value per
    px, the rows averaged), ``px_per_mm`` the scale, ``ridge_period_mm`` the pad's ridges (None: smooth),
    ``period_mm`` the grating's period if known (else read from the profile)."""
    profile = np.asarray(profile, dtype=np.float64)
    span = float(profile.max() - profile.min()) if profile.ndim == 1 and profile.size >= 16 else math.nan
    if not (math.isfinite(span) and span > 0):  # NaN or infinite pixels, a flat band, too short a line
        return ContactReading(unreadable(), math.nan)
    origin = 0.0  # where sample 0 lies, in samples from pixel 0's centre
    if px_per_mm >= BIN_FROM_PX_PER_MM:
        even = profile.size // 2 * 2
        profile, px_per_mm, origin = 0.5 * (profile[0:even:2] + profile[1:even:2]), px_per_mm / 2, 0.25
    s = profile
    if ridge_period_mm is not None:
        size = max(3, int(round(ridge_period_mm * px_per_mm)) | 1)
        s = minimum_filter1d(maximum_filter1d(s, size, mode="nearest"), size, mode="nearest")
    period_px = period_mm * px_per_mm if period_mm is not None else _period_px(profile, s, px_per_mm, ridge_period_mm)
    if not (math.isfinite(period_px) and 4 <= period_px <= profile.size / 2):
        return ContactReading(unreadable(), math.nan, read_on=s, step_mm=1.0 / px_per_mm)
    window = int(math.ceil(1.1 * period_px)) | 1
    upper = maximum_filter1d(s, window, mode="nearest")
    lower = minimum_filter1d(s, window, mode="nearest")
    middle, spread = 0.5 * (upper + lower), upper - lower
    typical = float(np.partition(spread, int(0.9 * (spread.size - 1)))[int(0.9 * (spread.size - 1))])
    floor = max(MIN_RELATIVE_RANGE * typical, MIN_NOISE_MULTIPLE * _noise_sd(profile))
    mask = (spread >= floor) & (spread >= MIN_DEPTH * np.abs(upper))
    starts, stops, states = _runs(s - middle, HYSTERESIS * spread, mask)
    widen = 0.0 if ridge_period_mm is None else RIDGE_HULL_SHORTFALL * ridge_period_mm * px_per_mm / 2
    starts_mm = (starts + origin - widen * states) / px_per_mm  # a land widened, a groove narrowed, on a ridged pad
    stops_mm = (stops + origin + widen * states) / px_per_mm
    # a land beside an incomplete run may be cut by the contact patch's end (whose baseline reads as gap): only lands
    # between two complete grooves count; a groove lies between two lands, whose edges are the grating's own
    inner = np.zeros(starts.size, dtype=bool)
    inner[1:-1] = (starts[1:-1] == stops[:-2]) & (stops[1:-1] == starts[2:])
    land, groove = (states > 0) & inner, states < 0
    period_read = period_px / px_per_mm
    values = (_measures(stops_mm[land] - starts_mm[land], stops_mm[groove] - starts_mm[groove], period_read,
                        ridge_period_mm) if _cycles_regular(starts, stops, period_px) else unreadable())
    return ContactReading(values, period_read, tuple(zip(starts_mm[land].tolist(), stops_mm[land].tolist())),
                          tuple(zip(starts_mm[groove].tolist(), stops_mm[groove].tolist())), s, middle,
                          1.0 / px_per_mm)


def _typical(widths: np.ndarray, period_mm: float) -> np.ndarray:
    """The runs of typical width: within :data:`PERIOD_TOLERANCE` of the period from their median. A land split by
    a smudge, or cut where the contact patch ends, is no whole land."""
    ordered = np.sort(widths)
    middle = 0.5 * (ordered[(ordered.size - 1) // 2] + ordered[ordered.size // 2])
    return ordered[np.abs(ordered - middle) <= PERIOD_TOLERANCE * period_mm]


def _measures(land: np.ndarray, groove: np.ndarray, period_mm: float, ridge_period_mm: float | None = None
              ) -> np.ndarray:
    """land_mm, groove_mm, land_fraction, width_se_mm from the complete runs' widths (mm); NaN without confidence.
    On a ridged pad the standard error includes the hull's quantisation, uniform over a ridge period (R / sqrt 12), which every
    land of a press may share."""
    if land.size < MIN_RUNS or groove.size < MIN_RUNS:
        return unreadable()
    land, groove = _typical(land, period_mm), _typical(groove, period_mm)
    if land.size < MIN_RUNS or groove.size < MIN_RUNS:
        return unreadable()
    land_mm, groove_mm = float(land.sum()) / land.size, float(groove.sum()) / groove.size
    se = math.sqrt(max(float(np.square(land - land_mm).sum()) / (land.size - 1) / land.size,
                       float(np.square(groove - groove_mm).sum()) / (groove.size - 1) / groove.size))
    if ridge_period_mm is not None:
        se = math.hypot(se, ridge_period_mm / math.sqrt(12.0))
    return np.array([land_mm, groove_mm, land_mm / (land_mm + groove_mm), se])


def contact_measures(profile, px_per_mm: float, *, ridge_period_mm: float | None = None,
                     period_mm: float | None = None) -> np.ndarray:
    """:data:`CONTACT_MEASURES` of one band profile, (len(CONTACT_MEASURES),) float64 (:func:`read_contact`)."""
    return read_contact(profile, px_per_mm, ridge_period_mm=ridge_period_mm, period_mm=period_mm).values
