"""Peak power law: perceived roughness as a power law of where the contact spectrum peaks, and of the contact's shape.

Why a second model. PLS is linear in the 45 amplitudes, and each grating puts its fundamental into bins that no other
training grating excites, so for a surface it never saw it has nothing to go on (under leave-one-specimen-out the
paper's PLS sits at the training mean's error). Roughness that people perceive by spatial coding grows with the
spacing of the contact pattern, and the spacing *moves* the spectrum's peak: a law in where the peak is (and how
strongly the contact concentrates there) extrapolates to a period between, or just beside, the trained ones.

The law, in logs, with 2 or 3 parameters::

    log(roughness) = b0 + b1 * log(peak frequency, mm^-1) [+ b3 * log(A(2 f0) / A(f0))]

- *Peak frequency*: the highest local maximum of the spectrum (averaged over a trial's forces), refined below the
  grid spacing by a parabola through the log amplitudes of the peak bin and its two neighbours (exact for a Gaussian
  lobe, which a Hann-windowed line's main lobe nearly is). The band's two end bins are never peaks (no neighbour on
  one side), and a fingerprint pad's own ridge frequency, 1 / ``pad_ridge_period_mm``, is excluded with
  ``exclusion_per_mm`` on either side: its relief is a pattern of the pad, not of the surface.
- *Peak amplitude*: the log amplitude at the refined peak. It earned no term under leave-one-specimen-out (its
  coefficient is 0) and bounds the domain only.
- *Shape*: the second harmonic's log ratio to the fundamental (sensor/shape.py: a square grating's is far below 0, a
  narrow contact's near 0), read on the surface's mean spectrum. A term only where every training surface shows it
  and they span more than one shape (:func:`law_terms`); it bounds the domain wherever it is read.
- *Fit*: Huber's M-estimator (epsilon 1.345, scale by the median absolute residual, iteratively reweighted least
  squares), because an image whose peak was misread (a fingerprint pad's lobe or a low-frequency shading hump) is an
  outlier that least squares would follow.
- *Surfaces*: rows labelled as presses of one surface share where its peak is (read from their mean spectrum);
  each keeps its own peak amplitude there (:func:`peak_features`).
- *Prediction*: features are clipped to the range of the training rows the fit kept (a power law is not carried
  past its data), and :meth:`PeakPowerLaw.applicability` says, in a user's words, what lies outside what the law
  was fitted on (period, peak strength, contact pattern, a spectrum with no clear peak, presses that disagree).

Nothing is chosen from the targets: the features, the rule for the terms (spectra only) and epsilon are fixed, so
cross-validating the fit is
all the nesting there is (docs/peak_law.md says how they were chosen, and on which data). Every fold of a
cross-validation, and every shuffled target of the permutation control, is fitted in one batched IRLS
(:func:`peak_law_cv`), the same arithmetic as a refit of :class:`PeakPowerLaw` on that fold.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from .._util.checks import POSITIVE, POSITIVE_INT, AnyOf, Described, check_params
from ..errors import ConfigError, InputError
from ..sensor.shape import duty_cycle, harmonic_ratio
from ..sensor.spectrum import grid_step
from .families import PEAK_LAW as NAME  # noqa: F401 (the family's name, beside its class)
from .huber_batch import HUBER_EPSILON, distinct_masks, huber_irls, row_classes
from .press_spread import PressScatter, deviations, robust_spread, trained_presses

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
#: Half-width (mm^-1) of the band around the pad's ridge frequency left out of the peak search: the Hann main lobe of
#: a 54 mm line is +-0.037 mm^-1, widened for the bench's magnification jitter and the ridges' sidebands.
DEFAULT_EXCLUSION_PER_MM = 0.1
#: The paper's band when a caller gives no grid: n evenly spaced frequencies over 0.1-1.0 mm^-1.
_DEFAULT_BAND_PER_MM = (0.1, 1.0)
#: A training row counts as kept by the Huber fit when its final weight is at least this (|residual| <= 2 epsilon
#: scale): its features bound the range the law is applied in (:func:`kept_rows`).
KEPT_WEIGHT = 0.5
#: A press agrees with its surface's peak when its own peak lies within this many grid bins of it.
AGREEMENT_BINS = 1.5
#: Slack (log units, a factor 1.65) on the peak's strength and a surface's clarity before a row counts as outside
#: what was trained: held-out gratings like the trained ones lay up to 0.43 beyond the others on seeds 0-2 (a
#: 2.5 mm press's strength; a 4 mm surface's clarity on the fingerprint pad by 0.3), where the flagged 0.5 and 1 mm
#: gratings' surfaces stood 0.6-1.9 below.
LOG_MARGIN = 0.5
#: Presses of one surface that peak elsewhere than the surface: below this share, there is no one period to read.
MIN_AGREEMENT = 1 / 3
#: Features more than this (in log units) outside the training range count as extrapolation (rounding aside).
_RANGE_TOL = 1e-9
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


# --------------------------------------------------------------------------- features that move with the surface


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
                  exclusion_per_mm: float = DEFAULT_EXCLUSION_PER_MM, surfaces=None) -> np.ndarray:
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
                 exclusion_per_mm: float = DEFAULT_EXCLUSION_PER_MM, surfaces=None) -> PeakReadout:
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


# --------------------------------------------------------------------------- the estimator


class PeakPowerLaw(RegressorMixin, BaseEstimator):
    """scikit-learn regressor: spectra (n, n_blocks x K) -> perceived roughness, by a power law of the spectrum's peak.

    roughness = exp(intercept + coef . (log peak frequency, log peak amplitude, log second-harmonic ratio)), fitted by
    Huber regression in logs on its terms (:func:`law_terms`; a feature that is no term has coefficient 0).

    ``freq_per_mm``: the spectra's grid (K frequencies; default K evenly spaced over 0.1-1.0 mm^-1);
    ``n_blocks``: spectra per row (3 for a combined-force trial); ``pad_ridge_period_mm``: the pad's ridge period
    (a fingerprint pad's), whose frequency is left out of the peak search; ``epsilon``: Huber's constant.
    ``fit``, ``predict`` and ``applicability`` take ``surfaces`` (one label per row; rows of one surface share
    where its peak is, read on their mean spectrum).
    Fitted: ``coef_`` (3,), ``intercept_``, ``scale_`` (robust residual SD, log units), ``feature_min_`` and
    ``feature_max_`` (the range of the rows the Huber fit kept, weight >= 0.5, used to clip and to flag),
    ``press_scatter_`` (the training presses' robust scatter about their surfaces, which widens the flag for a
    surface read from fewer presses than the trained ones, model/press_spread.py; None without ``surfaces``),
    ``freq_per_mm_``.

    Parameters
    ----------
    freq_per_mm : array-like, optional
        (K,) the spectra's frequencies in mm^-1; default K evenly spaced over 0.1-1.0.
    n_blocks : int
        Spectra side by side in a row (3 for a combined-force trial).
    pad_ridge_period_mm : float, optional
        A fingerprint pad's ridge period (mm): its frequency is no surface's peak.
    exclusion_per_mm : float
        How far either side of the pad's ridge frequency is left out (mm^-1).
    epsilon : float
        Huber's constant: residuals beyond ``epsilon`` robust SDs are down-weighted.

    Examples
    --------
    Spectra peaking at 1/period, from gratings of 2-5 mm, two presses each:

    >>> import numpy as np
    >>> import roughsense as rs
    >>> f = rs.frequency_grid()
    >>> periods = np.repeat([2.0, 3.0, 4.0, 5.0], 2)
    >>> X = np.exp(-((f - 1 / periods[:, None]) / 0.05) ** 2) + 0.01
    >>> y = (periods / 3) ** 0.9  # perceived roughness grows with the period
    >>> law = rs.PeakPowerLaw().fit(X, y)
    >>> law.predict(X[::2]).round(2)
    array([0.69, 1.  , 1.3 , 1.58])
    >>> unseen = np.exp(-((f - 1 / np.array([[2.5], [8.0]])) / 0.05) ** 2) + 0.01
    >>> law.predict(unseen).round(2)  # 8 mm lies beyond the law's domain: held at its edge
    array([0.85, 1.66])
    >>> law.applicability(unseen)
    ['', 'period 8.00 mm outside the trained 2.00-5.00 mm']
    """

    def __init__(self, freq_per_mm=None, n_blocks: int = 1, pad_ridge_period_mm: float | None = None,
                 exclusion_per_mm: float = DEFAULT_EXCLUSION_PER_MM, epsilon: float = HUBER_EPSILON) -> None:
        self.freq_per_mm = freq_per_mm
        self.n_blocks = n_blocks
        self.pad_ridge_period_mm = pad_ridge_period_mm
        self.exclusion_per_mm = exclusion_per_mm
        self.epsilon = epsilon

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.positive_only = True  # amplitude spectra
        tags.target_tags.positive_only = True  # magnitude estimates
        tags.regressor_tags.poor_score = True  # a 3-parameter law scores poorly on arbitrary data, by design
        return tags

    def _grid(self, n_features: int) -> np.ndarray:
        blocks = check_settings(n_blocks=self.n_blocks)["n_blocks"]
        if n_features % blocks:
            raise PeakLawInputError(f"{n_features} feature(s) cannot be split into {blocks} equal spectra")
        k_bins = n_features // blocks
        if self.freq_per_mm is None:
            return np.linspace(*_DEFAULT_BAND_PER_MM, k_bins)
        freq = check_grid(self.freq_per_mm)
        if freq.size != k_bins:
            raise PeakLawInputError(
                f"{n_features} feature(s) in {blocks} block(s) do not match the {freq.size}-frequency grid")
        return freq

    def _check_params(self) -> None:
        check_settings(pad_ridge_period_mm=self.pad_ridge_period_mm, exclusion_per_mm=self.exclusion_per_mm,
                       epsilon=self.epsilon)

    def features(self, X, surfaces=None) -> np.ndarray:
        """The peak readout of each row (log peak frequency, log peak amplitude, log second-harmonic ratio).

        Parameters
        ----------
        X : array-like
            (n_samples, n_blocks x K) spectra.
        surfaces : array-like, optional
            (n_samples,) labels: rows of one surface share where its peak is read.

        Returns
        -------
        numpy.ndarray
            (n_samples, 3) as :data:`FEATURE_NAMES` (the ratio NaN where it cannot be read).
        """
        check_is_fitted(self)
        X = validate_data(self, X, reset=False, ensure_min_samples=1)
        _check_positive(X)
        return self._features(X, surfaces)

    def _features(self, X: np.ndarray, surfaces=None) -> np.ndarray:
        return self._readout(X, surfaces).features

    def _reading(self) -> dict:
        return {"freq_per_mm": self.freq_per_mm_, "n_blocks": int(self.n_blocks),
                "pad_ridge_period_mm": self.pad_ridge_period_mm, "exclusion_per_mm": float(self.exclusion_per_mm)}

    def _readout(self, X: np.ndarray, surfaces=None) -> PeakReadout:
        return peak_readout(X, **self._reading(), surfaces=surfaces)

    def fit(self, X, y, surfaces=None):
        """Fit the law by Huber's M-estimator and record the range of the rows it kept.

        Parameters
        ----------
        X : array-like
            (n_samples, n_blocks x K) spectra (non-negative amplitudes).
        y : array-like
            (n_samples,) perceived roughness, positive (the law is fitted in logs).
        surfaces : array-like, optional
            (n_samples,) labels: rows of one surface share where its peak is read.

        Returns
        -------
        PeakPowerLaw
            This estimator, fitted.
        """
        self._check_params()
        X, y = validate_data(self, X, y, y_numeric=True, ensure_min_samples=2)
        _check_positive(X)
        y = np.asarray(y, dtype=np.float64)
        if np.any(y <= 0):
            raise PeakLawInputError(
                "perceived roughness must be positive (magnitude estimates); the law is fitted in logs")
        self.freq_per_mm_ = self._grid(X.shape[1])
        readout = self._readout(X, surfaces)
        features = readout.features
        beta, scale = fit_terms(features, np.log(y)[None, :], np.ones((1, len(y)), dtype=bool),
                                epsilon=float(self.epsilon), grouped=surfaces is not None)
        self.intercept_ = float(beta[0, 0, 0])
        self.coef_ = beta[0, 0, 1:].copy()
        self.scale_ = float(scale[0, 0])
        kept = kept_rows(features, np.log(y), beta[0, 0], self.scale_, float(self.epsilon), surfaces)
        low, high = kept_range(features, kept[None, None],
                               shape_read(features, np.ones((1, len(y)), dtype=bool), surfaces is not None))
        self.feature_min_, self.feature_max_ = low[0, 0], high[0, 0]
        self.clarity_limit_ = float(readout.clarity[kept].min()) - LOG_MARGIN
        everything = np.ones((1, len(y)), dtype=bool)
        self.press_scatter_ = None if surfaces is None else PressScatter(
            robust_spread(press_deviations(X, readout, **self._reading()), everything)[0],
            float(trained_presses(surface_codes(surfaces, len(y)), everything)[0]))
        return self

    def predict(self, X, surfaces=None) -> np.ndarray:
        """Perceived roughness by the law, each feature held to the law's domain.

        Parameters
        ----------
        X : array-like
            (n_samples, n_blocks x K) spectra.
        surfaces : array-like, optional
            (n_samples,) labels: rows of one surface share where its peak is read.

        Returns
        -------
        numpy.ndarray
            (n_samples,) predictions (positive).
        """
        return predict_law(self.features(X, surfaces), self.intercept_, self.coef_,
                           *domain_margins(grid_step(self.freq_per_mm_), self.feature_min_, self.feature_max_))

    def extrapolates(self, X, surfaces=None) -> np.ndarray:
        """True for each row outside the law's applicability domain (:meth:`applicability` gives the reasons).

        Parameters
        ----------
        X, surfaces
            As :meth:`predict`.

        Returns
        -------
        numpy.ndarray
            (n_samples,) booleans.
        """
        return np.array([bool(reason) for reason in self.applicability(X, surfaces)], dtype=bool)

    def applicability(self, X, surfaces=None) -> list[str]:
        """Per row, what lies outside what the law was fitted on, in a user's words ('' where nothing does).

        Parameters
        ----------
        X, surfaces
            As :meth:`predict`.

        Returns
        -------
        list of str
            One reason per row: period or peak strength beyond the trained range, no clear peak, presses that
            disagree; '' where the row is inside.
        """
        check_is_fitted(self)
        X = validate_data(self, X, reset=False, ensure_min_samples=1)
        _check_positive(X)
        return domain_reasons(self._readout(X, surfaces), self.feature_min_, self.feature_max_, self.clarity_limit_,
                              grid_step(self.freq_per_mm_), self.press_scatter_)


def kept_rows(features: np.ndarray, log_y: np.ndarray, beta: np.ndarray, scale: float, epsilon: float,
              surfaces=None) -> np.ndarray:
    """The rows the Huber fit kept: final weight at least :data:`KEPT_WEIGHT` (|residual| <= 2 epsilon scale).

    A misread peak is down-weighted, not dropped, so the raw training range would include it: a law trained on a
    1N fingerprint study with one press read at 0.13 mm^-1 would then call an 8 mm grating "inside". The range of
    the kept rows is the range the law was actually fitted on. With ``surfaces``, a surface most of whose presses
    are down-weighted keeps them all: its *rating* is what the law misses, and its features are real.
    """
    residual = log_y - beta[0] - np.nan_to_num(features) @ beta[1:]  # a NaN feature is no term: coefficient 0
    return _kept(np.abs(residual)[None, None], np.array([[scale]]), epsilon, np.ones((1, len(log_y)), bool),
                 surfaces)[0, 0]


def _kept(absolute: np.ndarray, scale: np.ndarray, epsilon: float, train: np.ndarray, surfaces) -> np.ndarray:
    """(F, B, n) kept training rows from absolute residuals (F, B, n), scales (F, B) and training masks (F, n)."""
    kept = (absolute <= epsilon * scale[:, :, None] / KEPT_WEIGHT * (1 + 1e-12)) & train[:, None, :]
    if surfaces is not None:
        codes = surface_codes(surfaces, absolute.shape[-1])
        members = np.zeros((codes.size, int(codes.max()) + 1))
        members[np.arange(codes.size), codes] = 1.0
        trained = train.astype(float) @ members  # (F, S) training presses of each surface
        share = (kept.astype(float) @ members) / np.maximum(trained, 1.0)[:, None, :]
        kept |= (share < 0.5)[:, :, codes] & train[:, None, :]
    return np.where(kept.any(axis=2, keepdims=True), kept, train[:, None, :])


def predict_law(features: np.ndarray, intercept: float, coef: np.ndarray, low: np.ndarray, high: np.ndarray
                ) -> np.ndarray:
    """exp(intercept + clip(features) . coef): the law's prediction, features held to [low, high] (the law's
    domain, :func:`domain_margins`)."""
    return np.exp(intercept + held_features(features, low, high) @ np.asarray(coef, dtype=np.float64))


def outside_each(features: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """(n, p) booleans: which of a row's features lies outside the range (rounding aside; NaN is not outside)."""
    return (features < low - _RANGE_TOL) | (features > high + _RANGE_TOL)


