"""Model files: versioned JSON that round-trips exactly and refuses anything damaged or mismatched."""
from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense import SIMPLS
from roughsense.errors import InputError, ModelFileError, OutputExistsError
from roughsense.model import modelfile as mf
from roughsense.model.pls.simpls import MIN_ROUGHNESS
from roughsense.model.scoring import score_images
from roughsense.sensor.spectrum import SpatialSpectrum

ROI = (0, 8, 400, 16)


def spectrum():
    return SpatialSpectrum(px_per_mm=20.0, roi=ROI).fit()


def fitted(p=45, A=4, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.random((30, p))
    y = X @ rng.standard_normal(p) + 0.1 * rng.standard_normal(30)
    return SIMPLS(A).fit(X, y), X


TRAINING = {"study": "tiny", "pad": "fingerprint", "condition": "1N", "cv": "loo", "cv_rmse": [1.0, 0.5, 0.4]}


@pytest.fixture
def saved(tmp_path):
    model, X = fitted()
    path = tmp_path / "model.json"
    mf.save_model(path, model, feature_definition=mf.feature_definition_for(spectrum(), ["1N"]), training=TRAINING)
    return path, model, X


def rewrite(path, change):
    """Edit the document and (unless told otherwise) re-sign it, so that only the schema check can object."""
    document = json.loads(path.read_text())
    resign = change(document)
    if resign is not False:
        document["sha256"] = mf._digest(document)
    path.write_text(json.dumps(document))


def test_round_trip_predicts_bit_identically(saved):
    path, model, X = saved
    loaded = mf.load_model(path)
    np.testing.assert_array_equal(loaded.linear_predict(X), model.predict(X))
    np.testing.assert_array_equal(loaded.predict(X), np.maximum(model.predict(X), MIN_ROUGHNESS))
    np.testing.assert_array_equal(loaded.coef_path_, model.coef_path_)
    np.testing.assert_array_equal(loaded.intercept_path_, model.intercept_path_)
    np.testing.assert_array_equal(loaded.x_mean_, model.x_mean_)
    assert loaded.n_components == 4 and loaded.coef_.shape == (45,)
    assert loaded.intercept_ == model.intercept_
    assert loaded.training == TRAINING and loaded.conditions == ["1N"]
    assert loaded.model_file_.features["spectrum"] == json.loads(json.dumps(spectrum().feature_definition()))
    document = json.loads(path.read_text())  # plain JSON, versioned, no pickle anywhere
    assert document["format"] == "roughsense-model" and document["version"] == 1
    assert len(document["model"]["coefficients"]) == 4


def test_a_loaded_file_is_the_fitted_estimator(saved, saved_law):
    """load_model gives back each family's own estimator, predicting bit for bit as the one that was saved (the
    PLS file adds its floor); the file's own part rides along in ``model_file_``."""
    from roughsense.model.peak_law.law import PeakPowerLaw

    for (path, model, X), kind in ((saved, SIMPLS), (saved_law, PeakPowerLaw)):
        loaded = mf.load_model(path)
        assert type(loaded) is kind and loaded.model_file_.path == path and loaded.training == TRAINING
        floor = loaded.floor_ if kind is SIMPLS else -np.inf
        np.testing.assert_array_equal(loaded.predict(X), np.maximum(model.predict(X), floor))
        settings = {k: v for k, v in loaded.get_params().items() if k != "freq_per_mm"}
        assert settings == {k: v for k, v in model.get_params().items() if k != "freq_per_mm"}
    np.testing.assert_array_equal(mf.load_model(saved_law[0]).freq_per_mm, saved_law[1].freq_per_mm_)
    with pytest.raises(ModelFileError, match=r"model\.json: the model expects 45 features per sample, got shape \(1, 3\)"):
        mf.load_model(saved[0]).predict(np.ones((1, 3)))
    np.testing.assert_array_equal(saved[1].predict(saved[2]), saved[1].linear_predict(saved[2]))  # a fit has no floor


def test_refuses_to_overwrite_without_force(saved):
    path, model, _ = saved
    before = path.read_bytes()
    definition = mf.feature_definition_for(spectrum(), ["1N"])
    with pytest.raises(OutputExistsError):
        mf.save_model(path, model, feature_definition=definition, training={})
    assert path.read_bytes() == before
    mf.save_model(path, model, feature_definition=definition, training={}, force=True)
    assert mf.load_model(path).training == {}


def test_truncated_file(saved):
    path, _, _ = saved
    path.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 2])
    with pytest.raises(ModelFileError, match="truncated") as info:
        mf.load_model(path)
    assert info.value.path == path


