"""PLS1 by SIMPLS, as MATLAB's ``plsregress`` computes it: the paper's model (section 3.3).

The paper regresses perceived roughness on spatial spectra with ``plsregress``: X centred but not scaled, y centred,
SIMPLS (de Jong 1993). :class:`SIMPLS` reproduces that model; one fit holds the coefficients of every component
count 1..A, so predicting with fewer components needs no refit. Its exact, fast cross-validation is
:mod:`roughsense.model.pls.cv`.
"""
from __future__ import annotations

import contextlib
from typing import ClassVar

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from ..._util.checks import POSITIVE_INT, Integer, check
from ...errors import ConfigError, InputError
from ..loaded import FromModelFile
from ..registry import PLS

__all__ = ["SIMPLS", "PLSInputError", "PLSConfigError", "linear_predict"]


class PLSInputError(InputError, ValueError):
    """Bad data for PLS; also a ValueError so scikit-learn tooling (and its checks) recognise it."""


class PLSConfigError(ConfigError, ValueError):
    """An impossible PLS option (too many components, a bad CV scheme); also a ValueError for scikit-learn.

    ``supported`` is set when the problem is too many components: the largest count the data support.
    """

    def __init__(self, message: str, *, supported: int | None = None) -> None:
        super().__init__(message)
        self.supported = supported


# A covariance vector this much smaller than the first one is rounding noise: the Krylov space
# of (X'X, X'y) is exhausted and a further component would be arbitrary.
_EXHAUSTED_RTOL = 1e-12


def validate_xy(estimator, X, y, *, reset: bool = True):
    """scikit-learn's validation, re-raised as our error family with the same (sklearn-checked) message."""
    try:
        X, y = validate_data(estimator, X, y, y_numeric=True, ensure_min_samples=3, dtype=np.float64, reset=reset)
    except PLSConfigError:
        raise
    except ValueError as exc:
        raise PLSInputError(str(exc)) from None
    check_target(y)
    return X, y


def check_target(y: np.ndarray) -> None:
    if np.ptp(y) == 0:
        raise PLSInputError(f"y is constant ({y[0]:g} for all {y.size} samples); PLS needs a response that varies")


def svd_rank(sv: np.ndarray, n: int, p: int) -> int:
    """Numerical rank from singular values, with numpy's ``matrix_rank`` tolerance."""
    if sv.size == 0 or not sv.max() > 0:
        return 0
    return int((sv > sv.max() * max(n, p) * np.finfo(float).eps).sum())


def _max_components(X0: np.ndarray) -> tuple[int, int]:
    """Largest component count the centred data support: min(n-1, p, numerical rank)."""
    n, p = X0.shape
    rank = svd_rank(np.linalg.svd(X0, compute_uv=False), n, p)
    return min(n - 1, p, rank), rank


_BLAS = None


# Below this many matrix elements BLAS threads cost more than they save (and contend badly on a busy
# machine: refitting 140 LOO folds of 140 x 135 ran 20x slower with two threads than with one).
SINGLE_THREAD_MAX_ELEMENTS = 1_000_000


def single_threaded_blas():
    """A context that limits BLAS to one thread (the controller is built once: scanning libraries is slow)."""
    global _BLAS
    if _BLAS is None:
        from threadpoolctl import ThreadpoolController

        _BLAS = ThreadpoolController()
    return _BLAS.limit(limits=1, user_api="blas")


def blas_threads_for(X: np.ndarray):
    """One BLAS thread for a problem below :data:`SINGLE_THREAD_MAX_ELEMENTS`, the library's own threads above it."""
    return single_threaded_blas() if X.size <= SINGLE_THREAD_MAX_ELEMENTS else contextlib.nullcontext()


#: The least roughness a PLS model file without a trained range may predict (a positive ratio to the reference).
MIN_ROUGHNESS = 0.01


