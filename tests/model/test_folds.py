"""The shared folds and training-mean baseline (model/folds.py): equal, bit for bit, to PLS's 0-component CV."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense.errors import ConfigError, InputError
from roughsense.model.folds import FoldConfigError, error_curve, fold_ids, training_mean_predictions
from roughsense.model.pls.cv import pls_cv


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n_groups=st.integers(3, 9), per_group=st.integers(1, 5),
       scheme=st.sampled_from(["loo", "loso", 3]))
def test_the_baseline_is_pls_zero_component_column_bit_for_bit(seed, n_groups, per_group, scheme):
    """The peak law reports PLS's rmse[0] as its null; computed here without PLS, it must be the same bits."""
    rng = np.random.default_rng(seed)
    n = n_groups * per_group
    X = rng.normal(size=(n, 6))
    y = np.exp(rng.normal(size=n))
    groups = np.repeat(np.arange(n_groups), per_group).astype(str) if scheme == "loso" else None
    cv = None if scheme == "loso" else scheme
    result = pls_cv(X, y, max_components=1, cv="loo" if cv is None else cv, groups=groups, random_state=seed,
                    cap=True)
    fid, name = fold_ids(n, cv, groups, seed)
    baseline = training_mean_predictions(y, fid)
    assert name == result.scheme and np.array_equal(fid, result.folds)
    assert np.array_equal(baseline, result.predictions[:, 0])
    other = rng.normal(size=n)  # a second column, as the law's CV stacks its own predictions beside the baseline
    rmse, _, _ = error_curve(np.column_stack([baseline, other]), y, fid)
    assert rmse[0] == result.rmse[0]


def test_the_baseline_is_each_training_folds_mean():
    y = np.array([1.0, 2.0, 4.0, 8.0, 16.0, 32.0])
    fid = np.array([0, 0, 1, 1, 2, 2])
    expected = [(y.sum() - y[fid == f].sum()) / 4 for f in fid]
    np.testing.assert_allclose(training_mean_predictions(y, fid), expected, rtol=1e-15)


@pytest.mark.parametrize(("cv", "groups", "error", "message"), [
    (None, ["a"] * 4, FoldConfigError, "at least 2 groups"),
    (None, ["a", "b"], InputError, "groups has 2 entries for 4 samples"),
    (5, None, ConfigError, "K-fold needs 2 <= k <= n_samples=4, got k=5"),
    ("loo", ["a", "b", "a", "b"], ConfigError, "cannot be combined"),
    ("half", None, ValueError, "cv must be 'loo'"),
])
def test_an_impossible_scheme_is_refused_in_words(cv, groups, error, message):
    with pytest.raises(error, match=message):
        fold_ids(4, cv, groups, 0)