def test_damaged_number_is_caught_by_the_checksum(saved):
    path, _, _ = saved
    document = json.loads(path.read_text())
    document["model"]["coefficients"][1][3] *= 1.001
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match="checksum") as info:
        mf.load_model(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda d: d.update(version=2), "version 2 is not supported"),
        (lambda d: d.update(format="something-else"), "not a roughsense model file"),
        (lambda d: d.pop("training"), "lacks training"),
        (lambda d: d.update(extra=1), "unknown field"),
        (lambda d: d["model"].update(kind="pls2"), "kind 'pls2'"),
        (lambda d: d["model"]["coefficients"].pop(), r"coefficients has shape \(3, 45\)"),
        (lambda d: d["model"]["x_mean"].append(0.0), r"x_mean has shape \(46,\)"),
        (lambda d: d["model"].update(n_components=0), "positive whole number"),
        (lambda d: d["model"].update(y_mean="1.0"), "y_mean must be a finite number"),
        (lambda d: d["features"].update(conditions=["1N", "2N"]), "2 condition"),
        (lambda d: d["features"].pop("spectrum"), "spectrum"),
    ],
)
def test_schema_violations_are_refused(saved, change, match):
    path, _, _ = saved
    rewrite(path, change)
    with pytest.raises(ModelFileError, match=match) as info:
        mf.load_model(path)
    assert info.value.path == path


def test_not_json_and_missing_file(tmp_path):
    bad = tmp_path / "m.json"
    bad.write_bytes(b"\x80\x81 not text")
    with pytest.raises(ModelFileError, match="damaged or truncated"):
        mf.load_model(bad)
    bad.write_text("[1, 2, 3]")
    with pytest.raises(ModelFileError, match="not a roughsense model file"):
        mf.load_model(bad)
    with pytest.raises(ModelFileError, match="not found"):
        mf.load_model(tmp_path / "absent.json")


def test_feature_definition_must_match_the_coefficients(tmp_path):
    model, _ = fitted(p=45)
    with pytest.raises(ModelFileError, match="45 frequencies x 3 condition"):
        definition = mf.feature_definition_for(spectrum(), ["1N", "2N", "3N"])
        mf.save_model(tmp_path / "m.json", model, feature_definition=definition, training={})
    assert not (tmp_path / "m.json").exists()


def test_check_features_refuses_a_different_definition(saved):
    path, _, _ = saved
    loaded = mf.load_model(path)
    mf.check_features(loaded, mf.feature_definition_for(spectrum(), ["1N"]))  # the same: accepted
    other_scale = SpatialSpectrum(px_per_mm=25.0, roi=ROI).fit()
    with pytest.raises(ModelFileError, match=r"spectrum\.px_per_mm is 25\.0 here but 20\.0 in the model") as info:
        mf.check_features(loaded, mf.feature_definition_for(other_scale, ["1N"]))
    assert info.value.path == path
    band = SpatialSpectrum(px_per_mm=20.0, roi=ROI, f_max_per_mm=0.9).fit()
    with pytest.raises(ModelFileError, match="f_max_per_mm"):
        mf.check_features(loaded, mf.feature_definition_for(band, ["1N"]))
    with pytest.raises(ModelFileError, match="conditions"):
        mf.check_features(loaded, mf.feature_definition_for(spectrum(), ["2N"]))
    with pytest.raises(ModelFileError, match="expects 45 features"):
        loaded.predict(np.zeros((2, 44)))


def gratings(wavelengths_mm, rng):
    x_mm = np.arange(400) / 20.0
    return [
        np.clip(np.round(255 * (0.5 + 0.3 * np.sin(2 * np.pi * x_mm / w) + 0.02 * rng.standard_normal((32, 400)))),
                0, 255).astype(np.uint8)
        for w in wavelengths_mm
    ]


