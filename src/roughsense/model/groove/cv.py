"""The groove model's nested cross-validation, batched: every outer fold, every inner leave-one-specimen-out fold,
every subset of terms and every target column from one set of sufficient statistics.

The model is least squares in logs, so a fit on any set of rows needs only the sums of the rows' design outer
products, design x target products and squared targets (:func:`row_stats`). A fold's training sums are the whole
sums less its held-out rows'; an inner fold's are its outer fold's less one specimen's rows; an inner fold's error
is its held-out rows' sums read against the inner fit. Every subset of the (at most four) terms is fitted this way
in every inner fold of every outer fold, each Gram matrix pseudo-inverted once for all target columns
(:func:`_inner_errors`), and the choice (:func:`walk_terms`) walks the terms in their fixed physical order, groove
first: a term is kept only if adding it to the terms kept so far lowers the inner leave-one-specimen-out error by
more than one standard error of the paired per-specimen difference (:data:`SELECTION_SE`). No outer held-out row
enters its own fold's choice or fit.

A term read in too few rows is not offered (:func:`offered`); rows whose offered terms are not all readable (NaN)
are left out of every fit (weight 0) and of every inner error; a
held-out row with an unreadable term is predicted at its fold's training mean of that term (the term then moves
nothing) and is flagged by the domain (model/groove/domain.py).
"""
from __future__ import annotations

import numpy as np

#: A term is kept only if it lowers the mean inner LOSO squared log error by more than this many standard errors of
#: the paired per-specimen difference (the one-SE rule: a term that helps no more than noise would is left out).
SELECTION_SE = 1.0
#: Relative cut-off of the pseudo-inverse: an exactly collinear subset (land = groove on half-and-half gratings) is
#: fitted as least squares' minimum-norm solution.
PINV_RCOND = 1e-10
#: A term is offered only where it was read in at least this share of the rows: a measure the study could rarely
#: read (a force whose gaps never resolve) would otherwise leave every row with one unreadable term out of every fit.
MIN_READABLE_SHARE = 0.8
#: About this many cells (outer folds x subsets x specimens x target columns) a working array: 16 MiB of float64.
CHUNK_CELLS = 1 << 21


def offered(terms: np.ndarray) -> np.ndarray:
    """The terms with each one read in too few rows (:data:`MIN_READABLE_SHARE`) set to 0 everywhere: not offered
    (a column of zeros never lowers an error, so it is never kept), and no row left out for it."""
    terms = np.asarray(terms, dtype=np.float64)
    scarce = np.isfinite(terms).mean(axis=0) < MIN_READABLE_SHARE if len(terms) else np.zeros(terms.shape[1], bool)
    return np.where(scarce[None, :], 0.0, terms)


def subsets(n_terms: int) -> list[np.ndarray]:
    """Each subset of the terms as the design columns it uses (0: the intercept), indexed by its bit mask."""
    return [np.array([0] + [1 + t for t in range(n_terms) if mask >> t & 1]) for mask in range(1 << n_terms)]


