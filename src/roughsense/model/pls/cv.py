"""Exact, fast cross-validation of PLS1 over every component count at once (LOO, LOSO, K-fold, many targets).

It is exact, not approximate. PLS1 depends on the data only through the centred cross-products X'X and X'y, and a
training fold's cross-products differ from the full data's by a low-rank term (its held-out rows and the shift of its
mean). So all folds share one rotation of the data (the SVD of the centred X, in which X'X is diagonal), and every
fold's model is advanced together, one component at a time, with a handful of batched array operations instead of
one refit per fold.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from sklearn.utils.validation import validate_data

from ... import defaults
from ..._util.checks import POSITIVE_INT, check
from ..folds import error_curve, fold_ids
from .cv_engine import (
    _KRYLOV_RTOL,
    _check_fold_support,
    _cv_predictions,
    _own_basis_predictions,
    _rotation,
)
from .simpls import SIMPLS, PLSConfigError, PLSInputError, blas_threads_for, check_target, svd_rank, validate_xy


@dataclass(frozen=True)
class PLSCVResult:
    """Cross-validated PLS1 for component counts 0..max (index = number of components).

    ``rmse[0]`` and ``predictions[:, 0]`` belong to the model that predicts the training fold's mean.
    ``folds[i]`` is the fold that held sample i out; ``test_indices`` lists each fold's samples.
    ``rmse_se`` is the standard error of the RMSE (delta method on the per-fold mean squared errors).
    """

    rmse: np.ndarray
    rmse_se: np.ndarray
    predictions: np.ndarray
    best_n_components: int
    one_se_n_components: int
    folds: np.ndarray
    scheme: str
    fold_mse: np.ndarray = field(repr=False)

    @property
    def max_components(self) -> int:
        return self.rmse.size - 1

    @property
    def n_folds(self) -> int:
        return self.fold_mse.shape[0]

    @property
    def test_indices(self) -> list[np.ndarray]:
        return [np.flatnonzero(self.folds == f) for f in range(self.n_folds)]


def _component_limit(max_components) -> int:
    """The largest component count to cross-validate: a whole number >= 1 (a bool is not a count)."""
    return check(max_components, POSITIVE_INT, name="max_components", error=PLSConfigError,
                 must="a positive whole number")


def pls_cv(X, y, max_components: int = defaults.MAX_COMPONENTS, cv="loo", groups=None, random_state=None, *,
           cap: bool = False) -> PLSCVResult:
    """Out-of-fold predictions of PLS1 (SIMPLS) with 0..max_components components, exact and batched: equal, to
    rounding, to refitting :class:`SIMPLS` on every training fold.

    Parameters
    ----------
    X, y : array-like
        (n_samples, n_features) predictors and the (n_samples,) response.
    max_components : int
        The largest component count cross-validated. With ``cap=True`` an upper bound: where the data (or the
        smallest training fold) support fewer, the curve stops there instead of raising (for a default).
    cv, groups, random_state
        ``"loo"`` (the paper's leave-one-out); an int k, shuffled K-fold seeded by ``random_state``; or ``groups``
        (labels), leave one group out, e.g. one specimen (the default ``cv`` then means that).

    Returns
    -------
    PLSCVResult
        ``rmse``, ``rmse_se`` (A + 1,) and ``predictions`` (n, A + 1) indexed by component count (0: the fold's mean);
        ``best_n_components`` (least RMSE), ``one_se_n_components`` (fewest within one SE), ``folds``, ``scheme``.

    Examples
    --------
    >>> import numpy as np
    >>> import roughsense as rs
    >>> rng = np.random.default_rng(0)
    >>> X = rng.normal(size=(12, 6))
    >>> y = 3 + X @ [1.0, 0.5, 0, 0, 0, 0] + 0.1 * rng.normal(size=12)
    >>> cv = rs.pls_cv(X, y, max_components=4)
    >>> cv.scheme, cv.rmse.round(2), cv.best_n_components, cv.one_se_n_components
    ('leave-one-out', array([1.63, 0.53, 0.33, 0.18, 0.15]), 4, 3)
    >>> rs.pls_cv(X, y, max_components=4, groups=np.repeat(np.arange(6), 2)).scheme
    'leave-one-group-out'
    """
    if cap:
        try:
            return pls_cv(X, y, max_components, cv, groups, random_state)
        except PLSConfigError as exc:
            if exc.supported is None or exc.supported < 1 or exc.supported >= max_components:
                raise
            return pls_cv(X, y, exc.supported, cv, groups, random_state, cap=True)
    if groups is not None and cv == "loo":
        cv = None
    X, y = validate_xy(SIMPLS(), X, y)
    A = _component_limit(max_components)
    n = X.shape[0]
    fid, scheme = fold_ids(n, cv, groups, random_state)
    # The work is many tiny matrix products: BLAS threads only add contention (badly so on a busy machine).
    with blas_threads_for(X):
        pred = _cv_predictions(X, y[:, None], fid, A)[0]
    rmse, rmse_se, fold_mse = error_curve(pred, y, fid)
    best = int(np.argmin(rmse[1:])) + 1
    one_se = int(np.flatnonzero(rmse[1:] <= rmse[best] + rmse_se[best])[0]) + 1
    return PLSCVResult(rmse=rmse, rmse_se=rmse_se, predictions=pred, best_n_components=best,
                       one_se_n_components=one_se, folds=fid, scheme=scheme, fold_mse=fold_mse)


# A batch of targets is cut into chunks whose Lanczos vectors take at most this many bytes. The steps are memory-bound
# (every reorthogonalisation reads the whole basis): 8 MiB, within the shared cache, cost 13 % less CPU than 64 MiB and
# held the study's two control threads 250 MiB lower; 2 MiB cost 23 % more (numpy's per-call overhead; bench_issue37.py
# --chunks).
_BATCH_BYTES = 8 * 2**20

# From this many targets on, leave-one-group-out (pls_cv_many) and nested LOSO's pairs of groups left out
# (_pair_choices) fit each fold in its own basis (the SVD of its training rows): every target of the fold then shares
# one diagonal operator and one held-out projection, so a Lanczos step is a few elementwise passes and the predictions
# one product at the end. Below it (the real target alone) the fold's SVD costs more than the downdates it saves.
_OWN_BASIS_MIN_TARGETS = 8


@dataclass(frozen=True)
class PLSCVBatch:
    """Cross-validated PLS1 of B targets sharing one X: ``rmse`` (B, A+1) and ``predictions`` (B, n, A+1).

    Index A as in :class:`PLSCVResult` (0 = the training mean). ``best_n_components`` is each target's
    argmin over 1..A, the rule :func:`pls_cv` uses.
    """

    rmse: np.ndarray
    predictions: np.ndarray
    folds: np.ndarray
    scheme: str

    @property
    def max_components(self) -> int:
        return self.rmse.shape[1] - 1

    @property
    def best_n_components(self) -> np.ndarray:
        return np.argmin(self.rmse[:, 1:], axis=1) + 1


def pls_cv_many(X, Y, max_components: int = defaults.MAX_COMPONENTS, cv="loo", groups=None, random_state=None, *,
                cap: bool = False) -> PLSCVBatch:
    """:func:`pls_cv` for many targets at once (the columns of Y), e.g. a permutation test's: only X'y depends on
    the target, so all share one rotation of X and run as one batch, several times faster than B calls and equal
    to them to rounding. ``cap=True`` lowers the component count for all targets alike.

    Parameters
    ----------
    X, Y : array-like
        (n_samples, n_features) predictors; (n_samples, n_targets) one response per column.
    max_components, cv, groups, random_state, cap
        As :func:`pls_cv`.

    Returns
    -------
    PLSCVBatch
        ``rmse`` (B, A + 1), ``predictions`` (B, n, A + 1), ``best_n_components`` (B,), ``folds``, ``scheme``.

    Examples
    --------
    >>> import numpy as np
    >>> import roughsense as rs
    >>> rng = np.random.default_rng(0)
    >>> X = rng.normal(size=(12, 6))
    >>> y = 3 + X @ [1.0, 0.5, 0, 0, 0, 0] + 0.1 * rng.normal(size=12)
    >>> Y = np.column_stack([y, rng.permutation(y)])  # the real target and a shuffled one
    >>> batch = rs.pls_cv_many(X, Y, max_components=4)
    >>> batch.rmse.shape, batch.predictions.shape
    ((2, 5), (2, 12, 5))
    >>> np.allclose(batch.rmse[0], rs.pls_cv(X, y, max_components=4).rmse)
    True
    """
    if groups is not None and cv == "loo":
        cv = None
    X, Y = _validated_targets(X, Y)
    A = _component_limit(max_components)
    n = X.shape[0]
    fid, scheme = fold_ids(n, cv, groups, random_state)
    F = int(fid.max()) + 1
    per_target = (A + 3) * F * min(X.shape) * 8
    chunk = max(1, _BATCH_BYTES // per_target)
    pred = np.empty((Y.shape[1], n, A + 1))
    try:
        with blas_threads_for(X):
            rotation = _rotation(X)
            if groups is not None and Y.shape[1] >= _OWN_BASIS_MIN_TARGETS:  # few folds, many targets: each its basis
                for _, rows, predictions in _own_basis_runs(X, Y, [np.flatnonzero(fid == f) for f in range(F)], A,
                                                               rotation):
                    pred[:, rows.ravel()] = predictions.transpose(1, 0, 2, 3).reshape(Y.shape[1], rows.size, A + 1)
            else:
                for start in range(0, Y.shape[1], chunk):
                    pred[start : start + chunk] = _cv_predictions(X, Y[:, start : start + chunk], fid, A, None,
                                                                  rotation)
    except PLSConfigError as exc:
        if not cap or exc.supported is None or exc.supported < 1 or exc.supported >= A:
            raise
        return pls_cv_many(X, Y, exc.supported, cv, groups, random_state, cap=True)
    rmse = np.sqrt(((pred - Y.T[:, :, None]) ** 2).mean(axis=1))
    return PLSCVBatch(rmse=rmse, predictions=pred, folds=fid, scheme=scheme)


def _validated_targets(X, Y) -> tuple[np.ndarray, np.ndarray]:
    """X as :class:`SIMPLS` takes it, and Y (n x B) with every column a target :func:`pls_cv` would take."""
    try:
        X = validate_data(SIMPLS(), X, ensure_min_samples=3, dtype=np.float64, reset=True)
    except ValueError as exc:
        raise PLSInputError(str(exc)) from None
    Y = np.asarray(Y, dtype=np.float64)
    if Y.ndim != 2 or Y.shape[0] != X.shape[0] or Y.shape[1] < 1:
        raise PLSInputError(f"Y must be n_samples x n_targets with n_samples={X.shape[0]}, got shape {Y.shape}")
    if not np.all(np.isfinite(Y)):
        raise PLSInputError("Y contains NaN or infinity")
    for column in Y.T:
        check_target(column)
    return X, Y


def nested_group_predictions(X, Y, groups, outer_predictions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nested leave-one-group-out: each held-out group's component count is chosen without it.

    ``outer_predictions`` (B, n, A+1) are the plain leave-one-group-out predictions of the targets Y (n x B)
    at every count; for the held-out group, the count is the argmin of a leave-one-group-out run over the
    other groups only (capped by A and by what its smallest inner training fold supports). Returns the
    nested predictions (B, n) and the chosen counts (B, n_groups), groups in order of first appearance.
    The same code serves the real targets (B = 1) and a permutation test's shuffled ones, so both go
    through exactly the same selection.
    """
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    groups = np.asarray(groups)
    A = outer_predictions.shape[2] - 1
    _, first = np.unique(groups, return_index=True)
    held = groups[None, :] == groups[np.sort(first)][:, None]  # (S, n), groups in order of first appearance
    usable = [int(min(A, len(rest) - int(np.unique(rest, return_counts=True)[1].max()) - 1, X.shape[1]))
              for rest in (groups[~h] for h in held)]  # capped by A and by the smallest inner training fold
    chosen = _pair_choices(X, Y, held, usable)
    if chosen is None:
        chosen = np.column_stack([pls_cv_many(X[~h], Y[~h], max_components=u, groups=groups[~h], cap=True)
                                  .best_n_components for h, u in zip(held, usable)])
    predictions = np.empty(outer_predictions.shape[:2])
    for j, h in enumerate(held):
        predictions[:, h] = np.take_along_axis(outer_predictions[:, h, :], chosen[:, j, None, None], axis=2)[:, :, 0]
    return predictions, chosen


def _pair_choices(X: np.ndarray, Y: np.ndarray, held: np.ndarray, usable: list[int]) -> np.ndarray | None:
    """Every group's inner choice (B, S) from one leave-two-groups-out batch: group j's inner fold k trains on every
    group but j and k, the very model of group k's inner fold j, so the S(S-1) inner models are S(S-1)/2, fitted once
    in the whole data's rotation, each predicting both groups it leaves out (equal to the per-group runs to rounding).

    None where the per-group runs would not all take the same count: fewer than 3 groups, unequal limits, or a limit
    that some inner run's own data (its rank) or some pair's Krylov space does not support (each run lowers its own).
    """
    S, U = held.shape[0], usable[0]
    if S < 3 or U < 1 or any(u != U for u in usable):
        return None
    for h in held:  # the rank each per-group run's own SVD would check
        rest = X[~h] - X[~h].mean(axis=0)
        if min(rest.shape[0] - 1, svd_rank(np.linalg.svd(rest, compute_uv=False), *rest.shape)) < U:
            return None
    first, second = np.triu_indices(S, k=1)
    if Y.shape[1] >= _OWN_BASIS_MIN_TARGETS:
        try:
            with blas_threads_for(X):
                return _own_basis_pair_choices(X, Y, held, U, first, second)
        except PLSConfigError:
            return None
    pair_rows = [np.flatnonzero(held[j] | held[k]) for j, k in zip(first, second)]
    rows = np.concatenate(pair_rows)
    fid = np.repeat(np.arange(first.size), [r.size for r in pair_rows])
    own = np.argmax(held[:, rows], axis=0)
    run = np.where(own == first[fid], second[fid], first[fid])  # the inner run an entry is held out for
    entries = [np.flatnonzero(run == j) for j in range(S)]
    entries = [e[np.argsort(rows[e], kind="stable")] for e in entries]  # each run's entries in X's row order
    chunk = max(1, _BATCH_BYTES // ((U + 3) * first.size * min(X.shape) * 8))
    chosen = np.empty((Y.shape[1], S), dtype=int)
    try:
        with blas_threads_for(X):
            rotation = _rotation(X)
            for start in range(0, Y.shape[1], chunk):
                part = Y[:, start : start + chunk]
                err2 = (_cv_predictions(X, part, fid, U, rows, rotation) - part.T[:, rows, None]) ** 2
                for j, mine in enumerate(entries):
                    rmse = np.sqrt(err2[:, mine].mean(axis=1))
                    chosen[start : start + chunk, j] = np.argmin(rmse[:, 1:], axis=1) + 1
    except PLSConfigError:
        return None
    return chosen


def _own_basis_pair_choices(X: np.ndarray, Y: np.ndarray, held: np.ndarray, U: int, first: np.ndarray,
                            second: np.ndarray) -> np.ndarray:
    """:func:`_pair_choices`' inner choices (B, S) with every pair fitted in its own basis, all targets at once.

    The pair's model predicts both groups it leaves out: group k's rows for group j's inner run and j's for k's. Each
    run's squared errors are summed over its pairs, and its count is the argmin of the RMSE over 1..U (as a run's own
    leave-one-group-out chooses). Pairs of one size go through in chunks of about :data:`_BATCH_BYTES` of Lanczos
    vectors. Raises PLSConfigError where a pair's Krylov space or training fold is too small.
    """
    B, S = Y.shape[1], held.shape[0]
    pair_rows = [np.flatnonzero(held[j] | held[k]) for j, k in zip(first, second)]
    sse = np.zeros((B, S, U + 1))
    for part, rows, predictions in _own_basis_runs(X, Y, pair_rows, U, _rotation(X)):
        err2 = (predictions - Y.T[:, rows].transpose(1, 0, 2)[..., None]) ** 2
        for f, i in enumerate(part):
            of_k = held[second[i], rows[f]]  # group k's rows are group j's inner fold k, and the other way round
            sse[:, first[i]] += err2[f][:, of_k].sum(axis=1)
            sse[:, second[i]] += err2[f][:, ~of_k].sum(axis=1)
    rmse = np.sqrt(sse / (~held).sum(axis=1)[None, :, None])  # a run's entries: every row but its own group's
    return np.argmin(rmse[:, :, 1:], axis=2) + 1


def _own_basis_runs(X: np.ndarray, Y: np.ndarray, fold_rows: list[np.ndarray], A: int,
                    rotation: tuple[np.ndarray, np.ndarray]):
    """Every fold (its held-out rows ``fold_rows[f]``) fitted in its own basis for all targets: yields (the folds, their
    rows (F, m), their predictions (F, B, m, A+1)) in chunks of folds of one size, each about :data:`_BATCH_BYTES` of
    Lanczos vectors. Raises PLSConfigError where a training fold or a Krylov space is too small for A."""
    Z, sv = rotation
    n = X.shape[0]
    _check_fold_support(sv, n, X.shape[1], np.array([n - r.size for r in fold_rows]), A)
    exhausted = _KRYLOV_RTOL * sv.max() ** 2
    sizes = np.array([r.size for r in fold_rows])
    chunk = max(1, _BATCH_BYTES // ((A + 1) * Y.shape[1] * Z.shape[1] * 8))
    for size in np.unique(sizes):  # folds of one size share the shapes of their bases: batched together
        folds = np.flatnonzero(sizes == size)
        for part in np.array_split(folds, -(-folds.size // chunk)):
            rows = np.stack([fold_rows[i] for i in part])
            yield part, rows, _own_basis_predictions(Z, Y, rows, A, exhausted, part)
