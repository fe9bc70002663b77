"""The peak power law (model/peak_law/law.py), checked against independent truth.

Huber's fit against statsmodels' RLM and against least squares; the estimator against scikit-learn's own checks;
the peak features against images of known period passed through the real sensor (SpatialSpectrum); the batched
cross-validation against a refit of the estimator on every training fold.
"""
from __future__ import annotations

import numpy as np
import pytest
import statsmodels.api as sm
from hypothesis import given
from hypothesis import strategies as st
from sklearn.model_selection import LeaveOneGroupOut, cross_val_predict
from sklearn.pipeline import Pipeline
from sklearn.utils.estimator_checks import parametrize_with_checks

from roughsense.model.huber_batch import huber_irls
from roughsense.model.peak_law.cv import peak_law_cv
from roughsense.model.peak_law.law import PeakPowerLaw
from roughsense.model.peak_search import peak_features
from roughsense.sensor.spectrum import SpatialSpectrum

PX_PER_MM = 34.9
LINE_PX = 1900
#: A one-row image holds the line; the sensor reads it through a crop of exactly that row.
LINE_ROI = (0, 0, LINE_PX, 1)
GRID = np.linspace(0.1, 1.0, 45)


def line_image(period_mm: float, phase: float = 0.0, *, square: bool = False, ridge_period_mm: float | None = None,
               ridge_gain: float = 0.0) -> np.ndarray:
    """A (1, 1900) gray image: a sinusoid or square wave of ``period_mm`` at 34.9 px/mm, plus a pad's ridges."""
    x_mm = np.arange(LINE_PX) / PX_PER_MM
    wave = np.sin(2 * np.pi * (x_mm / period_mm + phase))
    line = np.sign(wave) if square else wave
    if ridge_period_mm is not None:
        line = line + ridge_gain * np.sin(2 * np.pi * x_mm / ridge_period_mm + 1.0)
    return (0.5 + 0.1 * line)[None, :]


def sensor() -> SpatialSpectrum:
    return SpatialSpectrum(px_per_mm=PX_PER_MM, roi=LINE_ROI).fit()


def rlm_params(features: np.ndarray, y: np.ndarray) -> np.ndarray:
    """statsmodels' Huber M-estimator (t = 1.345, MAD scale), converged on the coefficients."""
    model = sm.RLM(y, sm.add_constant(features, has_constant="add"), M=sm.robust.norms.HuberT(t=1.345))
    return model.fit(conv="coefs", tol=1e-12, maxiter=200).params


