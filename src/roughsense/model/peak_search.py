"""The peak law's features: where a contact spectrum peaks (refined below the grid by a log-parabola), how high,
and the contact's shape (its second harmonic's ratio), read per press or per surface; and the law's terms and its
batched Huber fit on them. model/peak_law/law.py says why the law reads these and no others.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._util.checks import POSITIVE, POSITIVE_INT, AnyOf, Described, check_params
from ..errors import ConfigError, InputError
from ..sensor.band import RIDGE_EXCLUSION_PER_MM
from ..sensor.grid import grid_step
from ..sensor.shape import harmonic_ratio
from .huber_batch import HUBER_EPSILON, huber_irls
from .press_spread import deviations

#: What the peak readout gives per row. The law's terms are the first and, where every training surface shows it,
#: the third (:func:`law_terms`); the peak amplitude did not earn a term under LOSO and bounds the domain only
#: (docs/peak_law.md, benchmarks/bench_shape_terms.py).
FEATURE_NAMES = ("log_peak_frequency_per_mm", "log_peak_amplitude", "log_second_harmonic_ratio")
#: The features' columns: where the peak is, how high, and the contact's shape (sensor/shape.py).
FREQUENCY, AMPLITUDE, HARMONIC = 0, 1, 2
#: Least spread (log units) of the training surfaces' second-harmonic ratios for the ratio to be a term: two shapes.
#: A square grating's ratio lies near -4 and a semi-cylinder's near -1 on the twin; within one shape they spread
#: by under 0.6 (seeds 0-2), so 1 separates "one shape" from "several".
SHAPE_SPREAD = 1.0
#: A press agrees with its surface's peak when its own peak lies within this many grid bins of it.
AGREEMENT_BINS = 1.5
#: The law's settings and what each must be (scikit-learn's ``_parameter_constraints``, in roughsense's vocabulary).
SETTINGS = {
    "n_blocks": Described(POSITIVE_INT, "a positive whole number"),
    "pad_ridge_period_mm": Described(AnyOf(POSITIVE, None), "a positive number of mm or None"),
    "exclusion_per_mm": Described(POSITIVE, "a positive number"),
    "epsilon": Described(POSITIVE, "a positive number"),
}


class PeakLawConfigError(ConfigError, ValueError):
    """An impossible setting of the law (its grid, blocks, epsilon, ridge exclusion); a ValueError for scikit-learn."""


class PeakLawInputError(InputError, ValueError):
    """Spectra, targets, groups or surfaces the law cannot use; also a ValueError for scikit-learn."""


def search_bins(freq_per_mm: np.ndarray, pad_ridge_period_mm: float | None, exclusion_per_mm: float) -> np.ndarray:
    """Which grid bins may hold the surface's peak: interior bins, away from the pad's own ridge frequency."""
    freq_per_mm = np.asarray(freq_per_mm, dtype=np.float64)
    allowed = np.ones(freq_per_mm.size, dtype=bool)
    if freq_per_mm.size >= 3:  # a coarser grid has no interior bin: every bin may then be the peak
        allowed[[0, -1]] = False
    if pad_ridge_period_mm is not None:
        allowed &= np.abs(freq_per_mm - 1.0 / float(pad_ridge_period_mm)) > float(exclusion_per_mm)
    if not allowed.any():
        raise PeakLawConfigError(
            f"no frequency of the band {freq_per_mm[0]:g}-{freq_per_mm[-1]:g} mm^-1 is left to search for a peak "
            f"(pad ridge period {pad_ridge_period_mm} mm excluded +-{exclusion_per_mm:g} mm^-1)")
    return allowed


def check_grid(freq_per_mm, min_bins: int = 3) -> np.ndarray:
    """The spectra's frequency grid as floats: at least ``min_bins`` positive, evenly spaced, increasing values.

    The peak's sub-bin refinement steps by the grid spacing, so an uneven or unordered grid would misplace it.
    """
    freq = np.asarray(freq_per_mm, dtype=np.float64)
    steps = np.diff(freq) if freq.ndim == 1 else np.zeros(0)
    if freq.ndim != 1 or freq.size < min_bins or freq.size == 0 or not np.all(np.isfinite(freq)) or freq[0] <= 0 \
            or not np.all(steps > 0) or (steps.size and not np.allclose(steps, steps[0], rtol=1e-6)):
        raise PeakLawConfigError(f"freq_per_mm must be at least {min_bins} positive, evenly spaced, increasing "
                                 f"frequencies (mm^-1), got {np.array2string(freq.ravel()[:6], precision=4)}")
    return freq


def check_settings(**settings) -> dict:
    """The settings given, each checked against :data:`SETTINGS` (a bool is no number) and cast (ints, floats)."""
    return check_params(settings, SETTINGS, error=PeakLawConfigError)


def _check_spectra(spectra: np.ndarray) -> None:
    if not np.all(np.isfinite(spectra)):
        raise PeakLawInputError("spectra contain NaN or infinite values")
    if np.any(spectra < 0):
        raise PeakLawInputError("Negative values in data passed to PeakPowerLaw: spectra are amplitudes")


def peak_features(spectra, freq_per_mm, *, n_blocks: int = 1, pad_ridge_period_mm: float | None = None,
                  exclusion_per_mm: float = RIDGE_EXCLUSION_PER_MM, surfaces=None) -> np.ndarray:
    """(n, 3) log peak frequency (mm^-1), log peak amplitude and log second-harmonic ratio (NaN where it cannot be
    read, sensor/shape.py) of each row's spectrum.

    A row holds ``n_blocks`` spectra side by side (a combined-force trial); they are averaged first, so the peak is
    read from the trial's mean spectrum (the grating's peak stays where it is at every force; noise averages out).

    ``surfaces`` (one label per row, or None): rows with the same label are presses of one surface. Where the peak
    *is* belongs to the surface, so it is read once from the mean spectrum of its rows; how *strong* it is belongs to
    each press, so every row's amplitude is its own log-parabola at that place. A single press on a fingerprint pad
    can show no grating at all (contact on the ridge tips only) or a shading hump taller than the grating; the mean
    of a surface's presses shows the grating (docs/peak_law.md).
    """
    return peak_readout(spectra, freq_per_mm, n_blocks=n_blocks, pad_ridge_period_mm=pad_ridge_period_mm,
                        exclusion_per_mm=exclusion_per_mm, surfaces=surfaces).features


@dataclass(frozen=True)
class PeakReadout:
    """What the peak search saw, per row: the law's two features, and how clearly the row's surface shows a peak.

    ``clarity``: log height of the surface's peak above the median of its search band (a grating stands out by
    several log units; a spectrum with no grating in the band, by about one). ``agreement``: the share of the
    surface's presses whose own peak lies within :data:`AGREEMENT_BINS` bins of the surface's (1 for one press).
    ``presses``: how many presses the row's surface was read from (model/press_spread.py widens its flag margins).
    ``overshoot``: log of how far the second harmonic lies past the band's readable end (<= 0 inside it).
    """

    features: np.ndarray
    clarity: np.ndarray
    agreement: np.ndarray
    presses: np.ndarray | None = None
    overshoot: np.ndarray | None = None


def peak_readout(spectra, freq_per_mm, *, n_blocks: int = 1, pad_ridge_period_mm: float | None = None,
                 exclusion_per_mm: float = RIDGE_EXCLUSION_PER_MM, surfaces=None) -> PeakReadout:
    """:func:`peak_features` with the clarity and agreement of each row's surface (:class:`PeakReadout`)."""
    freq = check_grid(freq_per_mm, min_bins=1)  # the estimator's default grid may be coarser than 3 bins
    n_blocks = check_settings(n_blocks=n_blocks, pad_ridge_period_mm=pad_ridge_period_mm,
                              exclusion_per_mm=exclusion_per_mm)["n_blocks"]
    spectra = np.asarray(spectra, dtype=np.float64)
    if spectra.ndim != 2:
        raise PeakLawInputError(f"spectra must be a 2-D array (rows x features), got shape {spectra.shape}")
    _check_spectra(spectra)
    n, width = spectra.shape
    k_bins = freq.size
    if width != n_blocks * k_bins:
        raise PeakLawInputError(f"{width} features are not {n_blocks} block(s) of the {k_bins}-frequency grid")
    mean = spectra.reshape(n, n_blocks, k_bins).mean(axis=1)
    allowed = search_bins(freq, pad_ridge_period_mm, exclusion_per_mm)
    log_amp = _log(mean)
    own_peak, own_offset = _peak_positions(log_amp, allowed)
    if surfaces is None:
        peak, offset, surface_log = own_peak, own_offset, log_amp
        amplitude = _vertex_height(log_amp, peak, offset)
        agreement, presses = np.ones(n), np.ones(n)
    else:
        codes = surface_codes(surfaces, n)
        sums = np.zeros((int(codes.max()) + 1 if n else 0, k_bins))
        np.add.at(sums, codes, mean)
        surface_log = _log(sums / np.bincount(codes)[:, None])
        peak, offset = _peak_positions(surface_log, allowed)
        surface_top = peak + offset
        peak, offset = peak[codes], offset[codes]
        amplitude = _parabola_at(log_amp, peak, offset)
        near = np.abs(own_peak + own_offset - surface_top[codes]) <= AGREEMENT_BINS
        agreement = (np.bincount(codes, weights=near) / np.bincount(codes))[codes]
        presses = np.bincount(codes)[codes].astype(np.float64)
        surface_log = surface_log[codes]
    step = grid_step(freq)
    frequency = freq[peak] + offset * step
    clarity = _parabola_at(surface_log, peak, offset) - np.median(surface_log[:, allowed], axis=1)
    # The shape belongs to the surface, like where its peak is: read on the surface's mean spectrum.
    harmonic = harmonic_ratio(surface_log, freq, frequency, pad_ridge_period_mm, exclusion_per_mm) if k_bins > 1 \
        else np.full(n, np.nan)
    overshoot = np.log(2 * frequency / (freq[-1] + step)) if k_bins > 1 else np.zeros(n)
    return PeakReadout(np.column_stack([np.log(frequency), amplitude, harmonic]), clarity, agreement, presses,
                       overshoot)


