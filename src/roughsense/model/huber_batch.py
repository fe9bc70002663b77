"""Huber regression by IRLS for many problems at once, in chunks: the peak law's fit and its cross-validations.

A problem is one training mask and one target vector over the same features. Cross-validating the peak law with a
permutation control is folds x shufflings of them (leave-one-out of 140 presses with 199 shufflings: 27 860
problems of 140 rows). Held all at once, their working arrays grow with folds x shufflings x rows (quadratic in the
number of presses under leave-one-out: 250 MiB a model at 140 presses, 1 GiB at 280); advanced in chunks of a bounded
number of cells they stay in cache-sized arrays whatever the study's size. Each problem keeps its own convergence
test, so a chunk, like a batch, gives every problem exactly the iterations a fit of that problem alone takes, and the
chunking changes nothing but the rounding of BLAS products (~1e-13; tests/model/peak_law/test_law.py checks a batch against
each problem fitted on its own).

Many of those problems are one problem. Rows with the same features and the same target in every target column are
interchangeable (the law reads a specimen's peak on all its presses, and a shuffling gives all of them one value), so
two masks taking as many rows from each such class pose the same regression: leave-one-out's folds of one specimen's
presses do. Each distinct problem is solved once, which makes leave-one-out cost as many fits as there are specimens,
not presses: linear in the presses, not quadratic.
"""
from __future__ import annotations

import numpy as np

#: Huber's tuning constant: 95 % efficiency at normal errors (the textbook value; not tuned here).
HUBER_EPSILON = 1.345
#: Median absolute deviation -> standard deviation at normal errors.
_MAD_TO_SD = 1.0 / 0.6744897501960817
_MAX_IRLS_ITERATIONS = 100
_IRLS_TOL = 1e-8
#: Problems per chunk are chosen so that one working array (problems x rows) holds about this many cells: 1 MiB of
#: float64, small enough for a core's cache to hold much of what an iteration touches, large enough that numpy's
#: per-call overhead stays small beside the arithmetic (benchmarks/bench_peak_law.py; 1.5-2x faster than one batch).
CHUNK_CELLS = 1 << 17


def huber_irls(features: np.ndarray, targets: np.ndarray, train: np.ndarray, *,
               epsilon: float = HUBER_EPSILON) -> tuple[np.ndarray, np.ndarray]:
    """Huber regression of every target on the same features, for every training mask at once.

    ``features`` (n, p); ``targets`` (B, n); ``train`` (F, n) booleans (one row per fold).
    Returns coefficients (F, B, p + 1) (intercept first) and the final scale (F, B).
    Iteratively reweighted least squares from the least-squares start; the scale is the median absolute residual of
    the training rows over 0.6745, re-estimated each step (as statsmodels' RLM with HuberT and MAD scale). Each
    (fold, target) problem stops on its own once its coefficients move less than the tolerance, so a batch gives
    each problem exactly the iterations a fit of that problem alone would take. The stopping rule (coefficients
    moving less than 1e-8 of their size) leaves the fit within ~1e-7 of its fixed point in log roughness; a tighter
    one tripled the cost of the study's leave-one-out permutation control (28 000 fits per model), whose slow tail of
    problems is all that a 1e-10 rule added.
    """
    n = features.shape[0]
    design = np.column_stack([np.ones(n), features])
    n_targets = targets.shape[0]
    # Each distinct mask is solved once, and its fit given to every mask that poses the same problem.
    distinct, same_as = distinct_masks(np.column_stack([design, targets.T]), train)
    masks = train[distinct]
    n_problems = distinct.size * n_targets
    beta = np.empty((n_problems, design.shape[1]))
    scale = np.empty(n_problems)
    size = max(1, CHUNK_CELLS // max(n, 1))
    for start in range(0, n_problems, size):
        problems = np.arange(start, min(start + size, n_problems))
        folds, columns = np.divmod(problems, n_targets)
        beta[problems], scale[problems] = _irls_chunk(design, targets[columns], masks[folds], epsilon)
    p1 = design.shape[1]
    return beta.reshape(-1, n_targets, p1)[same_as], scale.reshape(-1, n_targets)[same_as]


def distinct_masks(rows: np.ndarray, masks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The masks (F, n) that pose distinct problems on ``rows`` (n, k): indices of one of each (the first), and for
    every mask the index into those of the one posing its problem. Rows are interchangeable when their bytes are
    equal; two masks pose one problem when they take as many rows of every interchangeable class."""
    row_class = row_classes(rows)
    by_class = np.argsort(row_class, kind="stable")
    starts = np.flatnonzero(np.diff(row_class[by_class], prepend=-1))
    taken = np.add.reduceat(masks[:, by_class].astype(np.intp), starts, axis=1)  # (F, classes), O(F n)
    _, first, same_as = np.unique(taken, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # keep the masks' own order: the first mask's problem is solved first
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return first[order], rank[same_as.ravel()]


def row_classes(rows: np.ndarray) -> np.ndarray:
    """(n,) a class id per row of ``rows`` (n, k): rows of one class have equal bytes, so they are interchangeable."""
    flat = np.ascontiguousarray(rows)
    _, row_class = np.unique(flat.view(np.dtype((np.void, flat.dtype.itemsize * flat.shape[1]))).ravel(),
                             return_inverse=True)
    return row_class.ravel()


def _irls_chunk(design: np.ndarray, targets: np.ndarray, mask: np.ndarray,
                epsilon: float) -> tuple[np.ndarray, np.ndarray]:
    """IRLS of one chunk of problems (rows of ``targets`` and ``mask``); a problem leaves the chunk once it stops."""
    beta = _weighted_lstsq(design, targets, mask.astype(np.float64))
    scale = np.ones(mask.shape[0])
    active = np.arange(mask.shape[0])
    for _ in range(_MAX_IRLS_ITERATIONS):
        if active.size == 0:
            break
        residual = targets - beta[active] @ design.T
        absolute = np.abs(residual)
        step_scale = np.maximum(_masked_median(absolute, mask) * _MAD_TO_SD, np.finfo(np.float64).tiny)
        limit = epsilon * step_scale[:, None]
        weights = mask * (limit / np.maximum(absolute, limit))
        updated = _weighted_lstsq(design, targets, weights)
        change = np.max(np.abs(updated - beta[active]), axis=1)
        done = change <= _IRLS_TOL * (1.0 + np.max(np.abs(updated), axis=1))
        beta[active] = updated
        scale[active] = step_scale
        if done.any():  # compact the working arrays only when a problem has stopped
            active, targets, mask = active[~done], targets[~done], mask[~done]
    return beta, scale


def _masked_median(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Median of each row's entries where ``mask`` is true (rows grouped by their count, one partition per count)."""
    counts = mask.sum(axis=1)
    hidden = np.where(mask, values, np.inf)
    medians = np.empty(values.shape[0])
    for count in np.unique(counts):
        rows = counts == count
        low, high = (count - 1) // 2, count // 2
        part = np.partition(hidden if rows.all() else hidden[rows], (low, high) if low != high else high, axis=1)
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
