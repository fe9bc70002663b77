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

from ...sensor.band import RIDGE_EXCLUSION_PER_MM
from ...sensor.grid import grid_step
from ..huber_batch import HUBER_EPSILON
from ..peak_search import check_grid, fit_terms, held_features, peak_features
from ..readout_domain import domain_margins
from .cv import fold_kept_ranges


def law_fold_models(X, y, train: np.ndarray, *, freq_per_mm, n_blocks: int = 1,
                    pad_ridge_period_mm: float | None = None, exclusion_per_mm: float = RIDGE_EXCLUSION_PER_MM,
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
    return np.exp(fold_log_predictions(features, beta, low, high, grid_step(freq_per_mm)))


def specimen_codes(specimens) -> tuple[np.ndarray, np.ndarray]:
    """Integer codes of the rows' specimens (order of first appearance) and the names."""
    codes, names = pd.factorize(pd.Series(np.asarray(specimens).astype(str)), sort=False)
    return codes, np.asarray(names)


def law_pair_models(X, y, specimens, **law) -> tuple[np.ndarray, tuple]:
    """The law fitted without every pair of specimens t, s (t == s: without t alone), in one batch: the (S, S) index
    of each pair's model and the models (:func:`law_fold_models`: coefficients, kept ranges, the rows' features)."""
    codes, names = specimen_codes(specimens)
    first, second = np.triu_indices(names.size)
    pair = np.empty((names.size, names.size), dtype=int)
    pair[first, second] = pair[second, first] = np.arange(first.size)
    held = (codes[None, :] == first[:, None]) | (codes[None, :] == second[:, None])
    settings = {k: v for k, v in law.items() if k != "surfaces"}
    return pair, law_fold_models(X, y, ~held, surfaces=law.get("surfaces"), **settings)


def law_pair_log_predictions(X, y, specimens, *, models=None, **law) -> np.ndarray:
    """(S, S, S) log mean prediction of each specimen u by the law fitted without specimens t and s ([t, s, u];
    [t, t, u]: without t alone), every pair in one batch (``models``: :func:`law_pair_models`, if at hand)."""
    from ..jackknife_plus import surface_means

    codes, names = specimen_codes(specimens)
    pair, (beta, low, high, features) = models or law_pair_models(X, y, specimens, **law)
    freq = check_grid(law["freq_per_mm"])
    predicted = np.exp(fold_log_predictions(features, beta, low, high, grid_step(freq)))
    return np.log(surface_means(predicted, codes, names.size))[pair]


def press_groups(codes: np.ndarray, count: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each specimen's presses shuffled (seeded) and cut into disjoint readings of ``count`` presses (a remainder
    left out): the rows read, each row's reading (0..R-1) and each reading's specimen. A specimen's first reading is
    the one whose residual enters the jackknife+; all of them are readings of it to cover."""
    rng = np.random.default_rng(seed)
    rows, reading, owner = [], [], []
    for specimen in range(int(codes.max()) + 1):
        mine = rng.permutation(np.flatnonzero(codes == specimen))
        n_readings = mine.size // count
        rows.append(mine[:n_readings * count])
        reading.append(len(owner) + np.repeat(np.arange(n_readings), count))
        owner.extend([specimen] * n_readings)
    return np.concatenate(rows), np.concatenate(reading), np.asarray(owner)


def law_nested_press_check(X, y, specimens, count: int, seed: int, *, level: float | None = None, models=None,
                           **law) -> pd.DataFrame:
    """The jackknife+ of a surface read from ``count`` presses, fully nested: specimen t's readings are covered or
    not by intervals built from the other specimens only, each fold fitted without t and s (leave-two-out) and
    each s's residual that of its first reading (as a model file keeps one per specimen). ``count`` 1 is a press
    read alone. Per specimen: its readings, the share covered, the median log half-width. ``models``:
    :func:`law_pair_models`, if at hand."""
    from ..interval import INTERVAL_LEVEL
    from ..jackknife_plus import jackknife_plus

    codes, names = specimen_codes(specimens)
    n_specimens = names.size
    pair, (beta, low, high, _) = models or law_pair_models(X, y, specimens, **law)
    settings = {k: v for k, v in law.items() if k != "surfaces"}
    rows, reading, owner = press_groups(codes, count, seed)
    features = peak_features(np.asarray(X)[rows], surfaces=reading, **settings)
    freq = check_grid(settings["freq_per_mm"])
    predicted = np.exp(fold_log_predictions(features, beta, low, high, grid_step(freq)))  # (P, rows)
    means = np.log(np.stack([np.bincount(reading, weights=p) for p in predicted]) / np.bincount(reading))  # (P, R)
    log_targets = np.log(pd.Series(np.asarray(y, dtype=np.float64)).groupby(codes).first().to_numpy())
    firsts = np.array([np.flatnonzero(owner == s)[0] for s in range(n_specimens)])
    out = []
    for t in range(n_specimens):
        others = np.array([s for s in range(n_specimens) if s != t])
        residuals = log_targets[others] - means[pair[t, others], firsts[others]]
        mine = np.flatnonzero(owner == t)
        lo, hi = jackknife_plus(means[pair[t, others]][:, mine].T, residuals, level or INTERVAL_LEVEL)
        out.append({"specimen": str(names[t]), "readings": int(mine.size),
                    "covered": float(np.mean((lo <= log_targets[t]) & (log_targets[t] <= hi))),
                    "log_halfwidth": float(np.median(0.5 * (hi - lo)))})
    return pd.DataFrame(out)
