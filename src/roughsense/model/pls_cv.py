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

from .._util.checks import POSITIVE_INT, check, is_whole_number
from .pls import (
    SIMPLS,
    PLSConfigError,
    PLSInputError,
    blas_threads_for,
    check_target,
    svd_rank,
    validate_xy,
)

# When the cross-validation's Lanczos recurrence is exhausted: its next-vector norm beta lives on the scale
# of X'X, and below ~50 eps of its largest eigenvalue it is rounding noise of the products that form it.
_KRYLOV_RTOL = 1e-14


# Components of a new Lanczos vector along the fold's basis (the reorthogonalisation coefficients h)
# smaller than this, relative to the vector, are left in place: they are within ~500 ulp of the three-term
# step's own rounding, so removing them buys nothing measurable, and skipping the removal saves a batched
# product per step. Anything larger (rounding amplified by converged Ritz values) is removed.
_REORTH_SKIP_RTOL = 1e-13


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


def fold_ids(n: int, cv, groups, random_state) -> tuple[np.ndarray, str]:
    """Fold id per sample, 0..F-1, for LOO, leave-one-group-out or shuffled K-fold."""
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != (n,):
            raise PLSInputError(f"groups has {groups.size} entries for {n} samples")
        if cv not in (None, "logo", "loso"):
            raise PLSConfigError(f"groups= gives leave-one-group-out; cv={cv!r} cannot be combined with it")
        _, ids = np.unique(groups, return_inverse=True)
        if ids.max() < 1:
            raise PLSConfigError("leave-one-group-out needs at least 2 groups")
        return ids.astype(np.intp), "leave-one-group-out"
    if cv is None or cv == "loo":
        return np.arange(n, dtype=np.intp), "leave-one-out"
    if is_whole_number(cv):
        if not 2 <= cv <= n:
            raise PLSConfigError(f"K-fold needs 2 <= k <= n_samples={n}, got k={cv}")
        rng = np.random.default_rng(random_state)
        ids = np.empty(n, dtype=np.intp)
        for f, part in enumerate(np.array_split(rng.permutation(n), int(cv))):
            ids[part] = f
        return ids, f"{int(cv)}-fold"
    raise PLSConfigError(f"cv must be 'loo', a whole number of folds, or None with groups=; got {cv!r}")


def _component_limit(max_components) -> int:
    """The largest component count to cross-validate: a whole number >= 1 (a bool is not a count)."""
    return check(max_components, POSITIVE_INT, name="max_components", error=PLSConfigError,
                 must="a positive whole number")


#: Largest component count cross-validated when the caller names none (fewer where the data support fewer).
DEFAULT_MAX_COMPONENTS = 20


