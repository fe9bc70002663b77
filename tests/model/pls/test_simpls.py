"""SIMPLS (PLS1) and its exact cross-validation, checked against scikit-learn, ikpls and algebra."""
from __future__ import annotations

import contextlib
import io

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st
from sklearn.cross_decomposition import PLSRegression
from sklearn.model_selection import LeaveOneOut, cross_val_predict
from sklearn.utils.estimator_checks import parametrize_with_checks
from threadpoolctl import threadpool_limits

from roughsense import SIMPLS, pls_cv
from roughsense.errors import ConfigError, InputError
from roughsense.model.pls.cv import PLSCVResult


def spectra(n_specimens=14, repetitions=10, p=45, noise=0.02, seed=0):
    """Spectra-like data: one peak per specimen (its wavelength) plus a fixed ridge peak; y = f(wavelength)."""
    rng = np.random.default_rng(seed)
    freq = np.linspace(0.1, 1.0, p)
    X, y, groups = [], [], []
    for s in range(n_specimens):
        f0 = 0.15 + 0.8 * rng.random()
        base = np.exp(-(((freq - f0) / 0.04) ** 2)) + 0.5 * np.exp(-(((freq - 1.0) / 0.05) ** 2))
        for _ in range(repetitions):
            X.append(base * (1 + 0.05 * rng.standard_normal()) + noise * rng.standard_normal(p))
            y.append(f0**-0.8)
            groups.append(f"S{s}")
    return np.array(X), np.array(y), np.array(groups)


def refit_predictions(X, y, folds, A):
    """Out-of-fold predictions by refitting SIMPLS from scratch on every training fold."""
    out = np.empty((len(y), A + 1))
    with threadpool_limits(1):  # many tiny fits: BLAS threads only contend
        _refit(X, y, folds, A, out)
    return out


def assert_nested_choices_are_inner_refits(X, Y, groups, outer, nested, chosen, A):
    """Every group's inner choice (of each target column) is what refitting SIMPLS on its inner folds chooses, and
    its nested predictions are the outer run's at that count."""
    for j, name in enumerate(pd.unique(groups)):
        held = groups == name
        for b in range(Y.shape[1]):
            inner = refit_predictions(X[~held], Y[~held, b], groups[~held], A)
            rmse = np.sqrt(((inner - Y[~held, b][:, None]) ** 2).mean(axis=0))
            assert chosen[b, j] == 1 + int(np.argmin(rmse[1:]))
            np.testing.assert_array_equal(nested[b, held], outer[b, held, chosen[b, j]])


def _refit(X, y, folds, A, out):
    for f in np.unique(folds):
        test = folds == f
        model = SIMPLS(A).fit(X[~test], y[~test])
        out[test, 0] = y[~test].mean()
        for k in range(1, A + 1):
            out[test, k] = model.predict(X[test], n_components=k)


def rel_err(a, b):
    return np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300))


# --------------------------------------------------------------------------- the estimator


def test_matches_sklearn_pls_regression_for_every_component_count():
    X, y, _ = spectra(n_specimens=8, repetitions=5, p=40)
    model = SIMPLS(n_components=12).fit(X, y)
    for k in range(1, 13):
        ref = PLSRegression(n_components=k, scale=False).fit(X, y)
        assert rel_err(model.predict(X, n_components=k), ref.predict(X).ravel()) < 1e-8
        expected_coef = ref.coef_.ravel()
        assert np.allclose(model.coef_path_[:, k - 1], expected_coef, rtol=1e-7, atol=1e-9 * np.abs(expected_coef).max())


def test_coefficients_are_the_krylov_least_squares_solution():
    """PLS1 with k components = least squares of y0 on X0 restricted to K_k(X0'X0, X0'y0) (Helland 1988)."""
    rng = np.random.default_rng(3)
    X = rng.standard_normal((30, 6))
    y = X @ rng.standard_normal(6) + 0.3 * rng.standard_normal(30)
    X0, y0 = X - X.mean(0), y - y.mean()
    S, s = X0.T @ X0, X0.T @ y0
    model = SIMPLS(4).fit(X, y)
    for k in range(1, 5):
        K = np.linalg.qr(np.column_stack([np.linalg.matrix_power(S, j) @ s for j in range(k)]))[0]
        beta = K @ np.linalg.solve(K.T @ S @ K, K.T @ s)
        assert np.allclose(model.coef_path_[:, k - 1], beta, rtol=1e-10, atol=1e-12)
        assert model.intercept_path_[k - 1] == pytest.approx(y.mean() - X.mean(0) @ beta, rel=1e-10)