def domain_margins(freq_step_per_mm: float, low: np.ndarray, high: np.ndarray, extra=None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The law's domain: the kept training range (``low``, ``high``: (..., 2)) widened by what a feature may lie
    beyond it and still count as inside. The law is applied unclipped inside and held at the domain's edge outside,
    so a prediction is held exactly when it is flagged (for a surface read from fewer presses than the trained ones,
    only beyond its presses' scatter, ``extra``, is it flagged).

    The period is read to about half a grid bin, so two gratings of one period can read 1-2 % apart: half a bin
    either side of the trained frequencies. The peak strength varies from press to press by more than that:
    :data:`LOG_MARGIN` either side. ``extra`` (n, p): a surface of few presses' excess scatter
    (model/press_spread.py), added in quadrature: (n, p) margins, for the flags only.
    """
    step = float(freq_step_per_mm)
    low, high = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    below, above = np.full(low.shape, LOG_MARGIN), np.full(high.shape, LOG_MARGIN)
    below[..., 0] = np.log1p(0.5 * step / np.exp(low[..., 0]))
    above[..., 0] = np.log1p(0.5 * step / np.exp(high[..., 0]))
    if extra is not None:
        below, above = np.hypot(below, extra), np.hypot(above, extra)
    return low - below, high + above


def range_reasons(features: np.ndarray, low: np.ndarray, high: np.ndarray, *, shown=None, tolerated=None
                  ) -> list[str]:
    """Per row, what lies outside the range [low, high] (margins included), in a user's words ('' where nothing).

    The frequency is said as a period (what a user designs), the amplitude as the peak's strength; ``shown``: the
    range the message quotes (the trained one, without the margins), default [low, high].
    """
    outside = outside_each(features, low, high)
    # The law reads the contact's shape where its range is bounded; a row whose shape cannot be read is then unsure.
    unread = np.isnan(features) & np.isfinite(low) & np.isfinite(high)
    if tolerated is not None:  # a shape unread only because the period's scatter put its harmonic past the band
        unread[:, HARMONIC:] &= ~np.asarray(tolerated, dtype=bool)[:, None]
    low, high = (low, high) if shown is None else shown
    reasons = []
    for row, out, blind in zip(features, outside, unread):
        parts = []
        if out[FREQUENCY]:
            parts.append(f"period {np.exp(-row[0]):.2f} mm outside the trained {np.exp(-high[0]):.2f}-"
                         f"{np.exp(-low[0]):.2f} mm")
        if out[AMPLITUDE]:
            side = "weaker" if row[1] < low[1] else "stronger"
            parts.append(f"peak strength {np.exp(row[1]):.3g} {side} than any trained ({np.exp(low[1]):.3g}-"
                         f"{np.exp(high[1]):.3g})")
        if len(row) > HARMONIC and (out[HARMONIC] or blind[HARMONIC]):
            parts.append(_shape_words(row[HARMONIC], low[HARMONIC], high[HARMONIC]))
        reasons.append("; ".join(parts))
    return reasons


def _shape_words(ratio: float, low: float, high: float) -> str:
    """The contact's shape against the trained ones, as the pulse train's duty cycle (sensor/shape.py)."""
    trained = f"trained surfaces {duty_cycle(high):.2f}-{duty_cycle(low):.2f} of the period in contact"
    if np.isnan(ratio):
        return f"contact pattern not readable (its second harmonic lies on the pad's ridges or past the band); {trained}"
    kind = "narrower ridges" if ratio > high else "wider lands"
    return (f"contact pattern unlike any trained surface: {kind} (about {duty_cycle(ratio):.2f} of the period in "
            f"contact; {trained})")


def domain_reasons(readout: PeakReadout, low: np.ndarray, high: np.ndarray, clarity_limit: float | None,
                   freq_step_per_mm: float, scatter: PressScatter | None = None) -> list[str]:
    """Per row, every way it lies outside the law's domain ('' where none): period and peak strength outside the
    kept training range (:func:`domain_margins`), a spectrum with no clear peak, presses that disagree on where the
    peak is. ``clarity_limit`` None: a model file written before the clarity was kept (not checked).
    ``scatter``: the training presses' scatter about their surfaces (model/press_spread.py); a row read from fewer
    presses than the trained surfaces is flagged only beyond it too. None: the surface margins alone."""
    slack, tolerated, extra = np.zeros(len(readout.clarity)), None, None
    if scatter is not None and readout.presses is not None:
        extra = scatter.excess(readout.presses)  # (n, 4)
        slack = np.hypot(LOG_MARGIN, extra[:, 3]) - LOG_MARGIN
        if readout.overshoot is not None:
            tolerated = (readout.overshoot > 0) & (readout.overshoot <= extra[:, FREQUENCY])
    low_m, high_m = domain_margins(freq_step_per_mm, low, high, None if extra is None else extra[:, :3])
    reasons = range_reasons(readout.features, low_m, high_m, shown=(low, high), tolerated=tolerated)
    for i, clarity in enumerate(readout.clarity):
        parts = [reasons[i]] if reasons[i] else []
        if clarity_limit is not None and clarity < clarity_limit - slack[i]:
            parts.append(f"spectrum shape: no clear peak (it stands {clarity:.2f} log units above the band's median, "
                         f"every trained surface at least {clarity_limit - slack[i]:.2f})")
        if readout.agreement[i] < MIN_AGREEMENT:
            parts.append(f"only {readout.agreement[i]:.0%} of the surface's presses peak at its period")
        reasons[i] = "; ".join(parts)
    return reasons


def _check_positive(X: np.ndarray) -> None:
    if np.any(X < 0):
        raise PeakLawInputError("Negative values in data passed to PeakPowerLaw: spectra are amplitudes")


# --------------------------------------------------------------------------- cross-validation, batched


def peak_law_cv(X, Y, *, groups=None, freq_per_mm, n_blocks: int = 1, pad_ridge_period_mm: float | None = None,
                exclusion_per_mm: float = DEFAULT_EXCLUSION_PER_MM, epsilon: float = HUBER_EPSILON,
                surfaces=None) -> np.ndarray:
    """Out-of-fold predictions (B, n) of the law for each target column of ``Y``, equal to refitting
    :class:`PeakPowerLaw` on every training fold (to rounding): the features are computed once and all folds and
    targets go through one batched IRLS. Folds that split a surface (LOO with ``surfaces``) let a held-out press
    share its surface's peak, read from all its presses' spectra (never a rating), which a refit cannot reproduce.

    Parameters
    ----------
    X, Y : array-like
        (n, n_blocks x K) spectra; (n, B) or (n,) perceived roughness, positive.
    groups, surfaces : array-like, optional
        (n,) labels: leave one group out (default leave-one-out); rows of one surface share where its peak is read.
    freq_per_mm : array-like
        (K,) the spectra's frequencies (at least 3).
    n_blocks, pad_ridge_period_mm, exclusion_per_mm, epsilon
        As :class:`PeakPowerLaw`.

    Returns
    -------
    numpy.ndarray
        (B, n) out-of-fold predictions.

    Examples
    --------
    >>> import numpy as np
    >>> import roughsense as rs
    >>> f = rs.frequency_grid()
    >>> periods = np.repeat([2.0, 3.0, 4.0, 5.0], 2)
    >>> X = np.exp(-((f - 1 / periods[:, None]) / 0.05) ** 2) + 0.01
    >>> y = (periods / 3) ** 0.9
    >>> rs.peak_law_cv(X, y, groups=periods, freq_per_mm=f).round(2)  # each period held out in turn
    array([[0.97, 0.97, 1.  , 1.  , 1.3 , 1.3 , 1.34, 1.34]])
    """
    check_settings(epsilon=epsilon)
    freq_per_mm = check_grid(freq_per_mm)  # as PeakPowerLaw given a grid: at least 3 bins
    X, targets = _cv_inputs(X, Y, groups)
    n = X.shape[0]
    features = peak_features(X, freq_per_mm, n_blocks=n_blocks, pad_ridge_period_mm=pad_ridge_period_mm,
                             exclusion_per_mm=exclusion_per_mm, surfaces=surfaces)
    fold_of = np.arange(n) if groups is None else np.unique(np.asarray(groups), return_inverse=True)[1].ravel()
    n_folds = int(fold_of.max()) + 1
    if n_folds < 2:
        raise PeakLawConfigError("cross-validation needs at least 2 folds")
    held_out = fold_of[None, :] == np.arange(n_folds)[:, None]
    log_targets = np.log(targets)
    folds = _interchangeable_folds(features, log_targets, held_out, surfaces)
    train = ~held_out[folds[1]]
    beta, scale = fit_terms(features, log_targets, train, epsilon=epsilon, grouped=surfaces is not None)
    low, high = domain_margins(grid_step(freq_per_mm),
                               *fold_kept_ranges(features, log_targets, train, beta, scale, epsilon, surfaces))
    return _out_of_fold(features, held_out, folds, beta, low, high, np.empty_like(targets))


def _out_of_fold(features: np.ndarray, held_out: np.ndarray, folds: tuple, beta: np.ndarray, low: np.ndarray,
                 high: np.ndarray, predictions: np.ndarray) -> np.ndarray:
    """``predictions`` (B, n) filled with each row's prediction by the laws of the fold holding it out; ``folds`` from
    :func:`_interchangeable_folds`, ``beta``, ``low`` and ``high`` per problem (its first fold). (The array keeps the
    targets' memory order: a reduction over it sums in that order.)"""
    row_class, distinct, same_as = folds
    for fold, problem in enumerate(same_as):
        rows = np.flatnonzero(held_out[fold])
        if fold != distinct[problem]:  # its rows match its problem's first fold's class by class: the same predictions
            source = np.flatnonzero(held_out[distinct[problem]])
            predictions[:, rows[np.argsort(row_class[rows], kind="stable")]] = \
                predictions[:, source[np.argsort(row_class[source], kind="stable")]]
        else:  # the fold's laws on its held-out rows, their features held to each law's domain
            clipped = held_features(features[rows][None], low[problem][:, None, :], high[problem][:, None, :])
            predictions[:, rows] = np.exp(beta[problem, :, :1] + np.einsum("brf,bf->br", clipped, beta[problem, :, 1:]))
    return predictions


def _interchangeable_folds(features: np.ndarray, log_targets: np.ndarray, held_out: np.ndarray, surfaces):
    """Folds (F, n) that leave out interchangeable rows (equal terms, targets and surface: one surface's presses under
    leave-one-out) fit one law with one kept range of its terms, so each is computed for the first such fold only.
    The amplitude, never a term, is left out of the comparison (its coefficient is 0: its range moves nothing).
    Returns each row's class, the first fold of each problem and each fold's problem (:func:`distinct_masks`)."""
    n = features.shape[0]
    codes = np.zeros(n) if surfaces is None else surface_codes(surfaces, n)
    row_class = row_classes(np.column_stack([np.delete(features, AMPLITUDE, axis=1), log_targets.T, codes]))
    return row_class, *distinct_masks(row_class[:, None], ~held_out)


def _cv_inputs(X, Y, groups) -> tuple[np.ndarray, np.ndarray]:
    """X (n, features) and the targets (B, n), refused in one line unless shapes match and every target is positive."""
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    n = X.shape[0] if X.ndim == 2 else -1
    if X.ndim != 2 or Y.ndim not in (1, 2) or Y.shape[0] != n:
        raise PeakLawInputError(
            f"X (shape {X.shape}) must be rows x features and Y (shape {Y.shape}) one row per row of X")
    targets = (Y[:, None] if Y.ndim == 1 else Y).T
    if not np.all(np.isfinite(targets)) or np.any(targets <= 0):
        raise PeakLawInputError("perceived roughness must be positive and finite (magnitude estimates); the law is fitted "
                                "in logs")
    if groups is not None and len(groups) != n:
        raise PeakLawInputError(f"groups has {len(groups)} entries for {n} rows of X")
    return X, targets


def fold_kept_ranges(features: np.ndarray, log_targets: np.ndarray, train: np.ndarray, beta: np.ndarray,
                     scale: np.ndarray, epsilon: float, surfaces=None) -> tuple[np.ndarray, np.ndarray]:
    """(F, B, 2) low and high of the kept training rows of every fold and target (:func:`kept_rows`, batched)."""
    fitted = beta[:, :, :1] + np.einsum("nf,kbf->kbn", np.nan_to_num(features), beta[:, :, 1:])  # (F, B, n)
    kept = _kept(np.abs(log_targets[None] - fitted), scale, epsilon, train, surfaces)
    return kept_range(features, kept, shape_read(features, train, surfaces is not None))


def kept_range(features: np.ndarray, kept: np.ndarray, read: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F, B, p) low and high of each feature over the kept rows (F, B, n). The second-harmonic ratio bounds the
    domain only where the shape is read (``read`` (F,), :func:`shape_read`); elsewhere its range is unbounded, so
    nothing is flagged for it."""
    columns = range(features.shape[1])
    low = np.stack([np.where(kept, features[:, j], np.inf).min(axis=2) for j in columns], axis=-1)
    high = np.stack([np.where(kept, features[:, j], -np.inf).max(axis=2) for j in columns], axis=-1)
    if features.shape[1] > HARMONIC:
        unused = ~read[:, None]
        low[..., HARMONIC] = np.where(unused, -np.inf, low[..., HARMONIC])
        high[..., HARMONIC] = np.where(unused, np.inf, high[..., HARMONIC])
    return low, high


def held_out_flags(X, y, groups, *, freq_per_mm, n_blocks: int = 1, pad_ridge_period_mm: float | None = None,
                   exclusion_per_mm: float = DEFAULT_EXCLUSION_PER_MM, epsilon: float = HUBER_EPSILON,
                   surfaces=None) -> np.ndarray:
    """Whether each row lies outside the domain of the law fitted without its group (:func:`domain_reasons`):
    the flag a user would have seen for a surface the law never saw. Equal to refitting on every fold."""
    X = np.asarray(X, dtype=np.float64)
    log_y = np.log(np.asarray(y, dtype=np.float64))[None, :]
    reading = {"freq_per_mm": freq_per_mm, "n_blocks": n_blocks, "pad_ridge_period_mm": pad_ridge_period_mm,
               "exclusion_per_mm": exclusion_per_mm}
    readout = peak_readout(X, **reading, surfaces=surfaces)
    fold_of = np.unique(np.asarray(groups), return_inverse=True)[1].ravel()
    held_out = fold_of[None, :] == np.arange(int(fold_of.max()) + 1)[:, None]
    scatter = [None] * held_out.shape[0]
    if surfaces is not None:
        counts = trained_presses(surface_codes(surfaces, X.shape[0]), ~held_out)
        spread = robust_spread(press_deviations(X, readout, **reading), ~held_out)
        scatter = [PressScatter(spread[f], float(counts[f])) for f in range(held_out.shape[0])]
    beta, scale = fit_terms(readout.features, log_y, ~held_out, epsilon=epsilon, grouped=surfaces is not None)
    low, high = fold_kept_ranges(readout.features, log_y, ~held_out, beta, scale, epsilon, surfaces)
    fitted = beta[:, 0, 0][None, :] + np.nan_to_num(readout.features) @ beta[:, 0, 1:].T  # (n, F)
    step = grid_step(freq_per_mm)
    flags = np.zeros(X.shape[0], dtype=bool)
    for fold, rows in enumerate(held_out):
        train = ~rows
        kept = _kept(np.abs(log_y[0] - fitted[:, fold])[None, None], scale[fold:fold + 1], epsilon, train[None],
                     surfaces)[0, 0]
        limit = float(readout.clarity[kept].min()) - LOG_MARGIN
        part = PeakReadout(readout.features[rows], readout.clarity[rows], readout.agreement[rows],
                           readout.presses[rows], readout.overshoot[rows])
        flags[rows] = [bool(r) for r in domain_reasons(part, low[fold, 0], high[fold, 0], limit, step, scatter[fold])]
    return flags