def pls_cv(X, y, max_components: int = DEFAULT_MAX_COMPONENTS, cv="loo", groups=None, random_state=None, *,
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
    rmse, rmse_se, fold_mse = _error_curve(pred, y, fid)
    best = int(np.argmin(rmse[1:])) + 1
    one_se = int(np.flatnonzero(rmse[1:] <= rmse[best] + rmse_se[best])[0]) + 1
    return PLSCVResult(rmse=rmse, rmse_se=rmse_se, predictions=pred, best_n_components=best,
                       one_se_n_components=one_se, folds=fid, scheme=scheme, fold_mse=fold_mse)


def _error_curve(pred: np.ndarray, y: np.ndarray, fid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """RMSE per component count, its standard error across folds (delta method on the folds' MSEs), and the
    folds' MSEs (F, A + 1)."""
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


def pls_cv_many(X, Y, max_components: int = DEFAULT_MAX_COMPONENTS, cv="loo", groups=None, random_state=None, *,
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


def _own_basis_predictions(Z: np.ndarray, Y: np.ndarray, held: np.ndarray, A: int, exhausted: float,
                           fold_ids: np.ndarray) -> np.ndarray:
    """Out-of-fold predictions (F, B, m, A+1) of F folds (numbered ``fold_ids`` in messages), each holding out m samples
    (``held``, F x m), for B targets.

    Each fold's centred training rows are rotated onto their own right singular vectors, in which its X'X is diagonal
    and its X'y are the targets' projections on the left ones: the same Krylov spaces as the shared rotation's
    downdated operator (:func:`_cv_predictions`), so the same models, to rounding. All F x B Lanczos runs advance
    together; the held-out samples' projections on every Lanczos vector are one product at the end.
    """
    (F, m), B = held.shape, Y.shape[1]
    y_mean, mu, start, projected = [], [], [], []
    for rows in held:
        train = np.ones(Z.shape[0], dtype=bool)
        train[rows] = False
        z_mean, Y_train = Z[train].mean(axis=0), Y[train]
        y_mean.append(Y_train.mean(axis=0))
        left, sv, right = np.linalg.svd(Z[train] - z_mean, full_matrices=False)
        mu.append(np.tile(sv**2, (B, 1)))
        start.append(((Y_train - y_mean[-1]).T @ left) * sv)  # X'y of the fold, (B, q)
        projected.append((Z[rows] - z_mean) @ right.T)  # the held-out samples about the fold's mean, (m, q)
    V, alpha, beta, norm = _diagonal_lanczos(np.concatenate(mu), np.concatenate(start), A, exhausted,
                                             np.repeat(fold_ids, B))
    q = V.shape[2]
    u = np.matmul(V.reshape(A, F, B, q), np.stack(projected).transpose(0, 2, 1)[None])  # (A, F, B, m)
    u = u.reshape(A, F * B, m)
    predictions = np.empty((A + 1, F * B, m))  # component-major while filling: each step writes one contiguous block
    predictions[0] = np.concatenate(y_mean)[:, None]
    eta, zeta = alpha[0], norm
    pi = u[0] / eta[:, None]
    for k in range(A):  # the D-Lanczos (CG) recurrences, seen through the held-out samples only
        if k:
            lam = beta[k - 1] / eta
            eta, zeta = alpha[k] - lam * beta[k - 1], -lam * zeta
            pi = (u[k] - beta[k - 1][:, None] * pi) / eta[:, None]
        np.add(predictions[k], zeta[:, None] * pi, out=predictions[k + 1])
    return predictions.transpose(1, 2, 0).reshape(F, B, m, A + 1)


def _diagonal_lanczos(mu: np.ndarray, start: np.ndarray, A: int, exhausted: float, folds: np.ndarray):
    """Lanczos with full reorthogonalisation, as :class:`_FoldLanczos` runs it, of G start vectors X'y (G, q), each
    under its own diagonal X'X (``mu``, G x q) and in its CV fold ``folds`` (G,): the basis (A, G, q), alpha (A, G),
    beta (A - 1, G), and |X'y| (G,)."""
    G, q = start.shape
    norm = np.sqrt(np.einsum("gq,gq->g", start, start))
    if not np.all(norm > 0):
        f = int(folds[np.flatnonzero(~(norm > 0))[0]])
        raise PLSInputError(f"in CV fold {f} the training y is constant or uncorrelated with X; PLS finds no direction")
    V = np.empty((A + 1, G, q))  # slots 0..k: the basis; slot k+1: the next vector while it is formed
    np.divide(start, norm[:, None], out=V[0])
    alpha, beta = np.empty((A, G)), np.empty((max(A - 1, 0), G))
    for k in range(A):
        w, x = V[k], V[k + 1]
        np.multiply(w, mu, out=x)
        alpha[k] = np.einsum("gq,gq->g", w, x)
        if k + 1 == A:
            break
        x -= alpha[k][:, None] * w
        if k:
            x -= beta[k - 1][:, None] * V[k - 1]
        beta[k] = _reorthogonalise_last(V, k, exhausted, A, folds)
    return V[:A], alpha, beta, norm


def _reorthogonalise_last(V: np.ndarray, k: int, exhausted: float, A: int, folds: np.ndarray) -> np.ndarray:
    """Slot k+1 of V orthogonalised against slots 0..k and normalised, in place; returns its norm before scaling.

    As :meth:`_FoldLanczos._reorthogonalise`: one product gives h = W'x and x'x together, beta^2 = x'x - h'h, and the
    removal is skipped where every h is at rounding level.
    """
    Vf = V.transpose(1, 0, 2)
    x = V[k + 1]
    g = np.matmul(Vf[:, : k + 2], x[:, :, None])[:, :, 0]
    h, xx = g[:, : k + 1], g[:, k + 1]
    hh = np.einsum("bk,bk->b", h, h)
    if np.all(hh <= 0.25 * xx):
        beta = np.sqrt(xx - hh)
        _check_krylov_step(beta, exhausted, A, k, folds)
        if not np.all(hh <= _REORTH_SKIP_RTOL**2 * xx):
            x -= np.matmul(h[:, None, :], Vf[:, : k + 1])[:, 0]
        x /= beta[:, None]
        return beta
    x -= np.matmul(h[:, None, :], Vf[:, : k + 1])[:, 0]  # never seen: Pythagoras would cancel; take the norm itself
    beta = np.sqrt(np.einsum("bq,bq->b", x, x))
    _check_krylov_step(beta, exhausted, A, k, folds)
    x /= beta[:, None]
    return beta


def _rotation(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The centred X's left singular vectors times its singular values (the samples, rotated), and the singular
    values: the same for every target, so computed once for all chunks of a batch."""
    U, sv, _ = np.linalg.svd(X - X.mean(axis=0), full_matrices=False)
    return U * sv, sv


def _cv_predictions(X: np.ndarray, Y: np.ndarray, fid: np.ndarray, A: int, rows: np.ndarray | None = None,
                    rotation: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Out-of-fold predictions (B, n, A+1) of every fold's PLS1 model for each of B targets (Y is n x B).

    ``fid`` gives each held-out entry its fold; an entry is a sample (``rows`` None: every sample held out once, folds
    a partition) or ``rows[i]``, so that folds may overlap (leave two groups out holds each sample out in many folds).

    PLS1 with k components is the least-squares fit restricted to the Krylov space
    K_k(S, s) of the centred cross-products S = X'X, s = X'y (Helland 1988); SIMPLS, NIPALS and
    Lanczos/conjugate gradients are different bases of the same space and give the same coefficients.
    Here each fold runs Lanczos with full reorthogonalisation on its own S_f, s_f, and the
    coefficients are accumulated by the D-Lanczos (conjugate-gradient) recurrences, so only the
    held-out samples' projections are ever formed, never a p-vector of coefficients per component.

    S_f is the full data's G = Xc'Xc minus a low-rank term (held-out rows and the shift of the
    mean). In the right singular vectors of Xc, G is diagonal, so S_f w costs O(p) per fold.
    Only s_f depends on the target, so B targets sharing X (a permutation test's shuffled targets) are
    B x F independent recurrences over the same rotation: they are advanced together as one batch,
    a "batch-fold" g = b * F + f per target b and fold f.
    """
    folds = _RotatedFolds(X, Y, fid, A, rows, _rotation(X) if rotation is None else rotation)
    lanczos = _FoldLanczos(folds, A)
    for k in range(A):
        u, u_fold, c_down, alpha = lanczos.apply_operator(k)
        lanczos.advance_predictions(k, u, u_fold, alpha)
        if k + 1 == A:
            break
        lanczos.next_vector(k, alpha, c_down)
    return np.ascontiguousarray(lanczos.pred.transpose(1, 2, 0))


class _RotatedFolds:
    """The data in the right singular vectors of the centred X, and the folds' sums in those coordinates.

    Rotating onto the right singular vectors makes G = Xc'Xc diagonal, and the rotation is orthogonal, so
    weights and predictions keep their accuracy (an eigendecomposition of G instead lost ~1e5x at spectra
    noise 1e-6: it is only accurate relative to the largest eigenvalue). Nothing is truncated: null
    directions simply never enter a Krylov space.
    """

    def __init__(self, X: np.ndarray, Y: np.ndarray, fid: np.ndarray, A: int, rows: np.ndarray | None,
                 rotation: tuple[np.ndarray, np.ndarray]) -> None:
        n, p = X.shape
        self.n, self.fid = fid.size, fid  # held-out entries: the samples, or the ``rows`` of overlapping folds
        self.B = Y.shape[1]
        self.F = int(fid.max()) + 1
        self.G = self.B * self.F
        m = np.bincount(fid, minlength=self.F)
        n_train = n - m
        Yc = Y - Y.mean(axis=0)
        self.y_mean = Y.mean(axis=0)
        Z, sv = rotation  # samples in the rotated coordinates; Z'Z = diag(lam)
        self.lam = sv**2
        _check_fold_support(sv, n, p, n_train, A)
        self.yz = Yc.T @ Z  # X'y of the whole data, (B, r)
        self.Yc, self.Z = (Yc, Z) if rows is None else (Yc[rows], Z[rows])
        self.dim = self.Z.shape[1]
        self.loo = rows is None and bool(np.all(m == 1)) and bool(np.all(fid == np.arange(n)))
        # Fold sums of scalars are products with the fold-membership matrix; those of rotated samples z_i go
        # fold by fold (one small product per fold: a membership product would cost F times the arithmetic).
        self.member = np.zeros((0, self.n) if self.loo else (self.F, self.n))
        if not self.loo:
            self.member[fid, np.arange(self.n)] = 1.0
        self.members = [] if self.loo else [np.flatnonzero(fid == f) for f in range(self.F)]
        self.Z_folds = [np.ascontiguousarray(self.Z[idx]) for idx in self.members]
        self.nt = n_train.astype(float)
        # Overlapping folds given fold by fold in equal blocks (leave two equal groups out): the fold sums and
        # held-out products are then one batched product each, not a Python loop over the many folds.
        blocks = rows is not None and np.all(m == m[0]) and np.array_equal(fid, np.repeat(np.arange(self.F), m[0]))
        self.block = int(m[0]) if blocks else 0
        self.Z_blocks = self.Z.reshape(self.F, self.block, self.dim) if self.block else None

    def fold_sum(self, M: np.ndarray) -> np.ndarray:
        """(B, n) or (B, n, 1) per sample -> (B, F) or (B, F, 1) per fold."""
        if self.loo:
            return M
        if self.block:
            return M.reshape(M.shape[0], self.F, self.block, *M.shape[2:]).sum(axis=2)
        return M @ self.member.T if M.ndim == 2 else np.matmul(self.member, M)

    def fold_sum_z(self, weights: np.ndarray) -> np.ndarray:
        """Sum over each fold's samples of weights[b, i] z_i: (B, n) -> (B, F, r)."""
        if self.block:
            return np.matmul(weights.reshape(-1, self.F, 1, self.block), self.Z_blocks).reshape(-1, self.F, self.dim)
        out = np.empty((weights.shape[0], self.F, self.Z.shape[1]))
        for f, (idx, Zf) in enumerate(zip(self.members, self.Z_folds)):
            np.matmul(weights[:, idx], Zf, out=out[:, f])
        return out

    def held_out_products(self, W: np.ndarray) -> np.ndarray:
        """z_i'w of the fold that holds sample i out, for every target: W (B, F, r) -> (B, n)."""
        if self.block:
            return np.matmul(self.Z_blocks, W[..., None]).reshape(W.shape[0], self.n)
        out = np.empty((W.shape[0], self.n))
        for f, (idx, Zf) in enumerate(zip(self.members, self.Z_folds)):
            out[:, idx] = W[:, f] @ Zf.T
        return out

    def per_sample(self, M: np.ndarray) -> np.ndarray:
        """(G, ...) per batch-fold -> (B, n, ...) per target and sample."""
        M = M.reshape(self.B, self.F, *M.shape[1:])
        return M if self.loo else M[:, self.fid]

    def training_means(self) -> tuple[np.ndarray, np.ndarray]:
        """Each training fold's mean of z (F, r) and of yc (B, F), in centred rotated coordinates."""
        d = -(self.Z if self.loo else self.member @ self.Z) / self.nt[:, None]
        e = -self.fold_sum(self.Yc.T[:, :, None])[:, :, 0] / self.nt
        return d, e

    def start_vectors(self, d: np.ndarray, e: np.ndarray) -> np.ndarray:
        """X'y per batch-fold (G, r): the full data's, minus the held-out rows', minus the shift of the mean."""
        Yc, Z = self.Yc, self.Z
        held_z_y = Yc.T[:, :, None] * Z[None] if self.loo else self.fold_sum_z(Yc.T)
        return (self.yz[:, None, :] - held_z_y - (self.nt[:, None] * d)[None] * e[:, :, None]).reshape(self.G, self.dim)


def _check_fold_support(sv: np.ndarray, n: int, p: int, n_train: np.ndarray, A: int) -> None:
    """Refuse more components than the data's rank or the smallest training fold support."""
    rank = svd_rank(sv, n, p)
    k_max = min(n - 1, p, rank)
    k_fold = int(n_train.min()) - 1
    if min(k_max, k_fold) < A:
        raise PLSConfigError(
            f"max_components={A} is more than the data support (n_samples={n}, n_features={p}, rank={rank}, "
            f"smallest training fold={int(n_train.min())} samples: at most {min(k_max, k_fold)} components)",
            supported=min(k_max, k_fold),
        )


class _FoldLanczos:
    """Every batch-fold's Lanczos basis, its CG coefficients and its held-out predictions, one step at a time.

    ``V[j]`` holds every batch-fold's j-th Lanczos vector (component-major, so the elementwise work runs over
    contiguous (G, r) blocks); ``Vf`` is the same memory batch-fold by batch-fold, for the batched products.
    At step k, slots 0..k hold the basis, slot k+1 the fold's downdate vector, slot k+2 the next vector.
    """

    def __init__(self, folds: _RotatedFolds, A: int) -> None:
        self.folds, self.A = folds, A
        B, F, G, n, dim = folds.B, folds.F, folds.G, folds.n, folds.dim
        self.d, e = folds.training_means()
        s0 = folds.start_vectors(self.d, e)
        s0_norm = np.sqrt(np.einsum("fp,fp->f", s0, s0))
        if not np.all(s0_norm > 0):
            f = int(np.flatnonzero(~(s0_norm > 0))[0]) % F
            raise PLSInputError(f"in CV fold {f} the training y is constant or uncorrelated with X; PLS finds no direction")
        self.exhausted = _KRYLOV_RTOL * folds.lam.max()
        self.pred = np.empty((A + 1, B, n))  # component-major while filling: each step writes one contiguous block
        self.pred[0] = folds.y_mean[:, None] + folds.per_sample(e.reshape(G))
        self.V = np.empty((A + 3, G, dim))
        self.Vf = self.V.transpose(1, 0, 2)
        np.divide(s0, s0_norm[:, None], out=self.V[0])
        self.lam_rows = np.tile(folds.lam, (G, 1))  # a same-shape operand is ~2x faster than a broadcast one
        self.d_rows = np.tile(self.d, (B, 1))
        self.back = np.empty((G, 1, dim))
        self.coef = np.zeros((G, 1, A + 3))  # combination coefficients of the batched products
        self.loo_scale = 1.0 + 1.0 / folds.nt
        self.beta_prev = np.zeros(G)
        self.eta = np.ones(G)
        self.zeta = s0_norm.copy()
        self.pi = np.zeros((B, n))  # held-out sample's projection on the current CG direction
        self.u_hist = np.empty((A, B, n))  # u_i = z_i'w_k of every step

    def apply_operator(self, k: int):
        """x = G w into slot k+2 and the fold's downdate into slot k+1; returns u, its fold sums, c and alpha.

        S_f w = (G - X_I'X_I - n_t d d') w; d'w = -sum_I(z_i'w)/n_t, so only u_i = z_i'w is needed.
        (For LOO the previous step's reorthogonalisation product already gave it.)
        """
        folds, V = self.folds, self.V
        B, F, G, n, dim = folds.B, folds.F, folds.G, folds.n, folds.dim
        w = V[k]
        if folds.loo:
            u = self.u_hist[k] if k else np.einsum("ip,bip->bi", folds.Z, folds.per_sample(w))
        else:  # z_i'w of the fold that holds i out: one product for all folds, then each sample's own fold
            u = folds.held_out_products(w.reshape(B, F, dim))
        self.u_hist[k] = u
        x = V[k + 2]
        np.multiply(w, self.lam_rows, out=x)  # G w, to which the downdate and the three-term step are applied
        down = V[k + 1]
        if folds.loo:  # d = -z_i/n_t: both corrections are one rank-1 term, c_i z_i with c_i = u_i (1 + 1/n_t)
            down.reshape(B, n, dim)[...] = folds.Z
            c_down = (u * self.loo_scale).reshape(G)
            u_fold = u
            alpha = np.einsum("fp,fp->f", w, x) - c_down * u.reshape(G)
        else:
            u_fold = folds.fold_sum(u)
            np.subtract(folds.fold_sum_z(u).reshape(G, dim), self.d_rows * u_fold.reshape(G, 1), out=down)
            c_down = 1.0
            alpha = np.einsum("fp,fp->f", w, x) - np.einsum("fp,fp->f", w, down)
        return u, u_fold, c_down, alpha

    def advance_predictions(self, k: int, u: np.ndarray, u_fold: np.ndarray, alpha: np.ndarray) -> None:
        """D-Lanczos (CG) update of the coefficients, seen only through the held-out samples.

        (z_i - d_f)'w = u_i + u_fold_f / n_t.
        """
        folds = self.folds
        per_sample = folds.per_sample
        shift = per_sample((u_fold / folds.nt).reshape(folds.G))
        if k:
            lam_k = self.beta_prev / self.eta
            self.eta = alpha - lam_k * self.beta_prev
            self.zeta = -lam_k * self.zeta
            self.pi = (u + shift - per_sample(self.beta_prev) * self.pi) / per_sample(self.eta)
        else:
            self.eta = alpha
            self.pi = (u + shift) / per_sample(self.eta)
        np.add(self.pred[k], per_sample(self.zeta) * self.pi, out=self.pred[k + 1])

    def next_vector(self, k: int, alpha: np.ndarray, c_down) -> None:
        """The next Lanczos vector into slot k+1: three-term step and downdate, then full reorthogonalisation.

        The downdate and the three-term recurrence are one batched product over the adjacent slots
        (w_{k-1}, w_k, downdate): x = G w - beta w_{k-1} - alpha w_k - c down.
        """
        x, back, Vf = self.V[k + 2], self.back, self.Vf
        c3 = self.coef[:, :, :3]
        c3[:, 0, 0] = self.beta_prev
        c3[:, 0, 1] = alpha
        c3[:, 0, 2] = c_down
        if k:
            np.matmul(c3, Vf[:, k - 1 : k + 2], out=back)
        else:
            np.matmul(c3[:, :, 1:], Vf[:, 0:2], out=back)
        x -= back[:, 0]
        self.beta_prev = self._reorthogonalise(k, x)

    def _reorthogonalise(self, k: int, x: np.ndarray) -> np.ndarray:
        """One classical Gram-Schmidt pass against the basis; returns beta, the new vector's norm before scaling.

        The three-term step already removed the two large terms. One product gives the coefficients h = W'x
        together with x'x, so beta^2 = x'x - h'h (Pythagoras; h is rounding-sized, so nothing cancels), and a
        second product forms the new unit vector (x - W h) / beta directly: no separate subtract, norm and scale
        passes. That second product is skipped in the steps where every fold's h is at rounding level.
        """
        folds, V, Vf, back = self.folds, self.V, self.Vf, self.back
        B, F, G, n = folds.B, folds.F, folds.G, folds.n
        g = np.matmul(Vf[:, : k + 3], x[:, :, None])[:, :, 0]
        h = g[:, : k + 1]
        hh = np.einsum("fk,fk->f", h, h)
        xx = g[:, k + 2]
        cr = self.coef[:, :, : k + 3]
        cr[:, 0, k + 1] = 0.0  # the downdate slot
        if np.all(hh <= _REORTH_SKIP_RTOL**2 * xx):  # x is already orthogonal to the basis to ~ulp level
            beta = np.sqrt(xx - hh)
            _check_krylov_step(beta, self.exhausted, self.A, k, F)
            inv = 1.0 / beta
            np.multiply(x, inv[:, None], out=V[k + 1])
            if folds.loo:
                self.u_hist[k + 1] = (g[:, k + 1] * inv).reshape(B, n)
        elif np.all(hh <= 0.25 * xx):
            beta = np.sqrt(xx - hh)
            _check_krylov_step(beta, self.exhausted, self.A, k, F)
            inv = 1.0 / beta
            np.multiply(h, -inv[:, None], out=cr[:, 0, : k + 1])
            cr[:, 0, k + 2] = inv
            np.matmul(cr, Vf[:, : k + 3], out=back)
            V[k + 1] = back[:, 0]
            if folds.loo:  # z_i'w_{k+1} = (z_i'x - sum_j (z_i'w_j) h_j) / beta, z_i'x from the product above
                self.u_hist[k + 1] = ((g[:, k + 1] - np.einsum("kf,fk->f", self.u_hist[: k + 1].reshape(k + 1, G), h))
                                      * inv).reshape(B, n)
        else:  # never seen: so much was removed that Pythagoras would cancel; take the norm itself
            np.negative(h, out=cr[:, 0, : k + 1])
            cr[:, 0, k + 2] = 1.0
            np.matmul(cr, Vf[:, : k + 3], out=back)
            beta = np.sqrt(np.einsum("fp,fp->f", back[:, 0], back[:, 0]))
            _check_krylov_step(beta, self.exhausted, self.A, k, F)
            np.divide(back[:, 0], beta[:, None], out=V[k + 1])
            if folds.loo:
                self.u_hist[k + 1] = np.einsum("ip,bip->bi", folds.Z, V[k + 1].reshape(B, n, folds.dim))
        return beta


def _check_krylov_step(beta: np.ndarray, exhausted: float, A: int, k: int, n_folds: int | np.ndarray) -> None:
    """Refuse a Lanczos step whose new direction is rounding noise: the fold's Krylov space is exhausted. ``n_folds``:
    the number of folds (runs are batch-folds b * F + f) or each run's fold."""
    if not beta.min() > exhausted:  # also catches NaN
        run = int(np.flatnonzero(~(beta > exhausted))[0])
        f = run % n_folds if isinstance(n_folds, int) else int(n_folds[run])
        raise PLSConfigError(
            f"max_components={A} is more than the data support numerically: in CV fold {f} the Krylov "
            f"space of X'X and X'y is exhausted after {k + 1} components (what is left is rounding noise); "
            f"use at most {k + 1}",
            supported=k + 1,
        )
