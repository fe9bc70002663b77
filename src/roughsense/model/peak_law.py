"""Peak power law: perceived roughness as a power law of where the contact spectrum peaks and how high.

Why a second model. PLS is linear in the 45 amplitudes, and each grating puts its fundamental into bins that no other
training grating excites, so for a surface it never saw it has nothing to go on (under leave-one-specimen-out the
paper's PLS sits at the training mean's error). Roughness that people perceive by spatial coding grows with the
spacing of the contact pattern, and the spacing *moves* the spectrum's peak: a law in where the peak is (and how
strongly the contact concentrates there) extrapolates to a period between, or just beside, the trained ones.

The law, in logs, with 3 parameters::

    log(roughness) = b0 + b1 * log(peak frequency, mm^-1) + b2 * log(peak amplitude)

- *Peak frequency*: the highest local maximum of the spectrum (averaged over a trial's forces), refined below the
  grid spacing by a parabola through the log amplitudes of the peak bin and its two neighbours (exact for a Gaussian
  lobe, which a Hann-windowed line's main lobe nearly is). The band's two end bins are never peaks (no neighbour on
  one side), and a fingerprint pad's own ridge frequency, 1 / ``pad_ridge_period_mm``, is excluded with
  ``exclusion_per_mm`` on either side: its relief is a pattern of the pad, not of the surface.
- *Peak amplitude*: the log amplitude at the refined peak (the spectrum is normalised to unit area, so this says how
  much of the contact's variation sits in that one spacing: a narrow contact on round crests spreads it over
  harmonics, a square grating concentrates it).
- *Fit*: Huber's M-estimator (epsilon 1.345, scale by the median absolute residual, iteratively reweighted least
  squares), because an image whose peak was misread (a fingerprint pad's lobe or a low-frequency shading hump) is an
  outlier that least squares would follow.
- *Prediction*: features are clipped to the range seen in training (a power law is not carried past its data) and
  :meth:`PeakPowerLaw.extrapolates` says which inputs fell outside it.

Nothing is chosen from the targets: the features, their number and epsilon are fixed, so cross-validating the fit is
all the nesting there is (docs/peak_law.md says how they were chosen, and on which data). Every fold of a
cross-validation, and every shuffled target of the permutation control, is fitted in one batched IRLS
(:func:`peak_law_cv`), the same arithmetic as a refit of :class:`PeakPowerLaw` on that fold.
"""
from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from .families import PEAK_LAW as NAME  # noqa: F401 (the family's name, beside its class)