def test_plsregress_outputs_are_consistent():
    X, y, _ = spectra(n_specimens=6, repetitions=4, p=12, seed=1)
    A = 5
    m = SIMPLS(A).fit(X, y)
    X0, y0 = X - X.mean(0), y - y.mean()
    assert np.allclose(m.x_scores_, X0 @ m.x_weights_)  # XS = X0 W
    assert np.allclose(m.x_scores_.T @ m.x_scores_, np.eye(A), atol=1e-10)  # orthonormal scores
    assert np.allclose(m.x_loadings_, X0.T @ m.x_scores_)  # XL = X0' XS
    assert np.allclose(m.y_loadings_, y0 @ m.x_scores_)  # YL = Y0' XS
    assert np.allclose(m.coef_, m.x_weights_ @ m.y_loadings_)  # BETA = W YL'
    assert m.intercept_ == pytest.approx(y.mean() - X.mean(0) @ m.coef_)
    # PCTVAR row 2 is the fraction of y variance explained: it sums to the training R^2.
    r2 = 1 - np.sum((y - m.predict(X)) ** 2) / np.sum(y0**2)
    assert m.pct_var_.shape == (2, A)
    assert m.pct_var_[1].sum() == pytest.approx(r2, rel=1e-10)
    # With as many components as the rank, every bit of X variance is explained.
    full = SIMPLS(12).fit(X, y)
    assert full.pct_var_[0].sum() == pytest.approx(1.0, rel=1e-9)


def test_paper_equations_give_the_same_model():
    """The paper's eqs. (1)-(7) (deflating X and y) span the same model; its weights act on the deflated X,
    so on the original X the coefficients are W (P'W)^-1 b, which must equal SIMPLS's."""
    X, y, _ = spectra(n_specimens=5, repetitions=4, p=15, seed=2)
    Xa, ya = X - X.mean(0), y - y.mean()
    model = SIMPLS(6).fit(X, y)
    R, P, B = [], [], []
    for _ in range(6):
        s = Xa.T @ ya  # (1)
        r = s / np.linalg.norm(s)  # (2)
        t = Xa @ r  # (3)
        p = Xa.T @ t / (t @ t)  # (4)
        b = t @ ya / (t @ t)  # (5)
        Xa = Xa - np.outer(t, p)  # (6)
        ya = ya - b * t  # (7)
        R.append(r), P.append(p), B.append(b)
    W, Pm = np.column_stack(R), np.column_stack(P)
    for k in range(1, 7):
        beta = W[:, :k] @ np.linalg.solve(Pm[:, :k].T @ W[:, :k], np.array(B[:k]))
        assert np.allclose(model.coef_path_[:, k - 1], beta, rtol=1e-8, atol=1e-10)


@parametrize_with_checks([SIMPLS()])
def test_scikit_learn_estimator_checks(estimator, check):
    """Every scikit-learn estimator check passes (check_array_api_input skips itself without SCIPY_ARRAY_API)."""
    check(estimator)


@pytest.mark.parametrize(
    ("X", "y", "error", "match"),
    [
        (np.array([[1.0, np.nan], [2.0, 1.0], [3.0, 0.0], [4, 2]]), np.arange(4.0), InputError, "NaN"),
        (np.array([[1.0, np.inf], [2.0, 1.0], [3.0, 0.0], [4, 2]]), np.arange(4.0), InputError, "infinity"),
        (np.array([[1.0, 2.0], [2.0, 1.0], [3.0, 0.0], [4, 2]]), np.array([0, 1, np.nan, 2]), InputError, "NaN"),
        (np.array([[1.0, 2.0], [2.0, 1.0]]), np.array([0.0, 1.0]), InputError, "minimum of 3"),
        (np.arange(8.0).reshape(4, 2) ** 1.5, np.full(4, 2.5), InputError, "constant"),
        (np.arange(10.0).reshape(5, 2), np.arange(4.0), InputError, "inconsistent numbers of samples"),
    ],
)
def test_bad_data_is_refused_clearly(X, y, error, match):
    with pytest.raises(error, match=match):
        SIMPLS(1).fit(X, y)
    with pytest.raises(error, match=match):
        pls_cv(X, y, max_components=1)


