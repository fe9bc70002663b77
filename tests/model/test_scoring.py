"""``model/scoring.py``: a batch's trials scored through the model's own spectrum, each kept trial exactly as if the
withheld ones had never been given, and ``--roi auto``'s field check never aborting on an unreadable image."""
from __future__ import annotations

import warnings

import cv2
import numpy as np
import pytest

import roughsense as rs
from roughsense.errors import RoughsenseWarning
from roughsense.model.modelfile import load_model, save_model
from roughsense.model.reading import SensorOverride
from roughsense.model.scoring import score_trials, warn_field_of_view

PX_PER_MM = 34.9


def grating(path, period_mm: float, width_px: int = 1920):
    row = 128 + 100 * np.sign(np.sin(2 * np.pi * np.arange(width_px) / PX_PER_MM / period_mm))
    assert cv2.imwrite(str(path), np.tile(row, (160, 1)).astype(np.uint8))
    return path


@pytest.fixture(scope="module")
def law(tmp_path_factory):
    """A peak law fitted on square gratings of 2-5 mm (no contact-image gate: every readable press is kept)."""
    folder = tmp_path_factory.mktemp("law")
    periods = np.repeat([2.0, 3.0, 4.0, 5.0], 2)
    spectrum = rs.SpatialSpectrum().fit()
    X = spectrum.transform([grating(folder / f"train{i}.png", p) for i, p in enumerate(periods)])
    fitted = rs.PeakPowerLaw(freq_per_mm=spectrum.freq_per_mm_).fit(X, (periods / 3) ** 0.9)
    features = {"spectrum": spectrum.feature_definition(), "conditions": ["2N"]}
    path = save_model(folder / "law.json", fitted, feature_definition=features, training={"reference_specimen": "R3"})
    return {"path": path, "spectrum": spectrum, "fitted": fitted, "folder": folder}


def test_a_kept_trial_scores_as_the_fitted_estimator_does_and_as_if_the_withheld_one_were_not_given(law, tmp_path):
    a, b = grating(tmp_path / "a_2N.png", 2.5), grating(tmp_path / "b_2N.png", 4.5)
    loaded = load_model(law["path"])
    alone = score_trials(loaded, [a, b])
    expected = law["fitted"].predict(law["spectrum"].transform([a, b]))  # the estimator fitted here, a fresh spectrum
    np.testing.assert_allclose(alone.roughness, expected, rtol=1e-12)
    mixed = score_trials(loaded, [a, tmp_path / "missing_2N.png", b])
    assert list(mixed.withheld) == [False, True, False] and np.isnan(mixed.roughness[1])
    assert mixed.reasons[1].startswith("unreadable:") and "not found" in mixed.reasons[1]
    np.testing.assert_array_equal(mixed.roughness[[0, 2]], alone.roughness)
    np.testing.assert_array_equal(mixed.low[[0, 2]], alone.low)


def test_roi_auto_with_an_unreadable_first_image_withholds_its_row_and_scores_the_rest(law, tmp_path):
    """On pre-45 the field check re-read the first image and aborted the batch ("image file not found")."""
    good = grating(tmp_path / "good_2N.png", 3.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RoughsenseWarning)  # the file has no gate: said once
        table = rs.predict(law["path"], [tmp_path / "missing_2N.png", good], roi="auto")
    assert list(table["withheld"]) == [True, False]
    assert np.isnan(table["roughness_rel_R3"][0]) and np.isfinite(table["roughness_rel_R3"][1])


def test_roi_auto_warns_on_the_first_readable_image_whose_field_differs(law, tmp_path):
    narrow = grating(tmp_path / "narrow_2N.png", 3.0, width_px=900)  # 25.8 mm of line, the model's 54.4 mm
    loaded = load_model(law["path"])
    override = SensorOverride.parse(roi="auto")
    with pytest.warns(RoughsenseWarning, match=r"--roi auto reads 25.8 mm of line in narrow_2N.png"):
        change = warn_field_of_view(loaded, override, [tmp_path / "missing_2N.png", narrow])
    assert change == pytest.approx(900 / 1900 - 1)
    assert warn_field_of_view(loaded, None, [narrow]) is None  # the model's own ROI: nothing to compare


def pulses(path, period_mm: float, land_mm: float, width_px: int = 1920):
    """A contact image of a rectangular grating: bright lands of ``land_mm`` every ``period_mm`` on a dark gap."""
    x_mm = np.arange(width_px) / PX_PER_MM
    row = np.where(np.mod(x_mm, period_mm) < land_mm, 200, 50)
    assert cv2.imwrite(str(path), np.tile(row, (160, 1)).astype(np.uint8))
    return path


def test_a_family_that_reads_the_contact_gets_each_trials_measures_from_predict(tmp_path):
    """The groove family's loaded model scores as the fitted one does on the contact measures the sensor reads,
    and a groove wider than any trained is flagged: predict passes the measures as the family's keyword."""
    from roughsense.model.groove.law import GrooveLaw
    from roughsense.sensor.contact_geometry import CONTACT_MEASURES

    geometry = [(2, 1), (3, 1.5), (4, 2), (5, 2.5), (4, 1), (4, 3), (3, 1), (3, 2)]
    images = [pulses(tmp_path / f"t{i}_{k}_2N.png", p, land) for i, (p, land) in enumerate(geometry) for k in (0, 1)]
    spectrum = rs.SpatialSpectrum().fit()
    pairs = list(spectrum.iter_transform_contact(images))
    X, contact = np.vstack([p[0] for p in pairs]), np.vstack([p[1] for p in pairs])
    names = tuple(f"{m}@2N" for m in CONTACT_MEASURES)
    groove = np.repeat([p - land for p, land in geometry], 2)
    fitted = GrooveLaw().fit(X, (groove / 1.5) ** 0.8, contact=contact, contact_names=names,
                             specimens=np.repeat(np.arange(len(geometry)), 2).astype(str))
    features = {"spectrum": spectrum.feature_definition(), "conditions": ["2N"]}
    path = save_model(tmp_path / "groove.json", fitted, feature_definition=features,
                      training={"reference_specimen": "R3"})
    new = [pulses(tmp_path / "a_2N.png", 4.5, 2.0), pulses(tmp_path / "wide_2N.png", 5.0, 0.6)]
    [(_, a), (_, wide)] = list(spectrum.iter_transform_contact(new))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RoughsenseWarning)  # the file has no gate: said once
        table = rs.predict(path, new)
    expected = fitted.predict(spectrum.transform(new), contact=np.vstack([a, wide]))
    np.testing.assert_allclose(table["roughness_rel_R3"], expected.round(3), atol=0.006)
    assert list(table["extrapolates"]) == [False, True] and "groove" in table["outside"][1]