def test_score_images_recomputes_the_models_features(tmp_path):
    rng = np.random.default_rng(1)
    model, _ = fitted(p=135, A=3)
    path = tmp_path / "combined.json"
    mf.save_model(path, model, feature_definition=mf.feature_definition_for(spectrum(), ["1N", "2N", "3N"]), training={})
    loaded = mf.load_model(path)
    images = gratings([2.0, 2.2, 2.4, 4.0, 4.1, 4.3], rng)
    spectra = spectrum().transform(images)
    combined = np.vstack([np.concatenate(spectra[0:3]), np.concatenate(spectra[3:6])])
    expected = np.maximum(model.predict(combined), MIN_ROUGHNESS)
    np.testing.assert_array_equal(score_images(loaded, images), expected)
    # A progress callback sees every image once and changes nothing in the result.
    seen = []

    def progress(items, *, total, description):
        for item in items:
            seen.append(description)
            yield item

    np.testing.assert_array_equal(score_images(loaded, images, progress=progress), expected)
    assert len(seen) == len(images)
    with pytest.raises(InputError, match="groups of 3.*got 4 image"):
        score_images(loaded, images[:4])


def test_deeply_nested_json_is_a_damaged_file_not_a_crash(tmp_path):
    bad = tmp_path / "deep.json"
    bad.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ModelFileError, match="damaged or truncated"):
        mf.load_model(bad)


# --------------------------------------------------------------------------- peak-law model files


@pytest.fixture
def saved_law(tmp_path):
    """A peak law fitted on gratings of 2-5 mm (roughness a power law of the period), saved and its path."""
    from roughsense.model.peak_law.law import PeakPowerLaw

    rng = np.random.default_rng(3)
    periods = np.repeat([2.0, 2.5, 3.0, 3.5, 4.0, 5.0], 2)
    X = spectrum().transform(gratings(periods, rng))
    y = (periods / 3.0) ** 0.9 * np.exp(0.05 * rng.standard_normal(periods.size))
    law = PeakPowerLaw(freq_per_mm=spectrum().freq_per_mm_, pad_ridge_period_mm=1.0).fit(X, y)
    path = tmp_path / "law.json"
    mf.save_model(path, law, feature_definition=mf.feature_definition_for(spectrum(), ["1N"]), training=TRAINING)
    return path, law, X


def test_peak_law_round_trip_predicts_as_the_fitted_law(saved_law):
    path, law, X = saved_law
    loaded = mf.load_model(path)
    assert loaded.family == "peak-law" and loaded.conditions == ["1N"] and loaded.n_features == 45
    np.testing.assert_allclose(loaded.predict(X), law.predict(X), rtol=1e-12, atol=0)
    assert loaded.intercept_ == law.intercept_ and list(loaded.coef_) == list(law.coef_)
    assert loaded.pad_ridge_period_mm == 1.0 and loaded.scale_ == law.scale_
    # a training trial is inside the range; a grating of a period far longer than trained is flagged, and predicted
    # as the law does (held at the training edge)
    new = np.vstack([X[4], spectrum().transform(gratings([9.0], np.random.default_rng(4)))[0]])
    np.testing.assert_array_equal(loaded.extrapolates(new), [False, True])
    np.testing.assert_array_equal(loaded.extrapolates(new), law.extrapolates(new))
    np.testing.assert_allclose(loaded.predict(new), law.predict(new), rtol=1e-12, atol=0)
    from roughsense.model.readout_domain import domain_margins

    low, high = domain_margins(float(np.diff(law.freq_per_mm_)[0]), law.feature_min_, law.feature_max_)
    outside = law.features(new[1:])
    outside[:, 2] = 0.0  # fitted on single presses: the harmonic ratio is no term (coefficient 0), read or not
    edge = np.exp(law.intercept_ + np.clip(outside, low, high) @ law.coef_)
    np.testing.assert_allclose(loaded.predict(new[1:]), edge, rtol=1e-12)
    assert law.features(new[1:])[0, 0] < law.feature_min_[0]  # its peak lies below the lowest trained frequency
    document = json.loads(path.read_text())
    assert document["version"] == 1 and document["model"]["kind"] == "peak-power-law"
    assert document["model"]["feature_names"] == ["log_peak_frequency_per_mm", "log_peak_amplitude",
                                                   "log_second_harmonic_ratio"]
    with pytest.raises(ModelFileError, match="expects 45 features"):
        loaded.predict(np.ones((1, 44)))