def press_deviations(spectra, surface: PeakReadout, **reading) -> np.ndarray:
    """(n, 4) each press read alone less its surface's reading ``surface`` (the three features, the clarity):
    the scatter model/press_spread.py sets the flag margins from. ``reading``: :func:`peak_readout`'s settings."""
    alone = peak_readout(spectra, **reading)
    return deviations(alone.features, alone.clarity, surface.features, surface.clarity)


def surface_codes(surfaces, n: int) -> np.ndarray:
    """Integer codes 0..S-1 of the rows' surface labels (order of first appearance), checked against ``n`` rows."""
    labels = np.asarray(surfaces)
    if labels.ndim != 1 or labels.shape[0] != n:
        raise PeakLawInputError(f"surfaces must give one label per row ({n}), got shape {labels.shape}")
    _, first, codes = np.unique(labels, return_index=True, return_inverse=True)
    order = np.argsort(np.argsort(first))  # relabel by first appearance, so codes do not depend on sorting labels
    return order[codes.ravel()]


def _log(amplitudes: np.ndarray) -> np.ndarray:
    return np.log(np.maximum(amplitudes, np.finfo(np.float64).tiny))


def _peak_positions(log_amp: np.ndarray, allowed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each row's peak bin (highest allowed local maximum) and its sub-bin offset in [-0.5, 0.5] (log-parabola)."""
    n, k_bins = log_amp.shape
    local_max = np.zeros_like(allowed, shape=log_amp.shape)
    local_max[:, 1:-1] = (log_amp[:, 1:-1] >= log_amp[:, :-2]) & (log_amp[:, 1:-1] >= log_amp[:, 2:])
    candidates = allowed & local_max
    # A spectrum with no interior local maximum in the search band (monotone there) falls back to its highest bin.
    candidates[~candidates.any(axis=1)] = allowed
    peak = np.argmax(np.where(candidates, log_amp, -np.inf), axis=1)
    rows = np.arange(n)
    interior = (peak > 0) & (peak < k_bins - 1)
    left = log_amp[rows, np.maximum(peak - 1, 0)]
    centre = log_amp[rows, peak]
    right = log_amp[rows, np.minimum(peak + 1, k_bins - 1)]
    curvature = left - 2.0 * centre + right
    concave = interior & (curvature < 0)
    offset = np.zeros(n)
    offset[concave] = 0.5 * (left[concave] - right[concave]) / curvature[concave]
    return peak, np.clip(offset, -0.5, 0.5)


def _vertex_height(log_amp: np.ndarray, peak: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """A row's peak height read at its own (clipped) vertex offset: the centre bin less the parabola's rise."""
    rows = np.arange(log_amp.shape[0])
    left = log_amp[rows, np.maximum(peak - 1, 0)]
    right = log_amp[rows, np.minimum(peak + 1, log_amp.shape[1] - 1)]
    return log_amp[rows, peak] - 0.25 * (left - right) * offset


def _parabola_at(log_amp: np.ndarray, peak: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Each row's log-parabola through bins peak-1, peak, peak+1, evaluated ``offset`` bins from ``peak``.

    At a row's own vertex this is the vertex's height; at an end bin (no neighbour on one side) the bin itself.
    """
    n, k_bins = log_amp.shape
    rows = np.arange(n)
    left = log_amp[rows, np.maximum(peak - 1, 0)]
    centre = log_amp[rows, peak]
    right = log_amp[rows, np.minimum(peak + 1, k_bins - 1)]
    interior = (peak > 0) & (peak < k_bins - 1)
    value = centre + 0.5 * (right - left) * offset + 0.5 * (left - 2.0 * centre + right) * offset**2
    return np.where(interior, value, centre)


def shape_read(features: np.ndarray, train: np.ndarray, grouped: bool = True) -> np.ndarray:
    """(F,) whether each training mask reads the contact's shape: every training row shows its second harmonic (a
    fingerprint pad hides it for a 2 mm grating) and rows are grouped into surfaces (``grouped``: a shape is a
    surface's, read on its presses' mean; one press's ratio is noise). Where it does, the shape bounds the domain."""
    if not grouped or features.shape[1] <= HARMONIC:
        return np.zeros(train.shape[0], dtype=bool)
    return ~np.any(train & ~np.isfinite(features[:, HARMONIC])[None, :], axis=1)


def law_terms(features: np.ndarray, train: np.ndarray, grouped: bool = True) -> np.ndarray:
    """(F, p) the features each training mask's law regresses on: the peak frequency always; the second-harmonic
    ratio where the shape is read (:func:`shape_read`) and the training surfaces differ in it by at least
    :data:`SHAPE_SPREAD` (one shape alone teaches no slope: its ratios differ by noise, which a free term would
    carry, magnified, to any other shape); the amplitude never."""
    terms = np.zeros((train.shape[0], features.shape[1]), dtype=bool)
    terms[:, FREQUENCY] = True
    read = shape_read(features, train, grouped)
    if read.any():
        ratio = np.where(np.isfinite(features[:, HARMONIC]), features[:, HARMONIC], 0.0)[None, :]
        spread = np.where(train, ratio, -np.inf).max(axis=1) - np.where(train, ratio, np.inf).min(axis=1)
        terms[:, HARMONIC] = read & (spread >= SHAPE_SPREAD)
    return terms


def fit_terms(features: np.ndarray, targets: np.ndarray, train: np.ndarray, *, epsilon: float = HUBER_EPSILON,
              grouped: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """:func:`huber_irls` on each mask's :func:`law_terms`: coefficients (F, B, p + 1), 0 for a feature that is no
    term, and scales (F, B). Masks sharing terms are one batch."""
    terms = law_terms(features, train, grouped)
    n_folds, n_targets = train.shape[0], targets.shape[0]
    beta = np.zeros((n_folds, n_targets, features.shape[1] + 1))
    scale = np.empty((n_folds, n_targets))
    for pattern in np.unique(terms, axis=0):
        folds = np.all(terms == pattern, axis=1)
        # A row outside a mask may lack a term's value: zero-filled, it carries weight 0 there.
        part, part_scale = huber_irls(np.nan_to_num(features[:, pattern]), targets, train[folds], epsilon=epsilon)
        beta[np.ix_(folds, np.arange(n_targets), np.r_[0, 1 + np.flatnonzero(pattern)])] = part
        scale[folds] = part_scale
    return beta, scale


def held_features(features: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Features held to the domain [low, high] (broadcast); one that cannot be read (NaN) is put at the middle of
    its range (0 where the range is unbounded: a feature that is no term)."""
    bounded = np.isfinite(low) & np.isfinite(high)
    middle = 0.5 * (np.where(bounded, low, 0.0) + np.where(bounded, high, 0.0))
    return np.clip(np.where(np.isnan(features), middle, features), low, high)
