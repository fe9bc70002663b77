"""model/peak_law/training.py: the law's one cross-validation, taking fold ids, is what the study's engine runs and
what ``fit`` reports, and it equals refitting :class:`PeakPowerLaw` on every training fold of a split."""
from __future__ import annotations

import numpy as np
import pytest

from roughsense.model.family import FoldSettings, TrainingSet
from roughsense.model.peak_law.family import PeakLawFamily
from roughsense.model.peak_law.law import PeakPowerLaw
from roughsense.model.peak_law.training import LAW_CV_MODELS, cross_validate_law, law_out_of_fold, train_law
from tests.model.test_jackknife_file import gratings


def _data(f, X, y, specimens, folds) -> TrainingSet:
    baseline = np.array([y[folds != folds[i]].mean() for i in range(y.size)])  # the training mean, by a plain loop
    return TrainingSet(X, y, specimens, 3, 0, folds, "3-fold", baseline, FoldSettings(f, 1, None, specimens), {},
                       "pad 'x' at 2N")


def test_the_studys_engine_and_fit_run_the_same_law_cv():
    f, X, y, specimens = gratings(n_specimens=8, presses=3)
    settings = FoldSettings(f, 1, None, specimens)
    for cv, folds in (("loso", specimens), ("loo", np.arange(y.size))):
        engine = PeakLawFamily().cross_validate(X, y, specimens, cv, settings, 1)
        np.testing.assert_array_equal(engine.out_of_fold, law_out_of_fold(X, y, folds, settings))


def test_the_law_under_k_folds_equals_refitting_it_on_every_training_fold():
    """Folds that keep each surface's presses together (a fold that splits one lets a held-out press share where its
    surface's peak is, which no refit can: peak_law_cv's docstring)."""
    f, X, y, specimens = gratings(n_specimens=8, presses=3)
    folds = np.repeat(np.arange(8) % 3, 3)
    result = cross_validate_law(_data(f, X, y, specimens, folds))
    refit = np.empty(y.size)
    for fold in range(3):
        held = folds == fold
        law = PeakPowerLaw(freq_per_mm=f).fit(X[~held], y[~held], surfaces=specimens[~held])
        refit[held] = law.predict(X[held], surfaces=specimens[held])
    np.testing.assert_allclose(result.predictions[:, 1], refit, rtol=1e-8)
    np.testing.assert_allclose(result.rmse, np.sqrt(np.mean((result.predictions - y[:, None]) ** 2, axis=0)))
    assert result.scheme == "3-fold" and len(LAW_CV_MODELS) == result.rmse.size == 2


def test_train_law_records_its_cv_beside_the_training_mean_and_fits_every_trial():
    f, X, y, specimens = gratings(n_specimens=8, presses=3)
    trained = train_law(_data(f, X, y, specimens, np.arange(y.size) % 3))
    assert list(trained.record) == ["model", "cv_models", "cv_rmse", "cv_rmse_se"]  # the model file's order
    assert trained.record["cv_models"] == list(LAW_CV_MODELS) and trained.n_components == 1
    direct = PeakPowerLaw(freq_per_mm=f).fit(X, y, surfaces=specimens)
    assert trained.model.coef_ == pytest.approx(direct.coef_) and trained.model.intercept_ == direct.intercept_