def design(terms: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The design (n, 1 + T) of centred terms (unreadable: 0) and each row's weight (1: every term readable)."""
    readable = np.all(np.isfinite(terms), axis=1)
    centred = np.where(np.isfinite(terms), terms - centre, 0.0)
    return np.column_stack([np.ones(len(terms)), centred]) * readable[:, None], readable.astype(np.float64)


def row_stats(D: np.ndarray, log_y: np.ndarray) -> np.ndarray:
    """Per row, flattened: the design's outer product (q*q), design x targets (q*B), squared targets (B), weight."""
    n, q = D.shape
    weight = D[:, 0]
    return np.concatenate([(D[:, :, None] * D[:, None, :]).reshape(n, q * q),
                           (D[:, :, None] * log_y[:, None, :]).reshape(n, -1),
                           weight[:, None] * log_y ** 2, weight[:, None]], axis=1)


def _split(stats: np.ndarray, q: int, n_targets: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    lead = stats.shape[:-1]
    gram = stats[..., :q * q].reshape(*lead, q, q)
    cross = stats[..., q * q:q * q + q * n_targets].reshape(*lead, q, n_targets)
    return gram, cross, stats[..., q * q + q * n_targets:-1], stats[..., -1]


def _sums(train: np.ndarray, codes: np.ndarray, n_specimens: int, stats: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray]:
    """Outer training sums (O, W) and each specimen's rows' sums within each outer training fold (O, S, W)."""
    outer = train.astype(np.float64) @ stats
    inner = np.stack([train[:, codes == s].astype(np.float64) @ stats[codes == s] for s in range(n_specimens)],
                     axis=1)
    return outer, inner


def _inverses(outer_gram: np.ndarray, inner_gram: np.ndarray, columns: list[np.ndarray]) -> list[np.ndarray]:
    """Per subset, the pseudo-inverse of every inner fold's Gram matrix (O, S, k, k): none depends on the targets."""
    train = outer_gram[:, None] - inner_gram
    return [np.linalg.pinv(train[..., c[:, None], c[None, :]], rcond=PINV_RCOND) for c in columns]


def _inner_errors(outer: np.ndarray, inner: np.ndarray, inverses: list[np.ndarray], columns: list[np.ndarray],
                  q: int, n_targets: int) -> tuple[np.ndarray, np.ndarray]:
    """Each inner fold's mean squared log error (O, M, S, B) under every subset M, and which inner folds count (O, S):
    those with a readable held-out row."""
    o_gram, o_cross, _, _ = _split(outer, q, n_targets)
    i_gram, i_cross, i_yy, i_count = _split(inner, q, n_targets)
    train_cross = o_cross[:, None] - i_cross
    errors = np.empty((outer.shape[0], len(columns), inner.shape[1], n_targets))
    for m, (c, inverse) in enumerate(zip(columns, inverses)):
        beta = inverse @ train_cross[..., c, :]  # (O, S, k, B)
        fitted = (beta * (i_gram[..., c[:, None], c[None, :]] @ beta)).sum(axis=-2)  # b' G b, by matrix products
        sse = i_yy - 2 * (beta * i_cross[..., c, :]).sum(axis=-2) + fitted
        errors[:, m] = sse / np.maximum(i_count, 1.0)[..., None]
    return errors, i_count > 0


def walk_terms(errors: np.ndarray, valid: np.ndarray, n_terms: int, se: float = SELECTION_SE) -> np.ndarray:
    """The subset chosen (O, B) as a bit mask: terms offered in order, each kept only if it lowers the mean inner
    error by more than ``se`` standard errors of the paired per-specimen difference."""
    n_outer, _, _, n_targets = errors.shape
    chosen = np.zeros((n_outer, n_targets), dtype=np.intp)
    counted = valid[:, :, None].astype(np.float64)  # (O, S, 1)
    n_valid = counted.sum(axis=1)  # (O, 1)
    for t in range(n_terms):
        offered = chosen | (1 << t)
        now = np.take_along_axis(errors, chosen[:, None, None, :], axis=1)[:, 0]  # (O, S, B)
        then = np.take_along_axis(errors, offered[:, None, None, :], axis=1)[:, 0]
        difference = (then - now) * counted
        mean = difference.sum(axis=1) / np.maximum(n_valid, 1.0)
        spread = np.sqrt(((difference - mean[:, None]) ** 2 * counted).sum(axis=1) / np.maximum(n_valid - 1.0, 1.0))
        standard_error = np.where(n_valid > 1, spread / np.sqrt(np.maximum(n_valid, 1.0)), np.inf)
        chosen = np.where(mean + se * standard_error < 0, offered, chosen)
    return chosen


def _outer_coefficients(outer: np.ndarray, columns: list[np.ndarray], chosen: np.ndarray, q: int,
                        n_targets: int) -> np.ndarray:
    """The chosen subset's least-squares fit on each outer training fold, full width (O, q, B), zeros elsewhere."""
    gram, cross, _, _ = _split(outer, q, n_targets)
    beta = np.zeros((outer.shape[0], q, n_targets))
    for m, c in enumerate(columns):
        fitted = np.linalg.pinv(gram[:, c[:, None], c[None, :]], rcond=PINV_RCOND) @ cross[:, c, :]
        use = chosen == m  # (O, B)
        beta[:, c, :] = np.where(use[:, None, :], fitted, beta[:, c, :])
    return beta


def nested_fit(terms: np.ndarray, log_y: np.ndarray, train: np.ndarray, specimens: np.ndarray,
               se: float = SELECTION_SE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every training mask of ``train`` (O, n) and target column of ``log_y`` (n, B): the terms chosen by inner
    leave-one-specimen-out within the mask (O, B bit masks), the fit on the mask (O, 1 + T, B; coefficients of centred
    terms, 0 for a term not chosen) and the centre the terms were measured from (T,)."""
    terms = np.asarray(terms, dtype=np.float64)
    centre = np.array([np.mean(c[np.isfinite(c)]) if np.isfinite(c).any() else 0.0 for c in terms.T])
    D, _ = design(terms, centre)
    q, n_terms = D.shape[1], terms.shape[1]
    codes = np.unique(np.asarray(specimens).astype(str), return_inverse=True)[1].ravel()
    n_specimens, columns = int(codes.max()) + 1, subsets(n_terms)
    gram_only = row_stats(D, np.zeros((len(D), 0)))
    outer_g, inner_g = _sums(train, codes, n_specimens, gram_only)
    inverses = _inverses(_split(outer_g, q, 0)[0], _split(inner_g, q, 0)[0], columns)
    width = max(1, CHUNK_CELLS // (train.shape[0] * len(columns) * n_specimens))
    chosen, beta = [], []
    for start in range(0, log_y.shape[1], width):
        part = log_y[:, start:start + width]
        outer, inner = _sums(train, codes, n_specimens, row_stats(D, part))
        errors, valid = _inner_errors(outer, inner, inverses, columns, q, part.shape[1])
        chosen.append(walk_terms(errors, valid, n_terms, se))
        beta.append(_outer_coefficients(outer, columns, chosen[-1], q, part.shape[1]))
    return np.concatenate(chosen, axis=1), np.concatenate(beta, axis=2), centre


def fold_centres(terms: np.ndarray, train: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Each training mask's mean of each term over its readable rows, centred (O, T): where an unreadable held-out
    term is put (it then moves nothing)."""
    D, weight = design(terms, centre)
    counts = np.maximum(train.astype(np.float64) @ weight, 1.0)
    return (train.astype(np.float64) @ D[:, 1:]) / counts[:, None]


def fold_ranges(terms: np.ndarray, train: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each training mask's range (O, T) low and high of each term over its readable rows (a term is held to it when
    predicting: a power law is not carried past its data)."""
    readable = np.all(np.isfinite(terms), axis=1)
    rows = (train & readable[None, :])[:, :, None]
    values = np.where(np.isfinite(terms), terms, 0.0)[None]
    low, high = np.where(rows, values, np.inf).min(axis=1), np.where(rows, values, -np.inf).max(axis=1)
    empty = low > high  # no readable training row: nothing to hold a term to (every coefficient is 0)
    return np.where(empty, -np.inf, low), np.where(empty, np.inf, high)


def nested_log_predictions(terms: np.ndarray, log_y: np.ndarray, folds: np.ndarray, specimens: np.ndarray,
                           se: float = SELECTION_SE) -> tuple[np.ndarray, np.ndarray]:
    """Out-of-fold log predictions (B, n) under the fold labels ``folds`` (each label a fold left out), the terms
    chosen anew within each training fold by inner leave-one-specimen-out, each held-out term held to its fold's
    training range (:func:`fold_ranges`); and the choices (F, B bit masks)."""
    terms = offered(terms)
    fold_of = np.unique(np.asarray(folds), return_inverse=True)[1].ravel()
    held = fold_of[None, :] == np.arange(int(fold_of.max()) + 1)[:, None]
    chosen, beta, centre = nested_fit(terms, log_y, ~held, specimens, se)
    imputed = fold_centres(terms, ~held, centre)[fold_of]  # (n, T)
    low, high = fold_ranges(terms, ~held)
    held_terms = np.clip(terms, low[fold_of], high[fold_of])
    centred = np.where(np.isfinite(terms), held_terms - centre, imputed)
    D = np.column_stack([np.ones(len(terms)), centred])
    return np.einsum("nq,nqb->bn", D, beta[fold_of]), chosen
