"""PLS's exact cross-validation: the permutation control's shortcuts against the plain paths, and against SIMPLS refitted fold by
fold.

Nested leave-one-specimen-out with many shuffled targets fits each pair of specimens left out in that pair's own basis
(``pls_cv._own_basis_pair_choices``): the same Krylov spaces as the shared rotation's downdated operator, so the same
predictions to rounding and the same choices."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense.model.pls import cv as engine
from roughsense.model.pls import cv_engine
from roughsense.model.pls.simpls import PLSConfigError
from tests.model.pls.test_simpls import assert_nested_choices_are_inner_refits, spectra
from tests.targets import shuffled_targets


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), n_specimens=st.integers(5, 7), repetitions=st.integers(3, 4),
       p=st.sampled_from([8, 20]), drop=st.booleans())
def test_own_basis_pair_predictions_equal_the_shared_rotations(seed, n_specimens, repetitions, p, drop):
    X, y, groups = spectra(n_specimens=n_specimens, repetitions=repetitions, p=p, noise=0.05, seed=seed)
    if drop:  # one group a press short: pairs of two sizes
        X, y, groups = X[1:], y[1:], groups[1:]
    Y = shuffled_targets(y, groups, 9, seed)
    A = 3
    held = groups[None, :] == pd.unique(groups)[:, None]
    first, second = np.triu_indices(held.shape[0], k=1)
    pair_rows = [np.flatnonzero(held[j] | held[k]) for j, k in zip(first, second)]
    Z, sv = cv_engine._rotation(X)
    for rows in pair_rows:
        plain = cv_engine._cv_predictions(X, Y, np.zeros(rows.size, dtype=np.intp), A, rows, (Z, sv))
        own = cv_engine._own_basis_predictions(Z, Y, rows[None, :], A, 0.0, np.zeros(1, dtype=int))[0]
        np.testing.assert_allclose(own, plain, rtol=1e-9, atol=1e-12)


def test_nested_choices_with_many_targets_equal_simpls_refitted_per_group():
    """Ten targets take the own-basis pairs; every group's inner choice is what refitting SIMPLS on its inner folds
    chooses, and the nested predictions are the outer run's at that count."""
    X, y, groups = spectra(n_specimens=6, repetitions=3, p=12, noise=0.05, seed=3)
    X, y, groups = np.delete(X, 4, axis=0), np.delete(y, 4), np.delete(groups, 4)
    Y = shuffled_targets(y, groups, 10, seed=1)
    assert Y.shape[1] >= engine._OWN_BASIS_MIN_TARGETS
    outer = engine.pls_cv_many(X, Y, max_components=3, groups=groups).predictions
    nested, chosen = engine.nested_group_predictions(X, Y, groups, outer)
    assert_nested_choices_are_inner_refits(X, Y, groups, outer, nested, chosen, 3)


def test_own_basis_choices_equal_the_shared_rotations_on_spectra(monkeypatch):
    X, y, groups = spectra(n_specimens=8, repetitions=4, p=30, seed=5)
    Y = shuffled_targets(y, groups, 12, seed=2)
    outer = engine.pls_cv_many(X, Y, max_components=6, groups=groups).predictions
    own = engine.nested_group_predictions(X, Y, groups, outer)
    monkeypatch.setattr(engine, "_OWN_BASIS_MIN_TARGETS", Y.shape[1] + 1)
    shared = engine.nested_group_predictions(X, Y, groups, outer)
    np.testing.assert_array_equal(own[1], shared[1])
    np.testing.assert_array_equal(own[0], shared[0])


@pytest.mark.parametrize("drop", [False, True])
def test_many_targets_leave_one_group_out_in_each_folds_basis_equals_one_cv_per_target(drop):
    X, y, groups = spectra(n_specimens=7, repetitions=4, p=25, noise=0.05, seed=8)
    if drop:  # folds of two sizes
        X, y, groups = X[1:], y[1:], groups[1:]
    Y = shuffled_targets(y, groups, 10, seed=4)
    batch = engine.pls_cv_many(X, Y, max_components=6, groups=groups)
    for b in range(Y.shape[1]):
        single = engine.pls_cv(X, Y[:, b], max_components=6, groups=groups)
        np.testing.assert_allclose(batch.predictions[b], single.predictions, rtol=1e-9, atol=1e-12)


def test_an_exhausted_krylov_space_in_a_folds_own_basis_is_refused_naming_its_fold():
    """X'X with two distinct eigenvalues spans a Krylov space of two directions: a third component is rounding noise,
    refused as the shared rotation refuses it, naming the run's fold and what it supports."""
    mu = np.tile(np.repeat([4.0, 1.0], 5), (2, 1))  # two runs, folds 5 and 7
    start = np.random.default_rng(0).normal(size=(2, 10))
    with pytest.raises(PLSConfigError, match=r"in CV fold [57] the Krylov space .* after 2 components") as info:
        cv_engine._diagonal_lanczos(mu, start, 3, 1e-14 * 16, np.array([5, 7]))
    assert info.value.supported == 2
