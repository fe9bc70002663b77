"""Jackknife+ over specimens: a surface's 90 % interval with a stated guarantee, and its fully nested check.

Why not the quantile of leave-one-specimen-out residuals around the full model's prediction (model/interval.py):
that is the plain jackknife, for which no coverage guarantee holds (Barber, Candès, Ramdas & Tibshirani, "Predictive
inference with the jackknife+", Ann. Statist. 49, 2021). The jackknife+ keeps every leave-one-specimen-out model:
with R_s the log residual of specimen s under the model fitted without s, and mu_{-s}(x) that model's log prediction
for a new surface x, the interval is

    [ the floor(alpha (n + 1))-th smallest of mu_{-s}(x) - R_s ,  the ceil((1 - alpha)(n + 1))-th smallest of
      mu_{-s}(x) + R_s ]

over the n training specimens, and it covers a new surface's perceived roughness with probability at least
1 - 2 alpha when specimens are exchangeable (Theorem 1 there; in practice close to 1 - alpha). Its unit is the
specimen, never the press: presses of one specimen share its rating and are not exchangeable. With 14 specimens
and alpha = 0.1 the upper rank is 14 of 14 and the lower 1 of 14, so the interval spans every fold's prediction
widened by its own residual: it narrows only as the model's worst held-out specimens do.

The check is fully nested: each held-out specimen t gets the jackknife+ interval built from the other specimens
only, each of whose residuals comes from a model fitted without t *and* s (leave-two-out), so no model that builds
t's interval ever saw t. MAPIE's CrossConformalRegressor implements CV+ with group folds, but it takes its quantiles
over rows (presses here) and passes fit parameters unsliced (the peak law's ``surfaces``), so it gives neither the
specimen-level guarantee nor our estimator's folds; tests/model/test_jackknife_plus.py checks this module's arithmetic
against MAPIE's jackknife+ on one row per specimen, where the two coincide.
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .interval import INTERVAL_LEVEL


def ranks(n: int, level: float = INTERVAL_LEVEL) -> tuple[int, int]:
    """The 1-based ranks (lower, upper) of the jackknife+ quantiles over n specimens; 0 / n + 1 when n is too small
    for the level (the interval is then unbounded on that side)."""
    alpha = 1.0 - level
    return math.floor(alpha * (n + 1) + 1e-12), math.ceil((1.0 - alpha) * (n + 1) - 1e-12)


def jackknife_plus(fold_log_predictions, log_residuals, level: float = INTERVAL_LEVEL) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) log bounds for each surface: ``fold_log_predictions`` (m, n) are the n leave-one-specimen-out
    models' log predictions of m surfaces, ``log_residuals`` (n,) each model's |log residual| on its held-out
    specimen."""
    centre = np.atleast_2d(np.asarray(fold_log_predictions, dtype=np.float64))
    residuals = np.abs(np.asarray(log_residuals, dtype=np.float64))
    n = residuals.size
    low_rank, high_rank = ranks(n, level)
    lows, highs = np.sort(centre - residuals, axis=1), np.sort(centre + residuals, axis=1)
    low = lows[:, low_rank - 1] if low_rank >= 1 else np.full(centre.shape[0], -np.inf)
    high = highs[:, high_rank - 1] if high_rank <= n else np.full(centre.shape[0], np.inf)
    return low, high


def surface_means(predictions: np.ndarray, codes: np.ndarray, n_surfaces: int) -> np.ndarray:
    """(F, S) mean prediction of each surface's rows by each fold model, from (F, n) row predictions."""
    counts = np.bincount(codes, minlength=n_surfaces)
    members = np.zeros((codes.size, n_surfaces))
    members[np.arange(codes.size), codes] = 1.0
    return (predictions @ members) / counts


def nested_check(pair_log_predictions: np.ndarray, log_targets: np.ndarray, names, level: float = INTERVAL_LEVEL
                 ) -> pd.DataFrame:
    """Per specimen t, its jackknife+ interval from the other specimens only, and whether it holds t's rating.

    ``pair_log_predictions`` (S, S, S): [t, s, u] is the log mean prediction of specimen u by the model fitted
    without t and s (t == s: without t alone). For t, specimen s != t contributes residual
    |log y_s - [t, s, s]| and centre [t, s, t].
    """
    n = len(log_targets)
    rows = []
    for t in range(n):
        others = np.array([s for s in range(n) if s != t])
        residuals = np.abs(log_targets[others] - pair_log_predictions[t, others, others])
        low, high = jackknife_plus(pair_log_predictions[t, others, t][None], residuals, level)
        low, high = float(low[0]), float(high[0])
        target = float(log_targets[t])
        miss = (low - target) if target < low else (target - high) if target > high else 0.0
        rows.append({"specimen": str(names[t]), "perceived": math.exp(target),
                     "prediction": math.exp(float(pair_log_predictions[t, t, t])),
                     "pi90_low": math.exp(low), "pi90_high": math.exp(high), "covered": miss == 0.0,
                     "miss_log": miss, "log_halfwidth": 0.5 * (high - low)})
    return pd.DataFrame(rows)
