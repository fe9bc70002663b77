"""Model files: versioned JSON that round-trips exactly and refuses anything damaged or mismatched."""
from __future__ import annotations

import json

import numpy as np
import pytest

from roughsense import SIMPLS
from roughsense.errors import InputError, ModelFileError, OutputExistsError
from roughsense.model import modelfile as mf
from roughsense.model.predict import score_images
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
    np.testing.assert_array_equal(loaded.predict(X), model.predict(X))
    np.testing.assert_array_equal(loaded.coef_path, model.coef_path_)
    np.testing.assert_array_equal(loaded.intercept_path, model.intercept_path_)
    np.testing.assert_array_equal(loaded.x_mean, model.x_mean_)
    assert loaded.n_components == 4 and loaded.coef_.shape == (45,)
    assert loaded.intercept_ == model.intercept_
    assert loaded.training == TRAINING and loaded.conditions == ["1N"]
    assert loaded.features["spectrum"] == json.loads(json.dumps(spectrum().feature_definition()))
    document = json.loads(path.read_text())  # plain JSON, versioned, no pickle anywhere
    assert document["format"] == "roughsense-model" and document["version"] == 1
    assert len(document["model"]["coefficients"]) == 4


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
    expected = model.predict(np.vstack([np.concatenate(spectra[0:3]), np.concatenate(spectra[3:6])]))
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