FEATURE_NAMES = ("log_peak_frequency_per_mm", "log_peak_amplitude")
#: Half-width (mm^-1) of the band around the pad's ridge frequency left out of the peak search: the Hann main lobe of
#: a 54 mm line is +-0.037 mm^-1, widened for the bench's magnification jitter and the ridges' sidebands.
DEFAULT_EXCLUSION_PER_MM = 0.1
#: Huber's tuning constant: 95 % efficiency at normal errors (the textbook value; not tuned here).
HUBER_EPSILON = 1.345
#: Median absolute deviation -> standard deviation at normal errors.
_MAD_TO_SD = 1.0 / 0.6744897501960817
_MAX_IRLS_ITERATIONS = 100
_IRLS_TOL = 1e-10
#: The paper's band when a caller gives no grid: n evenly spaced frequencies over 0.1-1.0 mm^-1.
_DEFAULT_BAND_PER_MM = (0.1, 1.0)
#: Features more than this (in log units) outside the training range count as extrapolation (rounding aside).
_RANGE_TOL = 1e-9


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
        raise ValueError(
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
        raise ValueError(f"freq_per_mm must be at least {min_bins} positive, evenly spaced, increasing frequencies "
                         f"(mm^-1), got {np.array2string(freq.ravel()[:6], precision=4)}")
    return freq


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def _check_blocks(n_blocks) -> int:
    if not isinstance(n_blocks, (int, np.integer)) or isinstance(n_blocks, (bool, np.bool_)) or n_blocks < 1:
        raise ValueError(f"n_blocks must be a positive whole number, got {n_blocks!r}")
    return int(n_blocks)


def check_settings(*, pad_ridge_period_mm=None, **positive) -> None:
    """Refuse a setting that is not a positive finite number (a bool is not one); the ridge period may be None."""
    for name, value in positive.items():
        if not _is_number(value) or not np.isfinite(value) or value <= 0:
            raise ValueError(f"{name} must be a positive number, got {value!r}")
    period = pad_ridge_period_mm
    if period is not None and (not _is_number(period) or not np.isfinite(period) or period <= 0):
        raise ValueError(f"pad_ridge_period_mm must be a positive number of mm or None, got {period!r}")


def _check_spectra(spectra: np.ndarray) -> None:
    if not np.all(np.isfinite(spectra)):
        raise ValueError("spectra contain NaN or infinite values")
    if np.any(spectra < 0):
        raise ValueError("Negative values in data passed to PeakPowerLaw: spectra are amplitudes")


def peak_features(spectra, freq_per_mm, *, n_blocks: int = 1, pad_ridge_period_mm: float | None = None,
                  exclusion_per_mm: float = DEFAULT_EXCLUSION_PER_MM) -> np.ndarray:
    """(n, 2) log peak frequency (mm^-1) and log peak amplitude of each row's spectrum.

    A row holds ``n_blocks`` spectra side by side (a combined-force trial); they are averaged first, so the peak is
    read from the trial's mean spectrum (the grating's peak stays where it is at every force; noise averages out).
    """
    freq = check_grid(freq_per_mm, min_bins=1)  # the estimator's default grid may be coarser than 3 bins
    n_blocks = _check_blocks(n_blocks)
    check_settings(pad_ridge_period_mm=pad_ridge_period_mm, exclusion_per_mm=exclusion_per_mm)
    spectra = np.asarray(spectra, dtype=np.float64)
    if spectra.ndim != 2:
        raise ValueError(f"spectra must be a 2-D array (rows x features), got shape {spectra.shape}")
    _check_spectra(spectra)
    n, width = spectra.shape
    k_bins = freq.size
    if width != n_blocks * k_bins:
        raise ValueError(f"{width} features are not {n_blocks} block(s) of the {k_bins}-frequency grid")
    mean = spectra.reshape(n, n_blocks, k_bins).mean(axis=1)
    log_amp = np.log(np.maximum(mean, np.finfo(np.float64).tiny))
    allowed = search_bins(freq, pad_ridge_period_mm, exclusion_per_mm)
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
    offset = np.clip(offset, -0.5, 0.5)
    step = freq[1] - freq[0] if k_bins > 1 else 0.0
    frequency = freq[peak] + offset * step
    amplitude = centre - 0.25 * (left - right) * offset
    return np.column_stack([np.log(frequency), amplitude])


# --------------------------------------------------------------------------- batched Huber IRLS


def huber_irls(features: np.ndarray, targets: np.ndarray, train: np.ndarray, *,
               epsilon: float = HUBER_EPSILON) -> tuple[np.ndarray, np.ndarray]:
    """Huber regression of every target on the same features, for every training mask at once.

    ``features`` (n, p); ``targets`` (B, n); ``train`` (F, n) booleans (one row per fold).
    Returns coefficients (F, B, p + 1) (intercept first) and the final scale (F, B).
    Iteratively reweighted least squares from the least-squares start; the scale is the median absolute residual of
    the training rows over 0.6745, re-estimated each step (as statsmodels' RLM with HuberT and MAD scale). Each
    (fold, target) problem stops on its own once its coefficients move less than the tolerance, so a batch gives
    each problem exactly the iterations a fit of that problem alone would take.
    """
    n = features.shape[0]
    design = np.column_stack([np.ones(n), features])
    n_folds, n_targets = train.shape[0], targets.shape[0]
    mask = np.broadcast_to(train[:, None, :], (n_folds, n_targets, n)).reshape(-1, n)
    flat_targets = np.broadcast_to(targets[None], (n_folds, n_targets, n)).reshape(-1, n)
    beta = _weighted_lstsq(design, flat_targets, mask.astype(np.float64))
    scale = np.ones(mask.shape[0])
    active = np.arange(mask.shape[0])
    for _ in range(_MAX_IRLS_ITERATIONS):
        if active.size == 0:
            break
        problem_mask, problem_targets = mask[active], flat_targets[active]
        residual = problem_targets - beta[active] @ design.T
        absolute = np.abs(residual)
        step_scale = np.maximum(_masked_median(absolute, problem_mask) * _MAD_TO_SD, np.finfo(np.float64).tiny)
        limit = epsilon * step_scale[:, None]
        weights = problem_mask * (limit / np.maximum(absolute, limit))
        updated = _weighted_lstsq(design, problem_targets, weights)
        change = np.max(np.abs(updated - beta[active]), axis=1)
        done = change <= _IRLS_TOL * (1.0 + np.max(np.abs(updated), axis=1))
        beta[active] = updated
        scale[active] = step_scale
        active = active[~done]
    p1 = design.shape[1]
    return beta.reshape(n_folds, n_targets, p1), scale.reshape(n_folds, n_targets)


def _masked_median(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Median of each row's entries where ``mask`` is true (rows grouped by their count, one partition per count)."""
    counts = mask.sum(axis=1)
    hidden = np.where(mask, values, np.inf)
    medians = np.empty(values.shape[0])
    for count in np.unique(counts):
        rows = counts == count
        low, high = (count - 1) // 2, count // 2
        part = np.partition(hidden[rows], (low, high), axis=1)
        medians[rows] = 0.5 * (part[:, low] + part[:, high])
    return medians


def _weighted_lstsq(design: np.ndarray, targets: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Solve the weighted normal equations of every problem (row of ``weights``): (problems, p + 1)."""
    p1 = design.shape[1]
    outer = (design[:, :, None] * design[:, None, :]).reshape(design.shape[0], p1 * p1)
    gram = (weights @ outer).reshape(-1, p1, p1)
    moment = (weights * targets) @ design
    # A tiny ridge on the slopes keeps a degenerate problem (one distinct feature value) solvable; it is 1e-12 of the
    # Gram matrix's own scale, far below rounding of any problem that is not degenerate.
    ridge = 1e-12 * np.maximum(np.trace(gram, axis1=-2, axis2=-1), 1.0)
    eye = np.eye(p1)
    eye[0, 0] = 0.0
    return np.linalg.solve(gram + ridge[:, None, None] * eye, moment[..., None])[..., 0]


# --------------------------------------------------------------------------- the estimator


class PeakPowerLaw(RegressorMixin, BaseEstimator):
    """scikit-learn regressor: spectra (n, n_blocks x K) -> perceived roughness, by the peak power law above.

    ``freq_per_mm``: the spectra's grid (K frequencies; default K evenly spaced over 0.1-1.0 mm^-1);
    ``n_blocks``: spectra per row (3 for a combined-force trial); ``pad_ridge_period_mm``: the pad's ridge period
    (a fingerprint pad's), whose frequency is left out of the peak search; ``epsilon``: Huber's constant.
    Fitted: ``coef_`` (2,), ``intercept_``, ``scale_`` (robust residual SD, log units), ``feature_min_`` and
    ``feature_max_`` (the training range, used to clip and to flag extrapolation), ``freq_per_mm_``.
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
        blocks = _check_blocks(self.n_blocks)
        if n_features % blocks:
            raise ValueError(f"{n_features} feature(s) cannot be split into {blocks} equal spectra")
        k_bins = n_features // blocks
        if self.freq_per_mm is None:
            return np.linspace(*_DEFAULT_BAND_PER_MM, k_bins)
        freq = check_grid(self.freq_per_mm)
        if freq.size != k_bins:
            raise ValueError(f"{n_features} feature(s) in {blocks} block(s) do not match the {freq.size}-frequency grid")
        return freq

    def _check_params(self) -> None:
        check_settings(pad_ridge_period_mm=self.pad_ridge_period_mm, exclusion_per_mm=self.exclusion_per_mm,
                       epsilon=self.epsilon)

    def features(self, X) -> np.ndarray:
        """The law's two inputs for each row (log peak frequency, log peak amplitude)."""
        check_is_fitted(self)
        X = validate_data(self, X, reset=False, ensure_min_samples=1)
        _check_positive(X)
        return self._features(X)

    def _features(self, X: np.ndarray) -> np.ndarray:
        return peak_features(X, self.freq_per_mm_, n_blocks=int(self.n_blocks),
                             pad_ridge_period_mm=self.pad_ridge_period_mm, exclusion_per_mm=float(self.exclusion_per_mm))

    def fit(self, X, y):
        self._check_params()
        X, y = validate_data(self, X, y, y_numeric=True, ensure_min_samples=2)
        _check_positive(X)
        y = np.asarray(y, dtype=np.float64)
        if np.any(y <= 0):
            raise ValueError("perceived roughness must be positive (magnitude estimates); the law is fitted in logs")
        self.freq_per_mm_ = self._grid(X.shape[1])
        features = self._features(X)
        beta, scale = huber_irls(features, np.log(y)[None, :], np.ones((1, len(y)), dtype=bool),
                                 epsilon=float(self.epsilon))
        self.intercept_ = float(beta[0, 0, 0])
        self.coef_ = beta[0, 0, 1:].copy()
        self.scale_ = float(scale[0, 0])
        self.feature_min_ = features.min(axis=0)
        self.feature_max_ = features.max(axis=0)
        return self

    def predict(self, X) -> np.ndarray:
        return predict_law(self.features(X), self.intercept_, self.coef_, self.feature_min_, self.feature_max_)

    def extrapolates(self, X) -> np.ndarray:
        """True for each row whose features fall outside the training range (its prediction is held at the edge)."""
        return outside_range(self.features(X), self.feature_min_, self.feature_max_)


def predict_law(features: np.ndarray, intercept: float, coef: np.ndarray, low: np.ndarray, high: np.ndarray
                ) -> np.ndarray:
    """exp(intercept + clip(features) . coef): the law's prediction, features held to the training range."""
    return np.exp(intercept + np.clip(features, low, high) @ np.asarray(coef, dtype=np.float64))


def outside_range(features: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    return np.any((features < low - _RANGE_TOL) | (features > high + _RANGE_TOL), axis=1)


def _check_positive(X: np.ndarray) -> None:
    if np.any(X < 0):
        raise ValueError("Negative values in data passed to PeakPowerLaw: spectra are amplitudes")


# --------------------------------------------------------------------------- cross-validation, batched


def peak_law_cv(X, Y, *, groups=None, freq_per_mm, n_blocks: int = 1, pad_ridge_period_mm: float | None = None,
                exclusion_per_mm: float = DEFAULT_EXCLUSION_PER_MM, epsilon: float = HUBER_EPSILON) -> np.ndarray:
    """Out-of-fold predictions (B, n) of the law for each target column of ``Y`` (n, B) (or ``Y`` of shape (n,)).

    Leave-one-out without ``groups``; leave-one-group-out (e.g. leave-one-specimen-out) with them. Equal to refitting
    :class:`PeakPowerLaw` on every training fold (to rounding): the features do not depend on the targets, so they are
    computed once, and all folds and targets go through one batched IRLS.
    """
    check_settings(epsilon=epsilon)
    freq_per_mm = check_grid(freq_per_mm)  # as PeakPowerLaw given a grid: at least 3 bins
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    n = X.shape[0] if X.ndim == 2 else -1
    if X.ndim != 2 or Y.ndim not in (1, 2) or Y.shape[0] != n:
        raise ValueError(f"X (shape {X.shape}) must be rows x features and Y (shape {Y.shape}) one row per row of X")
    targets = (Y[:, None] if Y.ndim == 1 else Y).T
    if not np.all(np.isfinite(targets)) or np.any(targets <= 0):
        raise ValueError("perceived roughness must be positive and finite (magnitude estimates); the law is fitted "
                         "in logs")
    if groups is not None and len(groups) != n:
        raise ValueError(f"groups has {len(groups)} entries for {n} rows of X")
    features = peak_features(X, freq_per_mm, n_blocks=n_blocks, pad_ridge_period_mm=pad_ridge_period_mm,
                             exclusion_per_mm=exclusion_per_mm)
    if groups is None:
        fold_of = np.arange(n)
    else:
        _, fold_of = np.unique(np.asarray(groups), return_inverse=True)
    n_folds = int(fold_of.max()) + 1
    if n_folds < 2:
        raise ValueError("cross-validation needs at least 2 folds")
    held_out = fold_of[None, :] == np.arange(n_folds)[:, None]
    beta, _ = huber_irls(features, np.log(targets), ~held_out, epsilon=epsilon)
    predictions = np.empty_like(targets)
    for fold in range(n_folds):
        rows = held_out[fold]
        train = ~rows
        low, high = features[train].min(axis=0), features[train].max(axis=0)
        clipped = np.clip(features[rows], low, high)
        predictions[:, rows] = np.exp(beta[fold, :, :1] + beta[fold, :, 1:] @ clipped.T)
    return predictions