def test_too_many_components_is_refused():
    rng = np.random.default_rng(0)
    X, y = rng.standard_normal((6, 10)), rng.standard_normal(6)
    with pytest.raises(ConfigError, match="n_samples=6"):
        SIMPLS(6).fit(X, y)  # at most n - 1 = 5
    SIMPLS(5).fit(X, y)
    X = rng.standard_normal((20, 3))
    X = np.column_stack([X, X @ [1.0, 2.0, -1.0], 2 * X[:, 0]])  # rank 3 with 5 columns
    y = rng.standard_normal(20)
    with pytest.raises(ConfigError, match="rank of centred X=3"):
        SIMPLS(4).fit(X, y)
    with pytest.raises(ConfigError, match="rank=3"):
        pls_cv(X, y, max_components=4)
    with pytest.raises(ConfigError):
        SIMPLS(0).fit(X, y)
    model = SIMPLS(2).fit(X, y)
    with pytest.raises(ConfigError, match=r"1\.\.2"):
        model.predict(X, n_components=3)


def test_an_exhausted_krylov_space_is_refused_not_nan():
    """Orthogonal equal-variance columns: X'X = cI, so one component fits y exactly and a second is undefined."""
    H = np.array([[1, 1], [1, -1]])
    H8 = np.kron(np.kron(H, H), H).astype(float)
    X = H8[:, 1:5]  # centred, orthogonal, equal norms; rank 4
    y = X @ [1.0, 2.0, 0.5, -1.0] + 3.0
    model = SIMPLS(1).fit(X, y)
    assert np.allclose(model.predict(X), y)
    with pytest.raises(ConfigError, match="exhausted"):
        SIMPLS(2).fit(X, y)
    with pytest.raises(ConfigError, match="exhausted"):
        pls_cv(X, y, max_components=2, groups=np.repeat([0, 1], 4))


# --------------------------------------------------------------------------- cross-validation


def test_numerically_exhausted_spectra_are_refused_with_the_usable_count():
    """Noise-free spectra of 14 specimens span ~15 directions; a 20th component would be rounding noise."""
    X, y, _ = spectra(p=135, noise=1e-9, seed=5)
    with pytest.raises(ConfigError, match=r"exhausted after (\d+) components.*use at most \1"):
        pls_cv(X, y, max_components=20)


def test_loo_equals_sklearn_cross_val_predict():
    X, y, _ = spectra(n_specimens=6, repetitions=5, p=25, seed=4)
    result = pls_cv(X, y, max_components=8, cv="loo")
    for k in (1, 3, 8):
        expected = cross_val_predict(PLSRegression(n_components=k, scale=False), X, y, cv=LeaveOneOut()).ravel()
        assert rel_err(result.predictions[:, k], expected) < 1e-6
    loo_mean = (y.sum() - y) / (len(y) - 1)  # index 0: the training mean of each fold
    assert np.allclose(result.predictions[:, 0], loo_mean)
    assert result.rmse[0] == pytest.approx(np.sqrt(np.mean((loo_mean - y) ** 2)))


@pytest.mark.parametrize("noise", [0.02, 1e-4, 1e-6])
@pytest.mark.parametrize("scheme", ["loo", "groups", "kfold"])
def test_equals_refitting_every_fold(noise, scheme):
    """The paper's problem size (140 x 135) including ill-conditioned spectra: exact to 1e-6 relative."""
    X, y, groups = spectra(p=135, noise=noise, seed=5)
    kwargs = {"loo": {"cv": "loo"}, "groups": {"groups": groups}, "kfold": {"cv": 7, "random_state": 1}}[scheme]
    A = 20 if scheme != "groups" else 12
    result = pls_cv(X, y, max_components=A, **kwargs)
    reference = refit_predictions(X, y, result.folds, A)
    assert rel_err(result.predictions, reference) < 1e-6
    rmse = np.sqrt(np.mean((reference - y[:, None]) ** 2, axis=0))
    assert np.allclose(result.rmse, rmse, rtol=1e-6)
    assert result.best_n_components == int(np.argmin(rmse[1:])) + 1


@pytest.mark.parametrize("cv", ["loo", 7])
def test_nearly_noise_free_spectra_at_the_usable_component_count(cv):
    """Noise 1e-8: the Krylov space of 14 specimens is nearly exhausted at 15 components, where Lanczos
    loses orthogonality fastest (converged Ritz values); the reorthogonalisation must keep it exact."""
    X, y, _ = spectra(p=135, noise=1e-8, seed=5)
    result = pls_cv(X, y, max_components=15, cv=cv, random_state=1)
    assert rel_err(result.predictions, refit_predictions(X, y, result.folds, 15)) < 1e-6


