"""The groove model's batched nested CV (model/groove/cv.py) against brute force: every outer fold refitted with
numpy's lstsq, its terms chosen by a plain loop over inner leave-one-specimen-out refits, and the final fit against
scikit-learn's LinearRegression."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.linear_model import LinearRegression

from roughsense.model.groove.cv import SELECTION_SE, nested_fit, nested_log_predictions


def _lstsq(Z, y, rows, cols):
    A = np.column_stack([np.ones(rows.sum()), Z[rows][:, cols]])
    return np.linalg.lstsq(A, y[rows], rcond=None)[0]


def _inner_errors(Z, y, specimens, train, cols) -> np.ndarray:
    """Each inner held-out specimen's mean squared error, by refitting without it (readable rows only)."""
    readable = np.all(np.isfinite(Z), axis=1)
    errors = []
    for s in np.unique(specimens[train]):
        fit_rows, test = train & (specimens != s) & readable, train & (specimens == s) & readable
        if test.any():
            b = _lstsq(Z, y, fit_rows, cols)
            errors.append(np.mean((y[test] - b[0] - Z[test][:, cols] @ b[1:]) ** 2))
    return np.array(errors)


def brute_choice(Z, y, specimens, train, se=SELECTION_SE) -> list[int]:
    """Forward selection in column order, each term kept if the paired inner difference beats one SE."""
    kept = []
    for t in range(Z.shape[1]):
        d = _inner_errors(Z, y, specimens, train, kept + [t]) - _inner_errors(Z, y, specimens, train, kept)
        if d.size > 1 and d.mean() + se * d.std(ddof=1) / np.sqrt(d.size) < 0:
            kept.append(t)
    return kept


def brute_out_of_fold(Z, y, folds, specimens) -> np.ndarray:
    readable = np.all(np.isfinite(Z), axis=1)
    out = np.empty(len(y))
    for label in np.unique(folds):
        held = folds == label
        kept = brute_choice(Z, y, specimens, ~held)
        b = _lstsq(Z, y, ~held & readable, kept)
        rows = ~held & readable
        terms = Z[held][:, kept]
        low, high = Z[rows][:, kept].min(axis=0), Z[rows][:, kept].max(axis=0)
        terms = np.where(np.isfinite(terms), np.clip(terms, low, high), Z[rows][:, kept].mean(axis=0))
        out[held] = b[0] + terms @ b[1:]
    return out


def design(seed: int, n_specimens: int = 8, reps: int = 3, nan_rows: int = 1):
    rng = np.random.default_rng(seed)
    specimens = np.repeat([f"s{i}" for i in range(n_specimens)], reps)
    groove = np.repeat(rng.uniform(-0.7, 1.2, n_specimens), reps) + 0.03 * rng.standard_normal(specimens.size)
    land = np.repeat(rng.uniform(-0.7, 1.2, n_specimens), reps) + 0.03 * rng.standard_normal(specimens.size)
    noise = 0.2 * rng.standard_normal(specimens.size)
    Z = np.column_stack([groove, land, noise])
    Z[rng.choice(specimens.size, nan_rows, replace=False), rng.integers(0, 3)] = np.nan
    truth = np.repeat(rng.normal(size=n_specimens), reps)
    log_y = np.column_stack([0.8 * np.repeat(groove[::reps], reps) + 0.05 * truth,
                             rng.permutation(truth), -0.3 * np.repeat(land[::reps], reps) + 0.1 * truth])
    return Z, log_y, specimens


