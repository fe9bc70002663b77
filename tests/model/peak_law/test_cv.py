"""The peak law's cross-validation: the law's leave-one-out fits a surface's interchangeable folds once, to the same bits as
fitting every fold."""
from __future__ import annotations

import numpy as np
import pytest

from roughsense.model.peak_law import cv as law_cv
from tests.model.peak_law.test_law import GRID, specimen_spectra
from tests.targets import shuffled_targets


@pytest.mark.parametrize("n_blocks, ridge", [(1, None), (3, 1.0)])
def test_law_loo_fits_each_surfaces_folds_once_and_equals_every_fold_fitted(monkeypatch, n_blocks, ridge):
    X, y, groups = specimen_spectra(n_specimens=6, repetitions=3, n_blocks=n_blocks, seed=4)
    Y = shuffled_targets(np.repeat(y[::3], 3), groups, 6, seed=3)  # one value per surface, as the control's shufflings
    settings = {"freq_per_mm": GRID, "n_blocks": n_blocks, "pad_ridge_period_mm": ridge, "surfaces": groups}
    masks = []
    original = law_cv.fit_terms
    monkeypatch.setattr(law_cv, "fit_terms", lambda f, t, train, **k: masks.append(len(train)) or original(f, t, train, **k))
    once = law_cv.peak_law_cv(X, Y, **settings)
    assert masks == [6]  # one fit per surface's presses, not one per press
    monkeypatch.setattr(law_cv, "row_classes", lambda rows: np.arange(len(rows)))  # no two rows interchangeable
    every = law_cv.peak_law_cv(X, Y, **settings)
    assert masks[-1] == len(y)
    np.testing.assert_array_equal(once, every)