def test_equals_ikpls_fast_cross_validation():
    from ikpls.fast_cross_validation.numpy import PLS

    X, y, groups = spectra(n_specimens=10, repetitions=6, p=45, seed=6)
    A = 10
    ours = pls_cv(X, y, max_components=A, groups=groups)
    pls = PLS(algorithm=2, center_X=True, center_Y=True, scale_X=False, scale_Y=False)
    with contextlib.redirect_stdout(io.StringIO()):
        by_fold = pls.cross_validate(X, y, A, groups, lambda y_val, y_pred: y_pred, n_jobs=1, verbose=0)
    for group, y_pred in by_fold.items():
        rows = groups == group
        assert rel_err(ours.predictions[rows, 1:], np.asarray(y_pred)[:, :, 0].T) < 1e-6


@pytest.mark.parametrize("drop", [None, 4])  # equal groups (the batched blocks); one group a press short (the loops)
def test_nested_choice_is_each_groups_own_inner_cv_from_one_leave_two_out_batch(monkeypatch, drop):
    """Nested LOSO chooses each held-out group's count by a LOSO over the other groups: refitted here group by group,
    while the batch fits each pair of groups left out once (group j's inner fold k is group k's inner fold j)."""
    from roughsense.model.pls import cv as engine

    X, y, groups = spectra(n_specimens=6, repetitions=3, p=12, noise=0.05, seed=3)
    if drop is not None:
        X, y, groups = np.delete(X, drop, axis=0), np.delete(y, drop), np.delete(groups, drop)
    names, codes = np.unique(groups, return_inverse=True)
    rng = np.random.default_rng(1)
    Y = np.column_stack([y] + [rng.permutation(np.unique(y))[codes] for _ in range(3)])  # shuffled per specimen
    outer = engine.pls_cv_many(X, Y, max_components=3, groups=groups).predictions
    overlapping = []
    original = engine._cv_predictions
    monkeypatch.setattr(engine, "_cv_predictions", lambda *a: overlapping.append(a[4] is not None) or original(*a))
    nested, chosen = engine.nested_group_predictions(X, Y, groups, outer)
    assert overlapping and all(overlapping)  # one leave-two-groups-out batch, no per-group runs
    assert_nested_choices_are_inner_refits(X, Y, groups, outer, nested, chosen, 3)


def test_chunks_of_one_target_share_one_rotation_and_equal_one_batch(monkeypatch):
    """Targets cut into chunks (8 MiB of Lanczos vectors; here one target each) reuse X's one rotation and give what one
    batch gives, to rounding; docs/pls.md quotes the chunk size the code uses."""
    from pathlib import Path

    from roughsense.model.pls import cv as engine

    docs = (Path(__file__).resolve().parents[3] / "docs" / "pls.md").read_text(encoding="utf-8")
    assert f"({engine._BATCH_BYTES >> 20} MiB of Lanczos vectors)" in docs
    X, y, groups = spectra(n_specimens=5, repetitions=3, p=10, seed=4)
    Y = np.column_stack([y, y[::-1], np.sqrt(y)])
    whole = engine.pls_cv_many(X, Y, max_components=4, groups=groups)
    rotations = []
    original = engine._rotation
    monkeypatch.setattr(engine, "_rotation", lambda X: rotations.append(1) or original(X))
    monkeypatch.setattr(engine, "_BATCH_BYTES", 1)
    chunked = engine.pls_cv_many(X, Y, max_components=4, groups=groups)
    assert len(rotations) == 1  # three chunks, one SVD
    np.testing.assert_allclose(chunked.predictions, whole.predictions, rtol=1e-10, atol=1e-12)


def test_result_layout_and_one_se_rule():
    X, y, groups = spectra(n_specimens=8, repetitions=4, p=30, seed=7)
    result = pls_cv(X, y, max_components=10, groups=groups)
    assert isinstance(result, PLSCVResult)
    assert result.rmse.shape == (11,) and result.predictions.shape == (32, 11) and result.rmse_se.shape == (11,)
    assert result.n_folds == 8 and result.scheme == "leave-one-group-out"
    for indices in result.test_indices:  # each fold holds out exactly one specimen, all its images
        assert len(set(groups[indices])) == 1 and len(indices) == 4
    assert sorted(np.concatenate(result.test_indices)) == list(range(32))
    # the one-SE rule from the per-fold MSEs, computed here independently
    err2 = (result.predictions - y[:, None]) ** 2
    fold_mse = np.array([err2[groups == g].mean(axis=0) for g in np.unique(groups)])
    se = fold_mse.std(axis=0, ddof=1) / np.sqrt(8) / (2 * result.rmse)
    assert np.allclose(result.rmse_se, se)
    best = int(np.argmin(result.rmse[1:])) + 1
    assert result.best_n_components == best
    threshold = result.rmse[best] + se[best]
    assert result.one_se_n_components == min(k for k in range(1, 11) if result.rmse[k] <= threshold)
    assert result.one_se_n_components <= best


