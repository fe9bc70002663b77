"""The groove model's jackknife+ folds (model/groove/jackknife.py): each the model chosen and refitted without one
specimen (brute force, tests/model/groove/test_cv.py), kept in a model file and read back with its interval."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import roughsense as rs
from roughsense.errors import ModelFileError
from roughsense.model import modelfile
from roughsense.model.groove.family import GrooveFamily
from roughsense.model.groove.law import GrooveInputError, GrooveLaw
from roughsense.model.groove.terms import contact_terms
from roughsense.model.jackknife_file import deployed_jackknife
from tests.model.groove.test_cv import brute_out_of_fold
from tests.model.groove.test_family import grating_study
from tests.model.groove.test_file import _features


@pytest.fixture(scope="module")
def deployed():
    X, y, specimens, settings = grating_study(reps=3)
    jackknife = GrooveFamily().jackknife(X, y, specimens, settings, None, seed=0)
    return jackknife, X, y, specimens, settings


def test_each_fold_is_the_model_chosen_and_refitted_without_its_specimen(deployed):
    jackknife, X, y, specimens, settings = deployed
    terms, _ = contact_terms(settings.contact, settings.contact_names, settings.surfaces)
    brute = brute_out_of_fold(terms, np.log(y), specimens, specimens)
    every = jackknife.folds.log_predict(X, specimens, contact=settings.contact)  # (S, n), surfaces read together
    codes, names = pd.factorize(pd.Series(specimens), sort=False)
    np.testing.assert_allclose(every[codes, np.arange(y.size)], brute, rtol=1e-9)
    assert jackknife.specimens == tuple(names) and jackknife.counts == (1, 3)
    whole = np.log(pd.Series(y).groupby(codes).first().to_numpy()) - np.log(
        pd.Series(np.exp(brute)).groupby(codes).mean().to_numpy())
    np.testing.assert_allclose(jackknife.log_residuals[-1], whole, rtol=1e-9)  # all 3 presses: each specimen whole


def test_the_folds_travel_in_a_model_file_and_give_its_interval(deployed, tmp_path):
    jackknife, X, y, specimens, settings = deployed
    law = GrooveLaw().fit(X, y, contact=settings.contact, contact_names=settings.contact_names, specimens=specimens)
    training = {"specimens": sorted(set(specimens)), "jackknife_plus": jackknife.to_dict()}
    path = modelfile.save_model(tmp_path / "groove.json", law, feature_definition=_features(), training=training)
    loaded = rs.load_model(path)
    again = deployed_jackknife(loaded)
    np.testing.assert_array_equal(again.log_residuals, jackknife.log_residuals)
    low, high, labels = again.intervals(X[:4], contact=settings.contact[:4])
    predicted = loaded.predict(X[:4], contact=settings.contact[:4])
    assert np.all(low <= predicted) and np.all(predicted <= high) and "jackknife+" in labels[0]
    with pytest.raises(GrooveInputError, match="intervals read contact measures"):
        again.intervals(X[:4])


def test_folds_that_do_not_bracket_their_model_are_refused(deployed, tmp_path):
    jackknife, X, y, specimens, settings = deployed
    law = GrooveLaw().fit(X, y, contact=settings.contact, contact_names=settings.contact_names, specimens=specimens)
    stored = jackknife.to_dict()
    stored["folds"]["intercept"] = [v + 3.0 for v in stored["folds"]["intercept"]]  # every fold e^3 above the model
    training = {"specimens": sorted(set(specimens)), "jackknife_plus": stored}
    with pytest.raises(ModelFileError, match="do not bracket the model"):
        modelfile.save_model(tmp_path / "forged.json", law, feature_definition=_features(), training=training)