def test_a_two_feature_law_file_loads_as_a_law_without_the_shape_term(saved_law):
    """A file written before the harmonic ratio existed (two features) still loads and predicts as it did."""
    path, law, X = saved_law

    def two_features(document):
        model = document["model"]
        for name in ("coefficients", "feature_min", "feature_max", "feature_names"):
            model[name] = model[name][:2]

    assert law.coef_[2] == 0
    rewrite(path, two_features)
    loaded = mf.load_model(path)
    assert loaded.coef_[2] == 0 and np.isinf(loaded.feature_min_[2]) and np.isinf(loaded.feature_max_[2])
    np.testing.assert_allclose(loaded.predict(X), law.predict(X), rtol=1e-12)
    assert not loaded.extrapolates(X).any()


def test_a_pls_file_flags_exactly_the_values_it_held_to_the_trained_range(saved):
    path, model, X = saved
    loaded = mf.load_model(path)
    assert loaded.family == "pls"
    raw = model.predict(X)
    np.testing.assert_array_equal(loaded.extrapolates(X), raw < MIN_ROUGHNESS)
    assert np.all(loaded.predict(X) > 0)
    held = [reason for reason, value in zip(loaded.applicability(X), raw) if value < MIN_ROUGHNESS]
    assert held and all("held at" in reason for reason in held)


LAW_FIELDS = ["kind", "n_features", "n_blocks", "pad_ridge_period_mm", "exclusion_per_mm", "epsilon", "intercept",
              "coefficients", "scale", "feature_min", "feature_max", "feature_names"]


@pytest.mark.parametrize("field", LAW_FIELDS[1:])
def test_a_law_missing_a_field_is_refused_naming_it(saved_law, field):
    path, _, _ = saved_law
    rewrite(path, lambda d: d["model"].pop(field))
    with pytest.raises(ModelFileError, match=rf"lacks the field\(s\) model\.{field}$") as info:
        mf.load_model(path)
    assert info.value.path == path and "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("scale", 0.0, r"model\.scale must be a finite number > 0 and <= 1000, got 0"),
        ("scale", -1, r"model\.scale must be"),
        ("scale", True, r"model\.scale must be .* got True"),
        ("epsilon", "1", r"model\.epsilon must be .* got '1'"),
        ("epsilon", 1e308, r"model\.epsilon must be"),
        ("exclusion_per_mm", 11.0, r"model\.exclusion_per_mm must be"),
        ("intercept", None, r"model\.intercept must be a finite number from -1000 to 1000, got None"),
        ("intercept", 1e308, r"model\.intercept must be"),
        ("pad_ridge_period_mm", 0, r"model\.pad_ridge_period_mm must be a number of mm"),
        ("pad_ridge_period_mm", "1.0", r"model\.pad_ridge_period_mm must be"),
        ("pad_ridge_period_mm", 1000.0, r"model\.pad_ridge_period_mm must be"),
        ("coefficients", [1.0, 1e308, 0.0], r"model\.coefficients\[1\] must be"),
        ("coefficients", [1.0, 2.0, 3.0, 4.0], r"model\.coefficients must be a list of 3 numbers"),
        ("coefficients", [True, 1.0, 0.0], r"model\.coefficients\[0\] must be"),
        ("coefficients", [1.0, 0.0, 0.5], r"must be numbers for every feature with a coefficient"),
        ("feature_min", [0.0], r"model\.feature_min must be a list of 3"),
        ("feature_min", [None, 0.0, None], r"model\.feature_min\[0\] must be"),
        ("feature_max", [-1.0, -1.0, None], r"feature_min exceeds model\.feature_max"),
        ("feature_names", ["a", "b"], r"model\.feature_names must be"),
        ("n_blocks", 3, r"model\.n_blocks is 3, but the feature definition has 1 force condition"),
        ("n_blocks", 1.0, r"model\.n_blocks must be a whole number"),
        ("n_features", 44, r"45 frequencies x 1 condition\(s\), but the model has 44"),
        ("n_features", -1, r"model\.n_features must be"),
        ("extra", 1, r"unknown field\(s\) model\.extra"),
    ],
)
def test_law_fields_out_of_range_are_refused_with_a_valid_checksum(saved_law, field, value, match):
    path, _, _ = saved_law
    rewrite(path, lambda d: d["model"].update({field: value}))
    with pytest.raises(ModelFileError, match=match) as info:
        mf.load_model(path)
    assert info.value.path == path and "\n" not in str(info.value)


