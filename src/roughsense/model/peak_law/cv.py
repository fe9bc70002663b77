"""The peak law cross-validated, batched: every fold and every target column in one IRLS
(:func:`peak_law_cv`), equal to refitting :class:`~roughsense.model.peak_law.law.PeakPowerLaw` on each fold, and
:func:`law_domain_flags`, the flag a user would have seen for each row had its group never been trained on.
"""
from __future__ import annotations

import numpy as np

from ...sensor.band import RIDGE_EXCLUSION_PER_MM
from ...sensor.grid import grid_step
from ..huber_batch import HUBER_EPSILON, distinct_masks, row_classes
from ..peak_search import (
    AMPLITUDE,
    PeakLawConfigError,
    PeakLawInputError,
    PeakReadout,
    check_grid,
    check_settings,
    fit_terms,
    held_features,
    peak_features,
    peak_readout,
    press_deviations,
    shape_read,
    surface_codes,
)
from ..press_spread import PressScatter, robust_spread, trained_presses
from ..readout_domain import LOG_MARGIN, _kept, domain_margins, domain_reasons, kept_range


def peak_law_cv(X, Y, *, groups=None, freq_per_mm, n_blocks: int = 1, pad_ridge_period_mm: float | None = None,
                exclusion_per_mm: float = RIDGE_EXCLUSION_PER_MM, epsilon: float = HUBER_EPSILON,
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


def law_domain_flags(X, y, groups, *, freq_per_mm, n_blocks: int = 1, pad_ridge_period_mm: float | None = None,
                   exclusion_per_mm: float = RIDGE_EXCLUSION_PER_MM, epsilon: float = HUBER_EPSILON,
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