def contaminated(seed: int, n: int = 40):
    """Two features, heavy-tailed noise and a few gross outliers (what Huber is for)."""
    rng = np.random.default_rng(seed)
    features = rng.normal(size=(n, 2))
    y = 0.3 + features @ np.array([0.8, -0.5]) + 0.1 * rng.standard_t(3, size=n)
    bad = rng.choice(n, size=n // 8, replace=False)
    y[bad] += rng.normal(0.0, 2.0, size=bad.size)
    return features, y


def specimen_spectra(n_specimens: int = 8, repetitions: int = 4, n_blocks: int = 1, seed: int = 0):
    """Spectra of gratings of periods 2-5 mm (several trials each, noisy) and a rating that grows with the period."""
    rng = np.random.default_rng(seed)
    spectrum = sensor()
    periods = np.linspace(2.0, 5.0, n_specimens)
    rows, groups = [], []
    for s, period in enumerate(periods):
        for _ in range(repetitions):
            blocks = [spectrum.transform([line_image(period * (1 + 0.02 * rng.standard_normal()), rng.random(),
                                                     square=bool(s % 2))])[0] for _ in range(n_blocks)]
            rows.append(np.abs(np.concatenate(blocks) + 0.02 * rng.standard_normal(n_blocks * GRID.size)))
            groups.append(f"S{s}")
    y = np.repeat(0.4 * periods ** 0.9, repetitions) * np.exp(0.05 * rng.standard_normal(len(rows)))
    return np.array(rows), y, np.array(groups)


# --------------------------------------------------------------------------- Huber's fit


@pytest.mark.parametrize("seed", range(4))
def test_huber_irls_equals_statsmodels_rlm(seed):
    features, y = contaminated(seed)
    beta, scale = huber_irls(features, y[None, :], np.ones((1, y.size), dtype=bool))
    np.testing.assert_allclose(beta[0, 0], rlm_params(features, y), rtol=0, atol=2e-7)
    assert scale[0, 0] > 0


def test_huber_irls_batch_equals_statsmodels_on_each_training_mask():
    """Several folds and targets in one batch: each (fold, target) is its own RLM fit on its training rows."""
    features, y = contaminated(7, n=30)
    rng = np.random.default_rng(1)
    targets = np.vstack([y, y[::-1] + 0.2, np.exp(0.1 * y)])
    train = rng.random((5, y.size)) > 0.25
    beta, _ = huber_irls(features, targets, train)
    for fold in range(train.shape[0]):
        for b in range(targets.shape[0]):
            rows = train[fold]
            np.testing.assert_allclose(beta[fold, b], rlm_params(features[rows], targets[b, rows]), atol=2e-7)


def test_huber_irls_in_chunks_of_one_cell_equals_statsmodels_on_each_problem(monkeypatch):
    """Chunks smaller than one problem (each problem alone) and than the batch: every fit is still its own RLM."""
    from roughsense.model import huber_batch

    features, y = contaminated(11, n=25)
    targets = np.vstack([y, y[::-1] + 0.3])
    train = np.random.default_rng(2).random((3, y.size)) > 0.3
    whole, _ = huber_irls(features, targets, train)
    for cells in (1, 2 * y.size):
        monkeypatch.setattr(huber_batch, "CHUNK_CELLS", cells)
        chunked, _ = huber_irls(features, targets, train)
        np.testing.assert_allclose(chunked, whole, rtol=0, atol=1e-12)
        for fold in range(train.shape[0]):
            for b in range(targets.shape[0]):
                rows = train[fold]
                np.testing.assert_allclose(chunked[fold, b], rlm_params(features[rows], targets[b, rows]), atol=2e-7)


def test_huber_irls_solves_interchangeable_masks_once_and_each_equals_statsmodels(monkeypatch):
    """Presses of one specimen share its features and (shuffled) target: leave-one-out's masks of one specimen pose
    one problem, solved once, and every fold's fit is still statsmodels' RLM on that fold's own training rows."""
    from roughsense.model import huber_batch

    base, y = contaminated(5, n=12)
    features, targets = np.repeat(base, 4, axis=0), np.vstack([np.repeat(y, 4), np.repeat(y[::-1], 4)])
    train = ~np.eye(48, dtype=bool)  # leave-one-out over 48 presses of 12 specimens
    solved = []
    original = huber_batch._irls_chunk
    monkeypatch.setattr(huber_batch, "_irls_chunk", lambda d, t, m, e: solved.append(m.shape[0]) or original(d, t, m, e))
    beta, scale = huber_irls(features, targets, train)
    assert sum(solved) == 12 * 2  # 12 specimens x 2 targets, not 48 x 2
    assert beta.shape == (48, 2, 3) and scale.shape == (48, 2)
    for fold in range(48):
        for b in range(2):
            rows = train[fold]
            np.testing.assert_allclose(beta[fold, b], rlm_params(features[rows], targets[b, rows]), atol=2e-7)
    # A press whose target differs from its specimen's in one column is not interchangeable with the others.
    targets[1, 0] += 1.0
    solved.clear()
    beta, _ = huber_irls(features, targets, train)
    assert sum(solved) == (11 + 2) * 2  # its specimen's two masks: without press 0, without one of the 3 others
    np.testing.assert_allclose(beta[0, 1], rlm_params(features[1:], targets[1, 1:]), atol=2e-7)


def test_huge_epsilon_without_outliers_is_least_squares():
    rng = np.random.default_rng(3)
    features = rng.normal(size=(25, 2))
    y = 1.0 + features @ np.array([0.5, 2.0]) + 0.05 * rng.normal(size=25)
    beta, _ = huber_irls(features, y[None, :], np.ones((1, 25), dtype=bool), epsilon=1e9)
    ols, *_ = np.linalg.lstsq(np.column_stack([np.ones(25), features]), y, rcond=None)
    np.testing.assert_allclose(beta[0, 0], ols, rtol=0, atol=1e-10)


def test_fit_equals_statsmodels_on_its_features():
    """PeakPowerLaw.fit is Huber's regression of log rating on its terms (the peak frequency and, read on every
    training surface, the second-harmonic ratio; the amplitude is no term), outliers and all."""
    X, y, groups = specimen_spectra(seed=2)
    y = y.copy()
    y[[3, 17]] *= np.array([4.0, 0.2])  # two misjudged trials
    model = PeakPowerLaw(freq_per_mm=GRID).fit(X, y, surfaces=groups)
    features = model.features(X, surfaces=groups)
    assert np.all(np.isfinite(features[:, 2]))  # 2-5 mm on a smooth pad: every second harmonic is in the band
    params = rlm_params(features[:, [0, 2]], np.log(y))
    # both stop iterating at ~1e-8 relative change, on different measures: they agree to ~5e-8
    np.testing.assert_allclose(np.r_[model.intercept_, model.coef_], np.r_[params[:2], 0.0, params[2]], rtol=0,
                               atol=2e-7)


# --------------------------------------------------------------------------- scikit-learn


@parametrize_with_checks([PeakPowerLaw()])
def test_scikit_learn_contract(estimator, check):
    check(estimator)


def test_pipeline_from_images_and_cross_val_predict_equal_peak_law_cv():
    """Images -> SpatialSpectrum -> PeakPowerLaw in a Pipeline; its grouped CV equals the batched one."""
    rng = np.random.default_rng(5)
    periods = np.repeat(np.linspace(2.0, 5.0, 6), 3)
    images = [line_image(p, rng.random(), square=True) for p in periods]
    y = 0.5 * periods ** 0.8 * np.exp(0.03 * rng.standard_normal(periods.size))
    groups = np.repeat(np.arange(6), 3)
    pipeline = Pipeline([("spectrum", SpatialSpectrum(px_per_mm=PX_PER_MM, roi=LINE_ROI)),
                         ("law", PeakPowerLaw(freq_per_mm=GRID))])
    predicted = cross_val_predict(pipeline, images, y, groups=groups, cv=LeaveOneGroupOut())
    X = sensor().transform(images)
    np.testing.assert_allclose(predicted, peak_law_cv(X, y, groups=groups, freq_per_mm=GRID)[0], rtol=1e-9)
    fitted = pipeline.fit(images, y)
    assert fitted.named_steps["law"].coef_[0] < 0  # rating grows with the period, so falls with the frequency


# --------------------------------------------------------------------------- features


@given(period_mm=st.floats(2.0, 5.0), phase=st.floats(0.0, 1.0), square=st.booleans())
def test_peak_frequency_of_a_grating_image_within_one_percent(period_mm, phase, square):
    spectrum = sensor().transform([line_image(period_mm, phase, square=square)])
    frequency = np.exp(peak_features(spectrum, GRID)[0, 0])
    assert abs(frequency * period_mm - 1.0) < 0.01


@given(period_mm=st.floats(2.0, 5.0), phase=st.floats(0.0, 1.0), ridge_period_mm=st.floats(1.05, 1.6),
       ridge_gain=st.floats(1.5, 4.0))
def test_the_pads_ridge_frequency_is_never_chosen_over_a_grating(period_mm, phase, ridge_period_mm, ridge_gain):
    """A fingerprint pad's ridges, stronger than the grating, win without the exclusion and never with it."""
    image = line_image(period_mm, phase, ridge_period_mm=ridge_period_mm, ridge_gain=ridge_gain)
    spectrum = sensor().transform([image])
    ridge_frequency = 1.0 / ridge_period_mm
    plain = np.exp(peak_features(spectrum, GRID)[0, 0])
    assert abs(plain - ridge_frequency) < 0.05  # the test has teeth: the ridges are the highest peak
    chosen = np.exp(peak_features(spectrum, GRID, pad_ridge_period_mm=ridge_period_mm)[0, 0])
    assert abs(chosen - ridge_frequency) > 0.1
    assert abs(chosen * period_mm - 1.0) < 0.01


@given(seed=st.integers(0, 2**32 - 1), log_c=st.floats(-7.0, 7.0))
def test_scaling_a_spectrum_shifts_only_its_log_amplitude(seed, log_c):
    spectra = np.random.default_rng(seed).lognormal(size=(3, GRID.size))
    before = peak_features(spectra, GRID)
    after = peak_features(np.exp(log_c) * spectra, GRID)
    np.testing.assert_allclose(after[:, 0], before[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(after[:, 1], before[:, 1] + log_c, rtol=0, atol=1e-9)


@given(seed=st.integers(0, 2**32 - 1), ridge=st.sampled_from([None, 1.0, 1.3]))
def test_identical_blocks_read_as_one(seed, ridge):
    spectra = np.random.default_rng(seed).lognormal(size=(4, GRID.size))
    one = peak_features(spectra, GRID, pad_ridge_period_mm=ridge)
    three = peak_features(np.tile(spectra, 3), GRID, n_blocks=3, pad_ridge_period_mm=ridge)
    np.testing.assert_allclose(three, one, rtol=0, atol=1e-12)


def test_extrapolation_is_flagged_and_held_at_the_edge():
    """A period shorter than any trained one: flagged, and predicted as the edge of the law's domain (the kept
    training range widened by its margins) would be: held exactly where it is flagged."""
    from roughsense.model.readout_domain import domain_margins

    X, y, _ = specimen_spectra(seed=4)
    model = PeakPowerLaw(freq_per_mm=GRID).fit(X, y)
    outside = sensor().transform([line_image(1.3, 0.2)])
    assert model.extrapolates(outside)[0] and not model.extrapolates(X).any()
    low, high = domain_margins(GRID[1] - GRID[0], model.feature_min_, model.feature_max_)
    features = model.features(outside)
    assert np.isnan(features[0, 2]) and model.coef_[2] == 0  # fitted on single presses: no shape term
    features[:, 2] = 0.0  # no term: any value
    held = np.clip(features, low, high)
    expected = np.exp(model.intercept_ + held @ model.coef_)
    np.testing.assert_allclose(model.predict(outside), expected, rtol=1e-12)


# --------------------------------------------------------------------------- batched cross-validation


def refit_each_fold(X, Y, folds, **settings):
    """Out-of-fold predictions (B, n) by fitting PeakPowerLaw from scratch on every training fold."""
    out = np.empty((Y.shape[1], len(X)))
    for fold in np.unique(folds):
        test = folds == fold
        for b in range(Y.shape[1]):
            model = PeakPowerLaw(**settings).fit(X[~test], Y[~test, b])
            out[b, test] = model.predict(X[test])
    return out


@pytest.mark.parametrize("n_blocks, ridge", [(1, None), (3, 1.0)])
@pytest.mark.parametrize("grouped", [False, True])
def test_peak_law_cv_equals_a_refit_on_every_fold(n_blocks, ridge, grouped):
    X, y, groups = specimen_spectra(n_specimens=7, repetitions=3, n_blocks=n_blocks, seed=n_blocks)
    rng = np.random.default_rng(9)
    Y = np.column_stack([y, y[rng.permutation(y.size)], np.exp(rng.normal(size=y.size))])
    settings = {"freq_per_mm": GRID, "n_blocks": n_blocks, "pad_ridge_period_mm": ridge}
    folds = groups if grouped else np.arange(len(y))
    batched = peak_law_cv(X, Y, groups=groups if grouped else None, **settings)
    np.testing.assert_allclose(batched, refit_each_fold(X, Y, folds, **settings), rtol=1e-9, atol=0)


def test_peak_law_cv_of_one_target_is_its_column():
    X, y, groups = specimen_spectra(n_specimens=5, repetitions=2)
    np.testing.assert_array_equal(peak_law_cv(X, y, groups=groups, freq_per_mm=GRID),
                                  peak_law_cv(X, y[:, None], groups=groups, freq_per_mm=GRID))


# --------------------------------------------------------------------------- refusals


def test_non_positive_or_non_finite_targets_are_refused():
    X, y, groups = specimen_spectra(n_specimens=4, repetitions=2)
    for bad in (0.0, -1.0, np.nan):
        Y = y.copy()
        Y[1] = bad
        with pytest.raises(ValueError, match="must be positive"):
            peak_law_cv(X, np.column_stack([y, Y]), groups=groups, freq_per_mm=GRID)
        if np.isfinite(bad):
            with pytest.raises(ValueError, match="must be positive"):
                PeakPowerLaw(freq_per_mm=GRID).fit(X, Y)


def test_negative_or_non_finite_spectra_are_refused():
    X, y, _ = specimen_spectra(n_specimens=4, repetitions=2)
    negative = X.copy()
    negative[0, 5] = -1e-3
    with pytest.raises(ValueError, match="Negative values"):
        PeakPowerLaw(freq_per_mm=GRID).fit(negative, y)
    with pytest.raises(ValueError, match="Negative values"):
        peak_features(negative, GRID)
    with pytest.raises(ValueError, match="Negative values"):
        peak_law_cv(negative, y, freq_per_mm=GRID)
    model = PeakPowerLaw(freq_per_mm=GRID).fit(X, y)
    with pytest.raises(ValueError, match="Negative values"):
        model.predict(negative)
    broken = X.copy()
    broken[1, 2] = np.nan
    with pytest.raises(ValueError, match="NaN or infinite"):
        peak_features(broken, GRID)


def test_spectra_that_do_not_split_into_the_blocks_are_refused():
    X, y, _ = specimen_spectra(n_specimens=4, repetitions=2)
    with pytest.raises(ValueError, match="cannot be split into 2 equal spectra"):
        PeakPowerLaw(freq_per_mm=GRID, n_blocks=2).fit(X, y)
    with pytest.raises(ValueError, match="not 3 block"):
        peak_features(X, GRID, n_blocks=3)
    with pytest.raises(ValueError, match="do not match the 45-frequency grid"):
        PeakPowerLaw(freq_per_mm=GRID, n_blocks=1).fit(np.hstack([X, X[:, :5]]), y)


@pytest.mark.parametrize("grid", [GRID[::-1], np.r_[GRID[:10], GRID[12:]], GRID - 0.2, np.r_[GRID[:-1], np.nan],
                                  GRID[:2], GRID.reshape(5, 9)])
def test_a_bad_frequency_grid_is_refused(grid):
    X, y, _ = specimen_spectra(n_specimens=4, repetitions=2)
    width = int(np.size(grid))
    with pytest.raises(ValueError, match="freq_per_mm must be"):
        PeakPowerLaw(freq_per_mm=grid).fit(X[:, :width], y)
    with pytest.raises(ValueError, match="freq_per_mm must be"):
        peak_law_cv(X[:, :width], y, freq_per_mm=grid)


@pytest.mark.parametrize("name, value", [("n_blocks", True), ("n_blocks", 0), ("n_blocks", 1.0), ("epsilon", True),
                                         ("epsilon", 0.0), ("exclusion_per_mm", True), ("exclusion_per_mm", np.inf),
                                         ("pad_ridge_period_mm", True), ("pad_ridge_period_mm", -1.0)])
def test_bool_and_out_of_range_settings_are_refused(name, value):
    X, y, _ = specimen_spectra(n_specimens=4, repetitions=2)
    with pytest.raises(ValueError, match=name):
        PeakPowerLaw(freq_per_mm=GRID, **{name: value}).fit(X, y)
    with pytest.raises(ValueError, match=name):
        peak_law_cv(X, y, freq_per_mm=GRID, **{name: value})


def test_a_ridge_exclusion_that_leaves_nothing_is_refused():
    X, y, _ = specimen_spectra(n_specimens=4, repetitions=2)
    with pytest.raises(ValueError, match="no frequency of the band"):
        peak_features(X, GRID, pad_ridge_period_mm=2.0, exclusion_per_mm=5.0)


def test_targets_or_groups_that_do_not_match_the_spectra_are_refused():
    X, y, groups = specimen_spectra(n_specimens=4, repetitions=2)
    with pytest.raises(ValueError, match="one row per row of X"):
        peak_law_cv(X, y[:-1], freq_per_mm=GRID)
    with pytest.raises(ValueError, match="groups has 7 entries for 8 rows"):
        peak_law_cv(X, y, groups=groups[:-1], freq_per_mm=GRID)
