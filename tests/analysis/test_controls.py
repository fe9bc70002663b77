"""The controls, recomputed independently: scikit-learn refits for a few shufflings, closed-form null models."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from sklearn.cross_decomposition import PLSRegression

from roughsense import pls_cv, pls_cv_many
from roughsense.analysis import controls, dataset
from roughsense.analysis.metrics import ALPHA
from roughsense.analysis.study_analysis import analyse_study
from roughsense.model.pls.family import permuted_cv_rmse
from tests.analysis.test_study_analysis import _regression_data, synthetic_study

MAX_K = 3


@pytest.fixture(scope="module")
def small():
    study, features = synthetic_study(repetitions=3, seed=5, pads=("smooth",))
    analysis = analyse_study(study, features=features, max_components=MAX_K, conditions=("1N",), n_permutations=3,
                             seed=7)
    return analysis, study, features


def _sklearn_cv_predictions(X, y, folds, k):
    """Out-of-fold predictions with k components, refitting scikit-learn's PLS on every training fold."""
    out = np.empty(len(y))
    for fold in np.unique(folds):
        test = folds == fold
        model = PLSRegression(n_components=k, scale=False).fit(X[~test], y[~test])
        out[test] = model.predict(X[test]).ravel()
    return out


def _sklearn_loo_rmse(X, y):
    """LOO with the count chosen as the paper chooses it: the smallest CV RMSE over 1..MAX_K."""
    folds = np.arange(len(y))
    return min(np.sqrt(np.mean((_sklearn_cv_predictions(X, y, folds, k) - y) ** 2)) for k in range(1, MAX_K + 1))


def _sklearn_nested_loso_rmse(X, y, specimens):
    """Nested LOSO: each held-out specimen's count is the argmin of a LOSO over the others only."""
    prediction = np.empty(len(y))
    for name in pd.unique(specimens):
        held = specimens == name
        Xr, yr, sr = X[~held], y[~held], specimens[~held]
        usable = min(MAX_K, len(yr) - 3 - 1)
        inner = [np.sum((_sklearn_cv_predictions(Xr, yr, sr, k) - yr) ** 2) for k in range(1, usable + 1)]
        k = 1 + int(np.argmin(inner))
        prediction[held] = PLSRegression(n_components=k, scale=False).fit(Xr, yr).predict(X[held]).ravel()
    return float(np.sqrt(np.mean((prediction - y) ** 2)))


def test_shuffled_targets_keep_one_value_per_specimen():
    specimens = np.repeat(["a", "b", "c", "d"], 3)
    y = np.repeat([1.0, 2.0, 3.0, 4.0], 3)
    perms = controls.specimen_permutations(4, 50, seed=1)
    Y = controls.permuted_targets(y, specimens, perms)
    assert Y.shape == (12, 50)
    for b in range(50):
        per_specimen = pd.Series(Y[:, b]).groupby(specimens).nunique()
        assert (per_specimen == 1).all()  # every repetition of a specimen shares its (wrong) value
        assert sorted(Y[::3, b]) == [1.0, 2.0, 3.0, 4.0]  # the same values, reassigned across specimens
    # Seeded: the same seed gives the same shufflings, another seed others.
    np.testing.assert_array_equal(perms, controls.specimen_permutations(4, 50, seed=1))
    assert not np.array_equal(perms, controls.specimen_permutations(4, 50, seed=2))


