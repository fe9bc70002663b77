"""The peak law fitted on any set of training masks at once, and the leave-two-specimens-out fits the jackknife+'s
nested check needs (model/jackknife_plus.py).

:func:`peak_law.peak_law_cv` gives each row its own fold's prediction; the jackknife+ needs more: every
leave-one-specimen-out model's prediction of *every* row (the centres of a new surface's interval), and for the
nested check, models fitted without two specimens. Both are one batched IRLS over the masks, with each fold's
domain clipping exactly as a refit of :class:`peak_law.PeakPowerLaw` on that fold would apply it.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from .peak_law import (
    DEFAULT_EXCLUSION_PER_MM,
    HUBER_EPSILON,
    check_grid,
    domain_margins,
    fit_terms,
    fold_kept_ranges,
    held_features,
    peak_features,
)


def law_fold_models(X, y, train: np.ndarray, *, freq_per_mm, n_blocks: int = 1,
                    pad_ridge_period_mm: float | None = None, exclusion_per_mm: float = DEFAULT_EXCLUSION_PER_MM,
                    epsilon: float = HUBER_EPSILON, surfaces=None) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                           np.ndarray]:
    """The law fitted on each training mask of ``train`` (F, n): coefficients (F, p + 1), the kept training range
    (F, p) low and high before :func:`domain_margins` (what a model file stores), and every row's features (n, p)."""
    freq_per_mm = check_grid(freq_per_mm)
    features = peak_features(X, freq_per_mm, n_blocks=n_blocks, pad_ridge_period_mm=pad_ridge_period_mm,
                             exclusion_per_mm=exclusion_per_mm, surfaces=surfaces)
    log_y = np.log(np.asarray(y, dtype=np.float64))[None, :]
    beta, scale = fit_terms(features, log_y, train, epsilon=epsilon, grouped=surfaces is not None)
    low, high = fold_kept_ranges(features, log_y, train, beta, scale, epsilon, surfaces)
    return beta[:, 0], low[:, 0], high[:, 0], features


def fold_log_predictions(features: np.ndarray, beta: np.ndarray, low: np.ndarray, high: np.ndarray,
                         freq_step_per_mm: float) -> np.ndarray:
    """(F, n) log predictions of rows with ``features`` (n, p) by F fold laws (:func:`law_fold_models`), each
    feature held to its fold's domain exactly as a fitted :class:`peak_law.PeakPowerLaw` holds it."""
    low, high = domain_margins(float(freq_step_per_mm), low, high)
    clipped = held_features(np.asarray(features)[None], low[:, None, :], high[:, None, :])  # (F, n, p)
    return beta[:, :1] + np.einsum("fnk,fk->fn", clipped, beta[:, 1:])


def law_fold_predictions(X, y, train: np.ndarray, *, freq_per_mm, **law) -> np.ndarray:
    """(F, n) predictions of every row by the law fitted on each training mask of ``train`` (F, n)."""
    freq_per_mm = check_grid(freq_per_mm)
    beta, low, high, features = law_fold_models(X, y, train, freq_per_mm=freq_per_mm, **law)
    return np.exp(fold_log_predictions(features, beta, low, high, float(freq_per_mm[1] - freq_per_mm[0])))


def specimen_codes(specimens) -> tuple[np.ndarray, np.ndarray]:
    """Integer codes of the rows' specimens (order of first appearance) and the names."""
    codes, names = pd.factorize(pd.Series(np.asarray(specimens).astype(str)), sort=False)
    return codes, np.asarray(names)


def law_pair_log_predictions(X, y, specimens, **law) -> np.ndarray:
    """(S, S, S) log mean prediction of each specimen u by the law fitted without specimens t and s ([t, s, u];
    [t, t, u]: without t alone), every pair in one batch."""
    from .jackknife_plus import surface_means

    codes, names = specimen_codes(specimens)
    n_specimens = names.size
    first, second = np.triu_indices(n_specimens)
    held = (codes[None, :] == first[:, None]) | (codes[None, :] == second[:, None])
    means = np.log(surface_means(law_fold_predictions(X, y, ~held, **law), codes, n_specimens))
    pairs = np.empty((n_specimens, n_specimens, n_specimens))
    pairs[first, second] = means
    pairs[second, first] = means
    return pairs
