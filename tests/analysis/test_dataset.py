"""A study as regression data: features per image, condition matrices (incl. combined) and targets."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from roughsense.analysis import dataset
from roughsense.errors import InputError
from roughsense.io.sensor_settings import SensorSettings
from roughsense.io.study import read_study
from roughsense.io.writer import StudyWriter
from roughsense.sensor.contact_geometry import CONTACT_MEASURES
from roughsense.sensor.grid import frequency_grid
from roughsense.sensor.spectrum import SpatialSpectrum

PX_PER_MM = 20.0
ROI = (0, 16, 600, 32)
# Specimen -> grating wavelength (mm) and the perceived roughness the ratings will aggregate to.
SPECIMENS = {"R1": 1.5, "R2": 2.0, "R3": 3.0, "R4": 4.0, "R5": 5.0, "C2": 2.5}
FORCES_N = (1.0, 2.0, 3.0)


def grating(wavelength_mm: float, force_n: float, rng: np.random.Generator, width_px: int = 600, height_px: int = 64):
    """A small contact image: a grating whose contrast grows with force, plus sensor noise (8 bit)."""
    x_mm = np.arange(width_px) / PX_PER_MM
    line = 0.5 + (0.1 + 0.08 * force_n) * np.sign(np.sin(2 * np.pi * x_mm / wavelength_mm + 0.3))
    frame = np.tile(line, (height_px, 1)) + 0.02 * rng.standard_normal((height_px, width_px))
    return np.clip(np.round(255 * frame), 0, 255).astype(np.uint8)


def make_study(root: Path, *, pads=("fingerprint",), repetitions: int = 3, seed: int = 0, drop=None) -> Path:
    """A tiny but complete study folder (64 px high images, explicit ROI, ratings with reference R3).

    ``drop`` = (specimen, pad, force_n, repetition) leaves that image out of the manifest.
    """
    rng = np.random.default_rng(seed)
    writer = StudyWriter(root)
    writer.write_config(name="tiny", sensor=SensorSettings(px_per_mm=PX_PER_MM, roi=ROI))
    writer.write_specimens(pd.DataFrame({
        "specimen": list(SPECIMENS),
        "shape": ["circular" if s.startswith("C") else "rectangular" for s in SPECIMENS],
        "wavelength_mm": list(SPECIMENS.values()),
    }))
    rows = []
    for pad in pads:
        for specimen, wavelength_mm in SPECIMENS.items():
            for repetition in range(1, repetitions + 1):
                for force_n in FORCES_N:
                    if drop == (specimen, pad, force_n, repetition):
                        continue
                    name = writer.write_image(
                        f"{pad}_{specimen}_{force_n:g}N_{repetition}.png", grating(wavelength_mm, force_n, rng)
                    )
                    rows.append({"image": name, "specimen": specimen, "pad": pad,
                                 "force_n": force_n + 0.01 * rng.standard_normal(), "repetition": repetition})
    writer.write_manifest(pd.DataFrame(rows))
    ratings = []
    for participant in ("P01", "P02", "P03"):
        for session in (1, 2, 3):
            for specimen, wavelength_mm in SPECIMENS.items():
                if specimen == "R3":
                    continue
                value = (wavelength_mm / 3.0) ** 0.8 * np.exp(0.1 * rng.standard_normal())
                ratings.append({"participant": participant, "session": session, "specimen": specimen, "rating": value})
    writer.write_ratings(pd.DataFrame(ratings))
    return root


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    return read_study(make_study(tmp_path_factory.mktemp("study") / "tiny", pads=("fingerprint", "smooth"), repetitions=2))


@pytest.fixture(scope="module")
def features(study):
    return dataset.study_features(study)


def test_features_are_the_sensor_spectra_of_each_manifest_image(study, features):
    assert len(features) == len(study.manifest) == 2 * 6 * 2 * 3
    freq = dataset.frequency_columns(features)
    np.testing.assert_array_equal(dataset.column_frequencies(freq), frequency_grid())
    for column in ("image", "specimen", "pad", "repetition", "condition"):
        assert list(features[column]) == list(study.manifest[column])
    spectrum = SpatialSpectrum(px_per_mm=PX_PER_MM, roi=ROI).fit()
    for i in (0, 17, 70):
        expected = spectrum.transform([study.root / features["image"][i]])[0]
        np.testing.assert_allclose(features[freq].iloc[i].to_numpy(float), expected, rtol=1e-12)
    # the grating's fundamental is where the spectrum peaks (within one grid step)
    row = features[(features.specimen == "R2") & (features.condition == "2N")].iloc[0]
    peak = dataset.column_frequencies(freq)[int(np.argmax(row[freq].to_numpy(float)))]
    assert abs(peak - 1 / SPECIMENS["R2"]) <= 0.9 / 44


def test_single_condition_matrix(features):
    X, meta = dataset.condition_matrix(features, "smooth", "2N")
    rows = features[(features.pad == "smooth") & (features.condition == "2N")]
    assert X.shape == (12, 45) and len(meta) == 12
    assert list(meta.columns) == ["specimen", "repetition", "image"]
    freq = dataset.frequency_columns(features)
    for i in range(len(meta)):
        source = rows[rows.image == meta.image[i]]
        np.testing.assert_array_equal(X[i], source[freq].to_numpy(float)[0])
        assert source.specimen.iloc[0] == meta.specimen[i]


def test_combined_matrix_concatenates_one_trials_three_forces(features):
    X, meta = dataset.condition_matrix(features, "fingerprint", "combined")
    assert X.shape == (12, 135)
    assert list(meta.columns) == ["specimen", "repetition", "image_1N", "image_2N", "image_3N"]
    freq = dataset.frequency_columns(features)
    by_image = features.set_index("image")[freq]
    for i, trial in meta.iterrows():
        for j, force in enumerate(("1N", "2N", "3N")):
            image = trial[f"image_{force}"]
            assert f"_{trial.specimen}_{force}_{trial.repetition}." in image
            np.testing.assert_array_equal(X[i, 45 * j : 45 * (j + 1)], by_image.loc[image].to_numpy(float))


def test_contact_measures_line_up_with_the_rows_force_block_by_force_block(features):
    table = features.sample(frac=1.0, random_state=3).reset_index(drop=True)  # the rows are found by image
    rng = np.random.default_rng(0)
    columns = dataset.contact_columns()
    table[columns] = rng.uniform(0.5, 3.0, (len(table), len(columns)))
    by_image = table.set_index("image")
    measures = [c[len(dataset.CONTACT_PREFIX):] for c in columns]
    X, meta = dataset.condition_matrix(table, "fingerprint", "combined")
    contact, names = dataset.condition_contact(table, meta, "combined")
    assert names == tuple(f"{m}@{f}" for f in ("1N", "2N", "3N") for m in measures)
    assert contact.shape == (len(meta), 3 * len(columns))
    for i, trial in meta.iterrows():
        for j, force in enumerate(("1N", "2N", "3N")):
            row = by_image.loc[trial[f"image_{force}"]]
            assert contact[i, j * len(columns):(j + 1) * len(columns)].tolist() == row[columns].tolist()
    _, single = dataset.condition_matrix(table, "fingerprint", "2N")
    contact, names = dataset.condition_contact(table, single, "2N")
    assert names == tuple(f"{m}@2N" for m in measures)
    np.testing.assert_array_equal(contact, by_image.loc[single["image"], columns].to_numpy())


def test_a_table_without_contact_measures_gives_none(features):
    plain = features[[c for c in features.columns if not str(c).startswith(dataset.CONTACT_PREFIX)]]
    _, meta = dataset.condition_matrix(plain, "fingerprint", "1N")
    assert dataset.condition_contact(plain, meta, "1N") == (None, ())


def test_combined_refuses_an_incomplete_trial(tmp_path):
    root = make_study(tmp_path / "gap", repetitions=2, drop=("R4", "fingerprint", 2.0, 2))
    features = dataset.study_features(read_study(root))
    with pytest.raises(InputError, match=r"specimen 'R4', repetition 2 .* no image at 2N") as info:
        dataset.condition_matrix(features, "fingerprint", "combined", source=root / "manifest.csv")
    assert info.value.path == root / "manifest.csv"
    X, _ = dataset.condition_matrix(features, "fingerprint", "1N")  # the single forces still work
    assert X.shape == (12, 45)


def test_a_manifest_column_named_by_a_number_is_no_spectrum_column(tmp_path, features):
    """Issue 28.1: a header such as 0.0795, 3, nan or Infinity stays a manifest column; X and the grid are unchanged."""
    root = make_study(tmp_path / "extra", pads=("fingerprint", "smooth"), repetitions=2)
    manifest = pd.read_csv(root / "manifest.csv", dtype=str)
    for header in (repr(float(frequency_grid()[0])), "0.0795", "3", "nan", "Infinity"):
        manifest[header] = "0.5"
    manifest.to_csv(root / "manifest.csv", index=False)
    extra = dataset.study_features(read_study(root))
    assert dataset.frequency_columns(extra) == dataset.frequency_columns(features)
    for condition in ("2N", "combined"):
        np.testing.assert_array_equal(dataset.condition_matrix(extra, "smooth", condition)[0],
                                      dataset.condition_matrix(features, "smooth", condition)[0])
    with pytest.raises(InputError, match="column '0.1' has the name of a spectrum frequency"):
        dataset.plain_names(extra)  # a file for people would hold two columns named 0.1
    plain = dataset.plain_names(features)
    n_contact = len(CONTACT_MEASURES)
    assert [float(c) for c in plain.columns[-45 - n_contact:-n_contact]] == list(frequency_grid())
    assert list(plain.columns[-n_contact:]) == list(CONTACT_MEASURES)
    manifest["spectrum@0.3"] = "1"
    manifest.to_csv(root / "manifest.csv", index=False)
    with pytest.raises(InputError, match="column 'spectrum@0.3' starts with 'spectrum@'"):
        dataset.study_features(read_study(root))


def test_unknown_pad_or_condition(features):
    with pytest.raises(InputError, match="pads in the study: fingerprint, smooth"):
        dataset.condition_matrix(features, "glass", "1N")
    with pytest.raises(InputError, match="unknown condition"):
        dataset.condition_matrix(features, "smooth", "5N")


def test_targets_are_the_geometric_means(study):
    summary = pd.DataFrame({"specimen": ["R1", "R3", "C2"], "gmean": [0.5, 1.0, 2.0], "sd": [0.1, np.nan, 0.2]})
    meta = pd.DataFrame({"specimen": ["C2", "R1", "R3", "R1"], "repetition": [1, 1, 1, 2]})
    np.testing.assert_array_equal(dataset.targets(meta, summary), [2.0, 0.5, 1.0, 0.5])
    with pytest.raises(InputError, match="no perceived roughness for specimen"):
        dataset.targets(pd.DataFrame({"specimen": ["R9"]}), summary)
    with pytest.raises(InputError) as info:  # the ratings file, when known, is named
        dataset.targets(pd.DataFrame({"specimen": ["R9", "R1"]}), summary, path=study.root / "ratings.csv")
    assert str(info.value) == f"{study.root / 'ratings.csv'}: no perceived roughness for specimen(s) R9 (not in the ratings)"
    # from the study's own ratings: the reference is 1, the others the geometric mean of participant medians
    perceived = dataset.perceived_roughness(study)
    ratings = study.ratings
    r5 = ratings[ratings.specimen == "R5"].groupby("participant")["rating"].median()
    got = perceived.set_index("specimen")["gmean"]
    assert got["R3"] == 1.0
    assert got["R5"] == pytest.approx(np.exp(np.log(r5).mean()))


def test_study_features_carry_each_contact_measure_read_with_its_pads_ridges(tmp_path, features):
    """Issue 46: one contact@NAME column per measure, each image read with its own pad's ridge period (the same
    numbers iter_transform_contact gives for that pad), beside spectra unchanged; a manifest column with the mark is
    refused before any image is read."""
    root = make_study(tmp_path / "contact", pads=("fingerprint", "smooth"), repetitions=2)
    study = dataclasses.replace(read_study(root), pad_ridge_period_mm={"fingerprint": 1.0})
    columns = dataset.contact_columns()
    assert columns == [f"contact@{name}" for name in CONTACT_MEASURES]
    assert list(features.columns[-len(columns):]) == columns
    features = dataset.study_features(study)
    spectrum = dataset.spectrum_for(study)
    for pad in ("smooth", "fingerprint"):
        rows = np.flatnonzero(features["pad"].to_numpy() == pad)
        ridge = study.pad_ridge_period_mm.get(pad)
        read = list(spectrum.iter_transform_contact([study.image_paths[i] for i in rows], ridge))
        np.testing.assert_array_equal(features[columns].to_numpy()[rows], np.vstack([c for _, c in read]))
        np.testing.assert_array_equal(features[dataset.frequency_columns(features)].to_numpy()[rows],
                                      np.vstack([s for s, _ in read]))
    manifest = pd.read_csv(root / "manifest.csv", dtype=str)
    manifest["contact@land_mm"] = "1"
    manifest.to_csv(root / "manifest.csv", index=False)
    with pytest.raises(InputError, match="column 'contact@land_mm' starts with 'contact@'"):
        dataset.study_features(read_study(root))


def test_the_feature_cache_gives_the_contact_columns_back_exactly(tmp_path, monkeypatch, features):
    """study's feature cache (_util/cache.py) stores the table as CSV: the contact columns, NaN where a press could not
    be read, come back as the same float64 numbers."""
    from roughsense._util import cache

    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    table = features.copy()
    table.loc[0, dataset.contact_columns()] = np.nan  # an unreadable press
    table.loc[:, dataset.contact_columns()[-1]] = np.nan  # a measure no press could give
    assert cache.cached_frame("k", lambda: table)[1] is False
    again, hit = cache.cached_frame("k", lambda: table)
    assert hit
    pd.testing.assert_frame_equal(again[dataset.contact_columns()], table[dataset.contact_columns()])