def test_kfold_is_seeded_and_balanced():
    X, y, _ = spectra(n_specimens=5, repetitions=5, p=20, seed=8)
    a = pls_cv(X, y, max_components=3, cv=4, random_state=11)
    b = pls_cv(X, y, max_components=3, cv=4, random_state=11)
    c = pls_cv(X, y, max_components=3, cv=4, random_state=12)
    assert np.array_equal(a.folds, b.folds) and np.array_equal(a.predictions, b.predictions)
    assert not np.array_equal(a.folds, c.folds)
    assert sorted(np.bincount(a.folds)) == [6, 6, 6, 7]


def test_bad_cv_options():
    X, y, groups = spectra(n_specimens=4, repetitions=3, p=10)
    with pytest.raises(ConfigError):
        pls_cv(X, y, max_components=2, cv="bootstrap")
    with pytest.raises(ConfigError):
        pls_cv(X, y, max_components=2, cv=1)
    with pytest.raises(ConfigError, match="groups"):
        pls_cv(X, y, max_components=2, cv=3, groups=groups)
    with pytest.raises(InputError, match="groups"):
        pls_cv(X, y, max_components=2, groups=groups[:-1])
    with pytest.raises(ConfigError, match="smallest training fold"):
        pls_cv(X, y, max_components=9, groups=groups)  # 9 training samples support 8 components


@given(
    scale=st.floats(0.01, 100.0),
    shift=st.floats(-50.0, 50.0),
    x_shift=st.floats(-10.0, 10.0),
    seed=st.integers(0, 2**16),
)
def test_invariances(scale, shift, x_shift, seed):
    """y -> a y + b maps predictions the same way; shifting X's columns and rotating X change nothing;
    permuting the samples permutes the LOO predictions."""
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((15, 6))
    y = X @ rng.standard_normal(6) + rng.standard_normal(15)
    base = pls_cv(X, y, max_components=4)
    affine = pls_cv(X, scale * y + shift, max_components=4)
    assert np.allclose(affine.predictions, scale * base.predictions + shift, rtol=1e-8, atol=1e-8 * (abs(shift) + scale))
    shifted = pls_cv(X + x_shift * rng.standard_normal(6), y, max_components=4)
    assert np.allclose(shifted.predictions, base.predictions, rtol=1e-8, atol=1e-9)
    Q = np.linalg.qr(rng.standard_normal((6, 6)))[0]
    rotated = pls_cv(X @ Q, y, max_components=4)
    assert np.allclose(rotated.predictions, base.predictions, rtol=1e-8, atol=1e-9)
    perm = rng.permutation(15)
    permuted = pls_cv(X[perm], y[perm], max_components=4)
    assert np.allclose(permuted.predictions, base.predictions[perm], rtol=1e-8, atol=1e-9)


def test_loo_equals_sklearn_at_the_papers_size():
    """140 x 135 combined-force-like spectra, up to 20 components: scikit-learn refits, fold by fold."""
    X, y, _ = spectra(p=135, noise=1e-4, seed=5)
    result = pls_cv(X, y, max_components=20, cv="loo")
    for k in (1, 8, 20):
        expected = cross_val_predict(PLSRegression(n_components=k, scale=False), X, y, cv=LeaveOneOut()).ravel()
        assert rel_err(result.predictions[:, k], expected) < 1e-6


def test_y_scores_follow_plsregress():
    """plsregress: YS(:, a) = y0 * q_a, orthogonalised against the earlier X scores, so XS' YS is lower triangular."""
    X, y, _ = spectra(n_specimens=5, repetitions=4, p=12, seed=2)
    model = SIMPLS(n_components=5).fit(X, y)
    y0 = y - y.mean()
    T, U, Q = model.x_scores_, model.y_scores_, model.y_loadings_
    assert np.allclose(U[:, 0], y0 * Q[0])
    for a in range(1, 5):
        expected = y0 * Q[a] - T[:, :a] @ (T[:, :a].T @ (y0 * Q[a]))
        assert np.allclose(U[:, a], expected)
    assert np.allclose(np.triu(T.T @ U, k=1), 0, atol=1e-10)


def test_cap_stops_the_curve_where_the_data_run_out():
    X, y, _ = spectra(p=135, noise=1e-9, seed=5)
    with pytest.raises(ConfigError) as info:
        pls_cv(X, y, max_components=20)
    supported = info.value.supported
    capped = pls_cv(X, y, max_components=20, cap=True)
    assert capped.max_components == supported < 20
    np.testing.assert_array_equal(capped.rmse, pls_cv(X, y, max_components=supported).rmse)