def test_batched_cv_equals_one_cv_per_target():
    study, features = synthetic_study(repetitions=3, seed=2, pads=("smooth",))
    rows, X, y = _regression_data(study, features, "smooth", "2N")
    rng = np.random.default_rng(0)
    Y = np.column_stack([y, rng.permutation(y), rng.normal(size=y.size)])
    for kwargs in ({"cv": "loo"}, {"groups": rows["specimen"].to_numpy()}):
        batch = pls_cv_many(X, Y, max_components=5, **kwargs)
        for b in range(Y.shape[1]):
            single = pls_cv(X, Y[:, b], max_components=5, **kwargs)
            np.testing.assert_allclose(batch.predictions[b], single.predictions, rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(batch.rmse[b], single.rmse, rtol=1e-9)


@pytest.mark.parametrize("cv", ["loo", pytest.param("loso", marks=pytest.mark.slow)])
def test_permutation_control_matches_sklearn_refits(small, cv):
    analysis, study, features = small
    rows, X, y = _regression_data(study, features, "smooth", "1N")
    specimens = rows["specimen"].to_numpy()
    perms = controls.specimen_permutations(len(pd.unique(specimens)), 3, seed=7)
    Y = controls.permuted_targets(y, specimens, perms)
    ours = permuted_cv_rmse(X, Y, specimens, cv, MAX_K)
    if cv == "loo":
        expected = [_sklearn_loo_rmse(X, Y[:, b]) for b in range(3)]
        real = _sklearn_loo_rmse(X, y)
    else:
        expected = [_sklearn_nested_loso_rmse(X, Y[:, b], specimens) for b in range(3)]
        real = _sklearn_nested_loso_rmse(X, y, specimens)
    np.testing.assert_allclose(ours, expected, rtol=1e-6)
    row = analysis.controls.set_index(["model", "pad", "condition", "cv"]).loc[("pls", "smooth", "1N", cv)]
    assert row["rmse"] == pytest.approx(real, rel=1e-6)
    assert row["n_permutations"] == 3
    assert row["permutation_p"] == pytest.approx((1 + sum(e <= real for e in expected)) / 4)


def test_null_model_is_the_training_mean_under_the_same_cv(small):
    analysis, study, features = small
    rows, _, y = _regression_data(study, features, "smooth", "1N")
    specimens = rows["specimen"].to_numpy()
    loo = (y.sum() - y) / (len(y) - 1)  # the mean of the other trials
    loso = np.array([y[specimens != s].mean() for s in specimens])
    table = analysis.controls.set_index(["model", "pad", "condition", "cv"])
    for model in ("pls", "peak-law"):  # one null per fold design, whichever model it is the floor of
        assert table.loc[(model, "smooth", "1N", "loo"), "null_rmse"] == pytest.approx(np.sqrt(np.mean((loo - y) ** 2)))
        assert table.loc[(model, "smooth", "1N", "loso"), "null_rmse"] == pytest.approx(
            np.sqrt(np.mean((loso - y) ** 2)))
    for _, row in analysis.controls.iterrows():
        assert row["beats_null"] == (row["rmse"] < row["null_rmse"])
        assert row["passes"] == (row["beats_null"] and row["permutation_p"] < ALPHA)


def test_a_model_that_only_recognises_specimens_fails_the_permutation_control():
    """Spectra that identify each specimen but carry no roughness information: LOO scores well, shuffling too."""
    study, features = synthetic_study(repetitions=4, seed=9, pads=("smooth",))
    rng = np.random.default_rng(3)
    codes = {s: rng.normal(size=45) for s in features["specimen"].unique()}  # a random fingerprint per specimen
    freq = dataset.frequency_columns(features)
    features = features.copy()
    features[freq] = np.vstack([codes[s] + rng.normal(0, 0.05, 45) for s in features["specimen"]])
    analysis = analyse_study(study, features=features, max_components=6, conditions=("1N",), n_permutations=39,
                             models=("pls",))
    row = analysis.controls.set_index("cv").loc["loo"]
    assert row["permutation_p"] > 0.2 and not row["passes"]
    loso = analysis.controls.set_index("cv").loc["loso"]
    assert not loso["passes"]


def test_controls_are_identical_on_one_or_two_threads(small):
    analysis, study, features = small
    again = analyse_study(study, features=features, max_components=MAX_K, conditions=("1N",), n_permutations=3,
                          seed=7, n_jobs=2)
    pd.testing.assert_frame_equal(again.controls, analysis.controls, check_exact=True)


def _law_refit_rmse(X, y, folds, law):
    """Pooled CV RMSE of PeakPowerLaw refitted on every training fold (scikit-learn's estimator, one fit per fold)."""
    from roughsense.model.peak_law.law import PeakPowerLaw

    settings = {k: v for k, v in law.items() if k != "surfaces"}
    surfaces = law.get("surfaces")
    out = np.empty(len(y))
    for fold in np.unique(folds):
        test = folds == fold
        # the surfaces' peaks are read over all rows, as the batched CV reads them (a LOO fold's held-out press
        # shares its specimen's peak with the other presses: spectra only, never ratings)
        features = PeakPowerLaw(**settings).fit(X, y, surfaces=surfaces).features(X, surfaces=surfaces)
        out[test] = _refit_on_features(features, y, ~test, test, settings.get("epsilon"), surfaces)
    return float(np.sqrt(np.mean((out - y) ** 2)))


def _refit_on_features(features, y, train, test, epsilon=None, surfaces=None):
    from tests.analysis.test_study_analysis import FREQS

    """The law refitted on precomputed features (statsmodels-free: the estimator's own IRLS on one fold)."""
    from roughsense.model.huber_batch import HUBER_EPSILON
    from roughsense.model.peak_law.domain import predict_law
    from roughsense.model.peak_search import fit_terms, shape_read
    from roughsense.model.readout_domain import domain_margins, kept_range, kept_rows

    eps = HUBER_EPSILON if epsilon is None else epsilon
    every = np.ones((1, int(train.sum())), bool)
    beta, scale = fit_terms(features[train], np.log(y[train])[None], every, epsilon=eps, grouped=surfaces is not None)
    kept = kept_rows(features[train], np.log(y[train]), beta[0, 0], float(scale[0, 0]), eps,
                     None if surfaces is None else np.asarray(surfaces)[train])
    low, high = (r[0, 0] for r in kept_range(features[train], kept[None, None],
                                             shape_read(features[train], every, surfaces is not None)))
    step = float(np.diff(FREQS)[0])  # the law is applied within its domain: the kept range and its margins
    return predict_law(features[test], beta[0, 0, 0], beta[0, 0, 1:], *domain_margins(step, low, high))


@pytest.mark.parametrize("cv", ["loo", "loso"])
def test_peak_law_permutation_control_matches_refits(small, cv):
    """The same shufflings as PLS's, each refitted fold by fold; p and the null as for PLS."""
    from tests.analysis.test_study_analysis import FREQS

    analysis, study, features = small
    rows, X, y = _regression_data(study, features, "smooth", "1N")
    specimens = rows["specimen"].to_numpy()
    folds = np.arange(len(y)) if cv == "loo" else specimens
    law = {"freq_per_mm": FREQS, "n_blocks": 1, "pad_ridge_period_mm": None, "surfaces": specimens}
    # The shufflings index specimens in the analysis's order (first appearance in its trials): the same ones as PLS's.
    order = pd.unique(analysis.condition_fit("smooth", "1N", cv, "peak-law").predictions["specimen"])
    value = pd.Series(y, index=specimens).groupby(level=0).first()
    perms = controls.specimen_permutations(len(order), 3, seed=7)
    shuffled = []
    for b in range(3):
        wrong = dict(zip(order, value.loc[order[perms[b]]].to_numpy()))  # specimen order[j] gets order[perms[b, j]]'s
        shuffled.append(_law_refit_rmse(X, np.array([wrong[s] for s in specimens]), folds, law))
    real = _law_refit_rmse(X, y, folds, law)
    table = analysis.controls.set_index(["model", "pad", "condition", "cv"])
    row = table.loc[("peak-law", "smooth", "1N", cv)]
    assert row["rmse"] == pytest.approx(real, rel=1e-9)
    assert row["permutation_p"] == pytest.approx((1 + sum(e <= real for e in shuffled)) / 4)
    assert row["permuted_rmse_median"] == pytest.approx(np.median(shuffled), rel=1e-9)
    assert row["permuted_rmse_min"] == pytest.approx(min(shuffled), rel=1e-9)
    assert row["null_rmse"] == table.loc[("pls", "smooth", "1N", cv), "null_rmse"]
    assert row["passes"] == (row["rmse"] < row["null_rmse"] and row["permutation_p"] < ALPHA)
    assert list(analysis.controls.columns[-2:]) == ["seed", "model"]  # model appended last


@pytest.mark.parametrize("cv", ["loo", "loso"])
def test_peak_law_control_in_chunks_of_shufflings_equals_one_batch(small, cv, monkeypatch):
    """Memory bounded by chunks of shufflings (one at a time here) changes no shuffling's RMSE beyond rounding."""
    from roughsense.model.peak_law import family as peak_law_family
    from roughsense.model.peak_law.cv import peak_law_cv
    from tests.analysis.test_study_analysis import FREQS

    analysis, study, features = small
    rows, X, y = _regression_data(study, features, "smooth", "1N")
    specimens = rows["specimen"].to_numpy()
    law = {"freq_per_mm": FREQS, "n_blocks": 1, "pad_ridge_period_mm": None, "surfaces": specimens}
    Y = controls.permuted_targets(y, specimens, controls.specimen_permutations(len(pd.unique(specimens)), 5, seed=3))
    whole = peak_law_family.permuted_law_rmse(X, Y, specimens, cv, law)
    batches = []
    monkeypatch.setattr(peak_law_family, "LAW_CHUNK_CELLS", 1)
    monkeypatch.setattr(peak_law_family, "peak_law_cv", lambda X, Y, **kw: batches.append(Y.shape[1]) or
                        peak_law_cv(X, Y, **kw))
    one_by_one = peak_law_family.permuted_law_rmse(X, Y, specimens, cv, law)
    assert batches == [1] * Y.shape[1]  # one shuffling per chunk: the chunking ran
    for b in range(Y.shape[1]):  # and each equals the law cross-validated on that shuffling alone
        alone = peak_law_family.permuted_law_rmse(X, Y[:, b:b + 1], specimens, cv, law)
        assert one_by_one[b] == pytest.approx(alone[0], rel=1e-12)
    np.testing.assert_allclose(one_by_one, whole, rtol=1e-12)