@pytest.mark.parametrize("scheme", ["loso", "loo", "pairs"])
def test_nested_predictions_are_brute_force_refits_of_every_fold(scheme):
    Z, log_y, specimens = design(0)
    folds = {"loso": specimens, "loo": np.arange(len(specimens)),
             "pairs": np.array([int(s[1:]) // 2 for s in specimens])}[scheme]
    predictions, chosen = nested_log_predictions(Z, log_y, folds, specimens)
    for b in range(log_y.shape[1]):
        np.testing.assert_allclose(predictions[b], brute_out_of_fold(Z, log_y[:, b], folds, specimens), atol=1e-9)
    assert chosen.shape == (np.unique(folds).size, log_y.shape[1])


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.integers(5, 9), st.integers(1, 4))
def test_nested_loso_matches_brute_force_on_random_designs(seed, n_specimens, reps):
    Z, log_y, specimens = design(seed, n_specimens, reps, nan_rows=0 if reps == 1 else 1)
    predictions, _ = nested_log_predictions(Z, log_y[:, :1], specimens, specimens)
    np.testing.assert_allclose(predictions[0], brute_out_of_fold(Z, log_y[:, 0], specimens, specimens), atol=1e-8)


def test_a_term_that_pays_is_chosen_and_noise_is_not():
    Z, log_y, specimens = design(3, n_specimens=12)
    every = np.ones((1, len(specimens)), dtype=bool)
    chosen, _, _ = nested_fit(Z, log_y, every, specimens)
    assert chosen[0, 0] == 0b001  # groove alone: it drives the first target
    assert chosen[0, 2] & 0b010  # land drives the third
    assert not chosen[0, 0] & 0b100  # the noise column never earns its place


def test_the_final_fit_is_ordinary_least_squares_on_the_chosen_terms():
    Z, log_y, specimens = design(4, n_specimens=10)
    readable = np.all(np.isfinite(Z), axis=1)
    every = np.ones((1, len(specimens)), dtype=bool)
    chosen, beta, centre = nested_fit(Z, log_y, every, specimens, se=-np.inf)  # keep every term offered
    assert (chosen == 0b111).all()
    for b in range(log_y.shape[1]):
        reference = LinearRegression().fit(Z[readable], log_y[readable, b])
        np.testing.assert_allclose(beta[0, 1:, b], reference.coef_, atol=1e-10)
        np.testing.assert_allclose(beta[0, 0, b] - beta[0, 1:, b] @ centre, reference.intercept_, atol=1e-10)


def test_many_target_columns_in_chunks_equal_each_alone(monkeypatch):
    from roughsense.model.groove import cv

    Z, log_y, specimens = design(5)
    together, chosen = nested_log_predictions(Z, log_y, specimens, specimens)
    monkeypatch.setattr(cv, "CHUNK_CELLS", 1)  # one column a chunk
    for b in range(log_y.shape[1]):
        alone, alone_chosen = nested_log_predictions(Z, log_y[:, b:b + 1], specimens, specimens)
        np.testing.assert_allclose(alone[0], together[b], atol=1e-12)
        assert (alone_chosen[:, 0] == chosen[:, b]).all()


def test_no_term_is_the_training_mean_of_log_roughness():
    _, log_y, specimens = design(6)
    predictions, chosen = nested_log_predictions(np.zeros((len(specimens), 0)), log_y, specimens, specimens)
    for s in np.unique(specimens):
        held = specimens == s
        np.testing.assert_allclose(predictions[:, held], np.broadcast_to(log_y[~held].mean(axis=0)[:, None], (3, held.sum())),
                                   atol=1e-12)
    assert (chosen == 0).all()


def test_a_term_read_in_too_few_rows_is_not_offered_and_drops_no_row():
    from roughsense.model.groove.cv import MIN_READABLE_SHARE

    Z, log_y, specimens = design(7, n_specimens=10)
    scarce = np.full(len(specimens), np.nan)
    scarce[: int(len(specimens) * MIN_READABLE_SHARE) - 1] = 1.0  # read in just under the share
    with_scarce, chosen = nested_log_predictions(np.column_stack([Z, scarce]), log_y, specimens, specimens)
    without, chosen_without = nested_log_predictions(Z, log_y, specimens, specimens)
    np.testing.assert_allclose(with_scarce, without, atol=1e-10)
    assert not (chosen & 0b1000).any() and (chosen == chosen_without).all()
