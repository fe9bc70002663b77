"""Folds and the training-mean baseline, beneath every family: each family's CV of one pad x condition holds out
the same trials and is judged against the same null model.

:func:`fold_ids` numbers the folds (leave-one-out, leave one group out, or shuffled K-fold from a seed).
:func:`training_mean_predictions` is the null model's out-of-fold prediction (each trial gets its training fold's
mean), computed with PLS's 0-component arithmetic (model/pls/cv_engine.py), so the baseline a family reports equals
PLS's ``rmse[0]`` bit for bit; :func:`error_curve` is the RMSE per prediction column and its fold-wise standard error.
"""
from __future__ import annotations

import numpy as np

from .._util.checks import is_whole_number
from ..errors import ConfigError, InputError


class FoldConfigError(ConfigError, ValueError):
    """An impossible fold scheme (too few groups, K beyond the samples); also a ValueError for scikit-learn."""


class FoldInputError(InputError, ValueError):
    """Groups that do not match the samples; also a ValueError for scikit-learn."""


def fold_ids(n: int, cv, groups, random_state) -> tuple[np.ndarray, str]:
    """Fold id per sample, 0..F-1, for LOO, leave-one-group-out or shuffled K-fold."""
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != (n,):
            raise FoldInputError(f"groups has {groups.size} entries for {n} samples")
        if cv not in (None, "logo", "loso"):
            raise FoldConfigError(f"groups= gives leave-one-group-out; cv={cv!r} cannot be combined with it")
        _, ids = np.unique(groups, return_inverse=True)
        if ids.max() < 1:
            raise FoldConfigError("leave-one-group-out needs at least 2 groups")
        return ids.astype(np.intp), "leave-one-group-out"
    if cv is None or cv == "loo":
        return np.arange(n, dtype=np.intp), "leave-one-out"
    if is_whole_number(cv):
        if not 2 <= cv <= n:
            raise FoldConfigError(f"K-fold needs 2 <= k <= n_samples={n}, got k={cv}")
        rng = np.random.default_rng(random_state)
        ids = np.empty(n, dtype=np.intp)
        for f, part in enumerate(np.array_split(rng.permutation(n), int(cv))):
            ids[part] = f
        return ids, f"{int(cv)}-fold"
    raise FoldConfigError(f"cv must be 'loo', a whole number of folds, or None with groups=; got {cv!r}")


def training_mean_predictions(y: np.ndarray, fid: np.ndarray) -> np.ndarray:
    """Each sample's training-fold mean (folds ``fid``, a partition), as PLS's exact CV computes its 0-component
    column: the overall mean less the held-out rows' centred sum over the training size, fold sums as one product
    with the fold-membership matrix (leave-one-out: each row alone), in that order."""
    Y = np.asarray(y, dtype=np.float64)[:, None]
    n = Y.shape[0]
    F = int(fid.max()) + 1
    m = np.bincount(fid, minlength=F)
    n_train = (n - m).astype(float)
    y_mean = Y.mean(axis=0)
    Yc = Y - Y.mean(axis=0)
    loo = bool(np.all(m == 1)) and bool(np.all(fid == np.arange(n)))
    if loo:
        sums = Yc.T
    else:
        member = np.zeros((F, n))
        member[fid, np.arange(n)] = 1.0
        sums = np.matmul(member, Yc.T[:, :, None])[:, :, 0]
    shift = -sums / n_train
    return (y_mean[:, None] + (shift if loo else shift[:, fid]))[0]


def error_curve(pred: np.ndarray, y: np.ndarray, fid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """RMSE of each prediction column (n, C), its standard error across folds (delta method on the folds' MSEs), and
    the folds' MSEs (F, C)."""
    F = int(fid.max()) + 1
    m = np.bincount(fid, minlength=F)
    order = np.argsort(fid, kind="stable")
    starts = np.concatenate([[0], np.cumsum(m)[:-1]])
    err2 = (pred - y[:, None]) ** 2
    rmse = np.sqrt(err2.mean(axis=0))
    fold_mse = np.add.reduceat(err2[order], starts, axis=0) / m[:, None]
    se_mse = fold_mse.std(axis=0, ddof=1) / np.sqrt(F)  # fold_ids always gives at least 2 folds
    rmse_se = np.divide(se_mse, 2 * rmse, out=np.zeros_like(rmse), where=rmse > 0)
    return rmse, rmse_se, fold_mse