class SIMPLS(FromModelFile, RegressorMixin, BaseEstimator):
    """PLS1 regression by SIMPLS, numerically the model of MATLAB ``plsregress(X, y, A)``.

    X is centred, not scaled; y is centred. After ``fit`` the attributes mirror plsregress:

    - ``coef_`` (p,) and ``intercept_``: BETA for ``n_components`` (BETA = [intercept_; coef_]);
    - ``coef_path_`` (p, A) and ``intercept_path_`` (A,): the model with k = 1..A components
      (column k-1), so ``predict(X, n_components=k)`` needs no refit;
    - ``x_weights_`` (p, A): stats.W, with ``x_scores_ = (X - x_mean_) @ x_weights_``;
    - ``x_loadings_`` (p, A): XL; ``y_loadings_`` (A,): YL; ``x_scores_`` (n, A): XS (unit-norm columns);
      ``y_scores_`` (n, A): YS;
    - ``pct_var_`` (2, A): PCTVAR, fractions of X and y variance explained per component (not percent,
      exactly as plsregress returns them);
    - ``floor_``: the least roughness ``predict`` gives (-inf for a fit; a loaded model file's is half the smoothest
      surface it was trained on), and ``domain_``: its applicability domain (None for a fit; a file's, loaded).

    Signs follow the paper's eq. (2), r = s/||s||; MATLAB's SVD may flip a component's weights, scores and
    loadings together, which leaves the coefficients unchanged.

    Parameters
    ----------
    n_components : int
        How many components to fit (at most what the data support: min(n - 1, rank of centred X)).

    Examples
    --------
    >>> import numpy as np
    >>> import roughsense as rs
    >>> rng = np.random.default_rng(0)
    >>> X = rng.normal(size=(12, 6))
    >>> y = 3 + X @ [1.0, 0.5, 0, 0, 0, 0] + 0.1 * rng.normal(size=12)
    >>> model = rs.SIMPLS(n_components=3).fit(X, y)
    >>> model.coef_[:2].round(1)  # y's weights on the first two columns
    array([0.9, 0.5])
    >>> model.predict(X[:2]).round(2), model.predict(X[:2], n_components=1).round(2)
    (array([3.01, 4.71]), array([2.98, 4.6 ]))
    """

    family: ClassVar[str] = PLS

    def __init__(self, n_components: int = 2):
        self.n_components = n_components

    def fit(self, X, y):
        """Fit ``n_components`` components, and with them every smaller model (``coef_path_``).

        Parameters
        ----------
        X : array-like
            (n_samples, n_features) predictors, e.g. spectra.
        y : array-like
            (n_samples,) the response, e.g. perceived roughness.

        Returns
        -------
        SIMPLS
            This estimator, fitted.
        """
        k = self.n_components
        check(k, POSITIVE_INT, name="n_components", error=PLSConfigError, must="a positive whole number")
        X, y = validate_xy(self, X, y)
        with blas_threads_for(X):
            return self._fit(X, y, int(k))

    def _fit(self, X: np.ndarray, y: np.ndarray, k: int) -> SIMPLS:
        n, p = X.shape
        self.x_mean_ = X.mean(axis=0)
        self.y_mean_ = float(y.mean())
        X0 = X - self.x_mean_
        y0 = y - self.y_mean_
        k_max, rank = _max_components(X0)
        if k > k_max:
            raise PLSConfigError(
                f"n_components={k} is more than the data support ({k_max}: n_samples={n}, n_features={p}, "
                f"rank of centred X={rank})"
            )
        self._simpls(X0, y0, k)
        return self

    def _simpls(self, X0: np.ndarray, y0: np.ndarray, A: int) -> None:
        """SIMPLS on centred data, step for step as plsregress does it (for a single response)."""
        n, p = X0.shape
        W = np.zeros((p, A))
        P = np.zeros((p, A))
        Q = np.zeros(A)
        T = np.zeros((n, A))
        U = np.zeros((n, A))
        V = np.zeros((p, A))
        cov = X0.T @ y0
        cov_norm0 = np.linalg.norm(cov)
        if not cov_norm0 > 0:
            raise PLSInputError("y is uncorrelated with every column of X (X'y = 0); PLS finds no direction")
        for a in range(A):
            s = np.linalg.norm(cov)
            if not s > _EXHAUSTED_RTOL * cov_norm0:
                raise PLSConfigError(
                    f"n_components={A} is more than the data support: after {a} components X'y is exhausted "
                    f"(y is already fitted exactly in that subspace)"
                )
            r = cov / s
            t = X0 @ r
            t_norm = np.linalg.norm(t)
            t = t / t_norm
            P[:, a] = X0.T @ t
            Q[a] = y0 @ t
            W[:, a] = r / t_norm
            T[:, a] = t
            u = y0 * Q[a]  # plsregress: YS(:, a) = Y0 * q_a, then orthogonalised against earlier X scores
            if a:
                u -= T[:, :a] @ (T[:, :a].T @ u)
            U[:, a] = u
            v = P[:, a].copy()
            for _ in range(2):  # re-orthogonalise, as plsregress does, for stability
                v -= V[:, :a] @ (V[:, :a].T @ v)
            v /= np.linalg.norm(v)
            V[:, a] = v
            cov = cov - v * (v @ cov)
            cov = cov - V[:, : a + 1] @ (V[:, : a + 1].T @ cov)
        self.x_weights_ = W
        self.x_loadings_ = P
        self.y_loadings_ = Q
        self.x_scores_ = T
        self.y_scores_ = U
        self.coef_path_ = np.cumsum(W * Q, axis=1)
        self.intercept_path_ = self.y_mean_ - self.x_mean_ @ self.coef_path_
        self.coef_ = np.ascontiguousarray(self.coef_path_[:, -1])
        self.intercept_ = float(self.intercept_path_[-1])
        self.pct_var_ = np.vstack([(P**2).sum(axis=0) / (X0**2).sum(), Q**2 / (y0 @ y0)])
        self.floor_, self.domain_ = -np.inf, None

    def predict(self, X, n_components: int | None = None, surfaces=None):
        """Predictions of the model with ``n_components`` (default: all fitted) components, held at ``floor_``.

        Parameters
        ----------
        X : array-like
            (n_samples, n_features) predictors with the training columns.
        n_components : int, optional
            A count from 1 to the fitted one; no refit is needed.
        surfaces : array-like, optional
            Accepted as every family accepts it; PLS reads each row alone.

        Returns
        -------
        numpy.ndarray
            (n_samples,) predictions.
        """
        return np.maximum(self.linear_predict(X, n_components), self.floor_)

    def linear_predict(self, X, n_components: int | None = None) -> np.ndarray:
        """The fitted coefficients' own prediction, before the floor (PLS is linear: it may be <= 0).

        Parameters
        ----------
        X, n_components
            As :meth:`predict`.

        Returns
        -------
        numpy.ndarray
            (n_samples,) predictions.
        """
        check_is_fitted(self, "coef_path_")
        X = self._file_inputs(X)
        try:
            X = validate_data(self, X, reset=False, dtype=np.float64)
        except ValueError as exc:
            raise PLSInputError(str(exc)) from None
        k = self._component_index(n_components)
        return linear_predict(X, self.coef_path_[:, k], self.intercept_path_[k])

    def applicability(self, X, surfaces=None) -> list[str]:
        """Per row, why its prediction is not to be trusted ('' where nothing says so): a spectrum outside
        ``domain_`` (a loaded model file's), or a prediction held at ``floor_``.

        Parameters
        ----------
        X : array-like
            (n_samples, n_features) spectra.
        surfaces : array-like, optional
            (n_samples,) labels: the domain's peak readout reads a surface's presses together.

        Returns
        -------
        list of str
            One reason per row; '' where the row is inside.
        """
        raw = self.linear_predict(X)
        shape = self.domain_.reasons(self._file_inputs(X), surfaces) if self.domain_ is not None else [""] * raw.size
        reasons = []
        for value, why in zip(raw, shape):
            parts = [why] if why else []
            if value < self.floor_:
                whose = "half the smoothest trained surface" if self.floor_ != MIN_ROUGHNESS else "the least " \
                    "roughness an older model file may give"
                parts.append(f"PLS gave {value:.3g}, below {whose}; held at {self.floor_:.3g}")
            reasons.append("; ".join(parts))
        return reasons

    def _component_index(self, n_components: int | None) -> int:
        A = self.coef_path_.shape[1]
        if n_components is None:
            return A - 1
        check(n_components, Integer(1, A), name="n_components", error=PLSConfigError,
              must=f"a whole number in 1..{A} for this fit")
        return int(n_components) - 1

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.single_output = True
        tags.target_tags.multi_output = False
        return tags


def linear_predict(X: np.ndarray, coef: np.ndarray, intercept: float) -> np.ndarray:
    """The one prediction formula, shared by the estimator and loaded model files (bit-identical results)."""
    return np.asarray(X, dtype=np.float64) @ np.ascontiguousarray(coef, dtype=np.float64) + float(intercept)
