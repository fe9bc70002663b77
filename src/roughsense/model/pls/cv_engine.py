"""The arithmetic of model/pls/cv.py's exact cross-validation: every fold's PLS1 run as a Lanczos recurrence in one
shared rotation of the data (:class:`_RotatedFolds`, :class:`_FoldLanczos`), or each fold in its own basis when
many targets share few folds (:func:`_own_basis_predictions`); cv.py chooses between them and batches them.
"""
from __future__ import annotations

import numpy as np

from .simpls import PLSConfigError, PLSInputError, svd_rank

# When the cross-validation's Lanczos recurrence is exhausted: its next-vector norm beta lives on the scale
# of X'X, and below ~50 eps of its largest eigenvalue it is rounding noise of the products that form it.
_KRYLOV_RTOL = 1e-14


# Components of a new Lanczos vector along the fold's basis (the reorthogonalisation coefficients h)
# smaller than this, relative to the vector, are left in place: they are within ~500 ulp of the three-term
# step's own rounding, so removing them buys nothing measurable, and skipping the removal saves a batched
# product per step. Anything larger (rounding amplified by converged Ritz values) is removed.
_REORTH_SKIP_RTOL = 1e-13


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