def test_a_law_whose_predictions_would_overflow_is_refused(saved_law):
    path, _, _ = saved_law

    def huge(document):
        document["model"].update(intercept=900.0, coefficients=[500.0, 500.0, 0.0], feature_max=[-0.1, 1.0, None],
                                 feature_min=[-2.0, -1.0, None])  # a log peak frequency on the grid, a huge law

    rewrite(path, huge)
    with pytest.raises(ModelFileError, match=r"model\.intercept and model\.coefficients give log roughness"):
        mf.load_model(path)


def test_non_finite_law_fields_are_refused_by_the_field_checks(saved_law):
    """NaN and infinity cannot pass the checksum (canonical JSON refuses them); the field checks refuse them too."""
    from roughsense.model.peak_law import file as peak_law_file

    path, _, _ = saved_law
    document = json.loads(path.read_text())
    for field, value in (("scale", float("nan")), ("intercept", float("inf")), ("coefficients", [float("-inf"), 0.0])):
        section = dict(document["model"], **{field: value})
        with pytest.raises(ModelFileError, match=rf"model\.{field}"):
            peak_law_file.loaded_law(section, document["features"], training={}, roughsense_version="x", path=path)
    (path.parent / "nan.json").write_text(path.read_text().replace('"scale": ', '"scale": NaN, "x": '))
    with pytest.raises(ModelFileError, match="checksum"):
        mf.load_model(path.parent / "nan.json")


def test_a_law_that_cannot_be_stored_is_not_written(tmp_path, saved_law):
    _, law, _ = saved_law
    law.coef_ = np.array([5e3, 0.0, 0.0])  # beyond what a file may hold: refused on saving, not on a user's load
    target = tmp_path / "big.json"
    with pytest.raises(ModelFileError, match=r"model\.coefficients\[0\]"):
        mf.save_model(target, law, feature_definition=mf.feature_definition_for(spectrum(), ["2N"]), training={})
    assert not target.exists()


def test_a_resigned_law_predicting_beyond_a_ratings_bound_is_refused(tmp_path):
    """Issue 28, item 16: a re-signed peak-law file whose law reaches 9e303 inside its own feature range is refused
    (bounded as PLS files are, 1e6), not loaded to predict it."""
    from roughsense.model.peak_law.law import PeakPowerLaw

    rng = np.random.default_rng(0)
    grid = np.linspace(0.1, 1.0, 45)
    X = np.array([np.exp(-0.5 * ((grid - 1 / p) / 0.02) ** 2) + 0.05 + 0.01 * rng.random(45)
                  for p in np.repeat([2.0, 3.0, 4.0, 5.0], 3)])
    y = np.repeat([0.6, 1.0, 1.4, 1.8], 3)
    law = PeakPowerLaw(freq_per_mm=grid).fit(X, y)
    path = tmp_path / "law.json"
    mf.save_model(path, law, feature_definition=mf.feature_definition_for(spectrum(), ["1N"]), training=TRAINING)

    def inflate(document):
        document["model"]["intercept"] = 699.0  # exp(699) ~ 9e303 somewhere in its feature box
    rewrite(path, inflate)
    with pytest.raises(mf.ModelFileError, match="within 1e-6 to 1e6"):
        mf.load_model(path)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**16), shift=st.floats(-50, 50))
def test_a_loaded_pls_model_never_predicts_a_value_at_or_below_zero(tmp_path_factory, seed, shift):
    """PLS is linear and may give any number; a model file's prediction is held at half the smoothest trained
    roughness and flagged where it was held."""
    from roughsense.model import modelfile as mf
    from roughsense.model.pls.simpls import SIMPLS
    from tests.model.test_modelfile import spectrum

    rng = np.random.default_rng(seed)
    X, y = rng.random((12, 45)), rng.uniform(0.5, 2.0, 12)
    model = SIMPLS(n_components=2).fit(X, y)
    training = {"target_range": [float(y.min()), float(y.max())], "reference_specimen": "R3"}
    document = mf.model_document(model, feature_definition=mf.feature_definition_for(spectrum(), ["1N"]),
                                 training=training)
    loaded = mf.model_from_document(document)
    new = X + shift * rng.random(X.shape)
    predicted = loaded.predict(new)
    assert np.all(predicted >= 0.5 * y.min() - 1e-12) and np.all(predicted > 0)
    held = model.predict(new) < 0.5 * y.min()
    reasons = loaded.applicability(new)
    assert [("held at" in reason) for reason in reasons] == list(held)
    assert np.all(loaded.extrapolates(new)[held])
