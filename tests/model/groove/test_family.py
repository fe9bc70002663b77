"""The groove family's engine (model/groove/family.py) on synthetic contact measures, through FoldSettings as the
study hands them: every method against brute-force refits (tests/model/groove/test_cv.py) or plain arithmetic."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from roughsense.errors import ConfigError
from roughsense.model.family import FoldSettings, TrainingSet
from roughsense.model.folds import fold_ids, training_mean_predictions
from roughsense.model.groove.domain import axis_values, held_out_flags
from roughsense.model.groove.family import GrooveFamily, log_predictions_under
from roughsense.model.groove.terms import contact_terms
from roughsense.model.registry import engine
from tests.model.groove.test_cv import brute_out_of_fold

FORCES = ("1N", "2N", "3N")
FREQ = np.linspace(0.1, 1.0, 45)


def grating_study(seed: int = 0, reps: int = 4, exponent: float = 0.7, nan_press: bool = True):
    """Gratings of periods 2-5 mm with lands 0.3, 0.5 and 0.7 of the period, ``reps`` presses each; the perceived
    roughness a power of the groove width (the literature's law). Returns X, y, specimens and the settings."""
    rng = np.random.default_rng(seed)
    periods = np.tile([2.0, 3.0, 4.0, 5.0], 3)
    lands = periods * np.repeat([0.5, 0.3, 0.7], 4)
    grooves = periods - lands
    specimens = np.repeat([f"rect:{p:g}:1:{land:g}" for p, land in zip(periods, lands)], reps)
    columns, names = [], []
    for k, force in enumerate(FORCES):  # the pad sinks a little into the gap as the force grows
        columns += [np.repeat(lands, reps) * (1 + 0.04 * k) * np.exp(0.02 * rng.standard_normal(specimens.size)),
                    np.repeat(grooves, reps) * (1 - 0.04 * k) * np.exp(0.02 * rng.standard_normal(specimens.size))]
        names += [f"land_mm@{force}", f"groove_mm@{force}"]
    contact = np.column_stack(columns)
    if nan_press:
        contact[5, [1, 3, 5]] = np.nan  # one press whose groove could not be read at any force
    y = np.repeat((grooves / 1.5) ** exponent, reps) * np.exp(0.01 * rng.standard_normal(specimens.size))
    X = np.abs(rng.standard_normal((specimens.size, 3 * FREQ.size)))  # spectra: the family ignores them
    settings = FoldSettings(FREQ, 3, None, specimens, contact, tuple(names))
    return X, y, specimens, settings


def test_the_registry_knows_the_family_and_it_reads_contact():
    family = engine("groove")
    assert isinstance(family, GrooveFamily) and family.reads_contact and family.reads_surfaces
    assert family.largest_count(20) == 1


@pytest.mark.parametrize("cv", ["loso", "loo"])
def test_cross_validation_is_brute_force_beside_the_training_mean(cv):
    X, y, specimens, settings = grating_study()
    fold = GrooveFamily().cross_validate(X, y, specimens, cv, settings, 1)
    folds = specimens if cv == "loso" else np.arange(y.size)
    terms, _ = contact_terms(settings.contact, settings.contact_names, settings.surfaces)
    expected = np.exp(brute_out_of_fold(terms, np.log(y), folds, specimens))
    np.testing.assert_allclose(fold.out_of_fold, expected, rtol=1e-9)
    null = np.array([y[folds != f].mean() for f in folds])
    np.testing.assert_allclose(fold.curve, [np.sqrt(np.mean((null - y) ** 2)), np.sqrt(np.mean((expected - y) ** 2))],
                               rtol=1e-9)
    assert fold.curve[1] < 0.5 * fold.curve[0]  # the groove pays


def test_the_permutation_control_refits_every_shuffled_column_as_the_real_one():
    X, y, specimens, settings = grating_study()
    rng = np.random.default_rng(1)
    codes = pd.factorize(specimens)[0]
    values = y[np.unique(codes, return_index=True)[1]]
    Y = np.column_stack([y] + [rng.permutation(values)[codes] for _ in range(5)])
    family = GrooveFamily()
    for cv in ("loso", "loo"):
        rmse = family.permuted_rmse(X, Y, specimens, cv, settings, 1)
        alone = [family.cross_validate(X, column, specimens, cv, settings, 1).curve[1] for column in Y.T]
        np.testing.assert_allclose(rmse, alone, rtol=1e-9)
        assert rmse[0] < rmse[1:].min()


def test_scheme_predictions_and_flags_under_any_folds():
    X, y, specimens, settings = grating_study()
    periods = np.array([s.split(":")[1] for s in specimens])  # a period left out
    family = GrooveFamily()
    predictions, flags = family.scheme_predictions(X, np.column_stack([y, y[::-1]]), specimens, periods, settings, 1)
    terms, names = contact_terms(settings.contact, settings.contact_names, settings.surfaces)
    np.testing.assert_allclose(predictions[0], np.exp(brute_out_of_fold(terms, np.log(y), periods, specimens)),
                               rtol=1e-9)
    assert predictions.shape == (2, y.size)
    np.testing.assert_array_equal(flags, held_out_flags(axis_values(terms, names), specimens, periods))
    # With its period left out, the narrowest land and the widest lands lie outside; a 1 / 1 mm grating does not
    # (the 3 mm gratings' lands and grooves, 0.9-2.1 mm, cover it on both axes).
    assert flags[specimens == "rect:2:1:0.6"].all() and flags[specimens == "rect:5:1:3.5"].all()
    assert not flags[specimens == "rect:2:1:1"].any()


def test_held_out_flags_flag_the_geometry_the_model_never_saw():
    X, y, specimens, settings = grating_study()
    flags = GrooveFamily().held_out_flags(X, y, specimens, settings, None)
    table = pd.DataFrame({"specimen": specimens, "flag": flags}).groupby("specimen")["flag"].mean()
    assert table["rect:5:1:1.5"] == 1.0 and table["rect:2:1:0.6"] == 1.0  # widest groove; narrowest land
    assert table["rect:4:1:2"] == 0.0  # inside every other geometry's widths
    assert not flags[5]  # its groove was not read, but its surface's other presses read it
    import dataclasses

    alone = GrooveFamily().held_out_flags(X, y, specimens, dataclasses.replace(settings, surfaces=None), None)
    assert alone[5]  # read alone, its groove is unknown: flagged


def test_the_interval_check_reads_leave_two_out_fits():
    X, y, specimens, settings = grating_study(reps=3)
    check = GrooveFamily().interval_check(X, y, specimens, settings, 0)
    assert len(check) == 12 and {"covered", "log_halfwidth"} <= set(check.columns)
    terms, _ = contact_terms(settings.contact, settings.contact_names, settings.surfaces)
    pair = ~np.isin(specimens, specimens[[0, 3]])  # without the first two specimens
    log_predictions = log_predictions_under(terms, np.log(y)[:, None], pair[None], specimens)[0, 0]
    np.testing.assert_allclose(log_predictions[~pair], brute_out_of_fold(
        terms, np.log(y), np.where(pair, 0, 1), specimens)[~pair], rtol=1e-9)


def test_without_contact_measures_no_term_is_offered_and_every_row_is_flagged():
    X, y, specimens, settings = grating_study()
    bare = FoldSettings(FREQ, 3, None, specimens)
    family = GrooveFamily()
    fold = family.cross_validate(X, y, specimens, "loso", bare, 1)
    np.testing.assert_allclose(fold.out_of_fold, [np.exp(np.log(y[specimens != s]).mean()) for s in specimens])
    assert family.held_out_flags(X, y, specimens, bare, fold).all()


def _training_set(X, y, specimens, settings, scheme="loso"):
    folds, name = fold_ids(y.size, None if scheme == "loso" else scheme, specimens if scheme == "loso" else None, 0)
    return TrainingSet(X, y, specimens, scheme, 0, folds, name, training_mean_predictions(y, folds), settings, {},
                       "pad 'smooth' at combined")


@pytest.mark.parametrize("scheme", ["loso", 3])
def test_train_recovers_the_groove_law_and_reports_its_cv(scheme):
    X, y, specimens, settings = grating_study(nan_press=False)
    trained = GrooveFamily().train(_training_set(X, y, specimens, settings, scheme))
    law = trained.model
    assert law.terms_[0] == "log_groove_mm" and law.coef_[0] == pytest.approx(0.7, abs=0.05)
    folds = trained.cv.folds
    terms, _ = contact_terms(settings.contact, settings.contact_names, settings.surfaces)
    expected = np.exp(brute_out_of_fold(terms, np.log(y), folds, specimens))
    np.testing.assert_allclose(trained.cv.predictions[:, 1], expected, rtol=1e-9)
    assert trained.record["cv_rmse"][1] == pytest.approx(np.sqrt(np.mean((expected - y) ** 2)))
    assert trained.record["terms_kept"]["log_groove_mm"] == 1.0
    table, lines = GrooveFamily().fit_report(trained)
    assert list(table["model"]) == ["training mean", "groove"]
    assert "log groove width" in lines[1] and "groove widths" in lines[2]


def test_train_refuses_a_study_without_contact_measures_in_one_line():
    X, y, specimens, _ = grating_study()
    with pytest.raises(ConfigError, match="the groove model reads contact measures .* pad 'smooth' at combined"):
        GrooveFamily().train(_training_set(X, y, specimens, FoldSettings(FREQ, 3, None, specimens)))
