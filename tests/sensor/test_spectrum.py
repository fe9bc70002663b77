"""The sensor front end: image -> normalised spatial spectrum, checked against analytic truth and numpy.fft."""
from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from sklearn.base import clone
from sklearn.cross_decomposition import PLSRegression
from sklearn.model_selection import KFold, cross_val_predict
from sklearn.pipeline import Pipeline

import roughsense
from roughsense.errors import ConfigError, InputError
from roughsense.io.images import GRAY_WEIGHTS_RGB, to_gray
from roughsense.sensor.grid import frequency_grid, line_amplitude
from roughsense.sensor.line import resolve_roi, spatial_spectrum
from roughsense.sensor.spectrum import SpatialSpectrum, combine_forces

PX_PER_MM = 34.9
SAMPLES = Path(roughsense.__file__).parent / "data" / "samples"


def grating_line(wavelength_mm, width_px=1900, *, shift_mm=0.0, px_per_mm=PX_PER_MM, edge=None, ridges=0.1):
    """Rectangular grating (lands = 1, grooves = 0) plus weaker 1 mm fingerprint ridges.

    ``edge`` softens the land edges (tanh of a sine) the way lens blur does; None keeps them sharp.
    """
    x_mm = np.arange(width_px) / px_per_mm + shift_mm
    if edge is None:
        lands = (np.mod(x_mm, wavelength_mm) < wavelength_mm / 2).astype(float)
    else:
        lands = 0.5 + 0.5 * np.tanh(edge * np.sin(2 * np.pi * x_mm / wavelength_mm))
    return 0.2 + 0.5 * lands + ridges * np.cos(2 * np.pi * x_mm / 1.0)


def frame(line, height_px=1080):
    """A full camera frame whose every row is ``line`` (so any crop's middle row is that line)."""
    return np.tile(np.asarray(line, dtype=float), (height_px, 1))


def encode(path: Path, pixels: np.ndarray) -> Path:
    """Write RGB or gray pixels with OpenCV (BGR on disk)."""
    if pixels.ndim == 3:
        pixels = pixels[:, :, ::-1]
    assert cv2.imwrite(str(path), np.ascontiguousarray(pixels))
    return path


# --------------------------------------------------------------------------- grid and gray


def test_frequency_grid_is_the_papers_45_points_inclusive():
    grid = frequency_grid()
    assert grid.shape == (45,)
    assert grid[0] == 0.1 and grid[-1] == 1.0
    np.testing.assert_allclose(np.diff(grid), 0.9 / 44, rtol=1e-12)


@pytest.mark.parametrize("band", [(0.0, 1.0), (1.0, 0.5), (0.1, float("nan"))])
def test_frequency_grid_refuses_bad_bands(band):
    with pytest.raises(ConfigError):
        frequency_grid(*band)


def test_gray_weights_are_matlabs_rgb2gray():
    # MATLAB rgb2gray: first row of the inverse of the NTSC YIQ -> RGB matrix, printed as 0.2989, 0.5870, 0.1140.
    yiq_to_rgb = np.array([[1.0, 0.956, 0.621], [1.0, -0.272, -0.647], [1.0, -1.106, 1.703]])
    expected = np.linalg.inv(yiq_to_rgb)[0]
    np.testing.assert_allclose(GRAY_WEIGHTS_RGB, expected, rtol=1e-12)
    np.testing.assert_allclose(np.round(GRAY_WEIGHTS_RGB, 4), [0.2989, 0.5870, 0.1140])


def test_to_gray_scales_8_and_16_bit_to_unit_range():
    rgb8 = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]]], dtype=np.uint8)
    np.testing.assert_allclose(to_gray(rgb8)[0], [*GRAY_WEIGHTS_RGB, 1.0], rtol=1e-12)
    np.testing.assert_allclose(to_gray(rgb8.astype(np.uint16) * 257), to_gray(rgb8), rtol=1e-12)


# --------------------------------------------------------------------------- the line spectrum


@pytest.mark.parametrize("window", ["hann", "none"])
def test_line_amplitude_matches_zero_padded_numpy_fft(window):
    # With 32 px/mm and the FFT padded to 14080 points, bin m sits at m/440 mm^-1, and the paper's grid
    # 0.1 + k * 0.9/44 = (44 + 9k)/440 falls exactly on bins 44 + 9k: numpy's FFT is then the truth.
    px_per_mm, n_fft = 32.0, 14080
    rng = np.random.default_rng(7)
    line = rng.normal(size=1500) + np.sin(2 * np.pi * np.arange(1500) / px_per_mm / 3.0)
    taper = np.hanning(line.size) if window == "hann" else np.ones(line.size)
    spectrum = np.fft.rfft((line - line.mean()) * taper, n=n_fft)
    expected = 2.0 / taper.sum() * np.abs(spectrum[44 + 9 * np.arange(45)])
    grid = frequency_grid()
    np.testing.assert_allclose(np.abs(grid * n_fft / px_per_mm - (44 + 9 * np.arange(45))), 0, atol=1e-9)
    got = line_amplitude(line, px_per_mm=px_per_mm, freq_per_mm=grid, window=window)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)


def test_sine_reads_its_own_amplitude():
    grid = frequency_grid()
    x_mm = np.arange(1900) / PX_PER_MM
    amplitude = 0.37
    line = 5.0 + amplitude * np.sin(2 * np.pi * grid[20] * x_mm + 0.3)
    got = line_amplitude(line, px_per_mm=PX_PER_MM, freq_per_mm=grid)
    assert got[20] == pytest.approx(amplitude, rel=1e-3)


@pytest.mark.parametrize("wavelength_mm", [2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0])
def test_grating_peaks_at_one_over_wavelength(wavelength_mm):
    grid = frequency_grid()
    spectrum = spatial_spectrum(frame(grating_line(wavelength_mm, 1920)))
    step = grid[1] - grid[0]
    assert abs(grid[np.argmax(spectrum)] - 1 / wavelength_mm) <= step / 2 + 1e-12
    # On a fine grid the continuous peak sits on 1/lambda to well within the line's resolution (1/54 mm^-1).
    fine = spatial_spectrum(frame(grating_line(wavelength_mm, 1920)), f_min_per_mm=0.1, f_max_per_mm=0.6, n_freqs=2001)
    fine_grid = frequency_grid(0.1, 0.6, 2001)
    assert abs(fine_grid[np.argmax(fine)] - 1 / wavelength_mm) < 1e-3


def test_spectrum_has_unit_trapezoid_area():
    grid = frequency_grid(0.2, 0.9, 30)
    spectrum = spatial_spectrum(frame(grating_line(3.0, 1920)), f_min_per_mm=0.2, f_max_per_mm=0.9, n_freqs=30)
    assert np.trapezoid(spectrum, grid) == pytest.approx(1.0, rel=1e-12)
    assert np.all(spectrum >= 0)


# --------------------------------------------------------------------------- invariances


@given(
    offset=st.floats(-50, 50),
    gain=st.floats(0.01, 100).flatmap(lambda g: st.sampled_from([g, -g])),
    wavelength_mm=st.floats(2.0, 5.0),
)
def test_invariant_to_brightness_and_contrast(offset, gain, wavelength_mm):
    line = grating_line(wavelength_mm, 1900, edge=3.0)
    image = np.tile(line, (5, 1))
    reference = spatial_spectrum(image, roi="0,0,1900,5", rows=3)
    scaled = spatial_spectrum(offset + gain * image, roi="0,0,1900,5", rows=3)
    np.testing.assert_allclose(scaled, reference, rtol=1e-8, atol=1e-10)


def _line_of(components, shift_mm, width_px=1900):
    x_mm = np.arange(width_px) / PX_PER_MM + shift_mm
    return sum(a * np.cos(2 * np.pi * f * x_mm + p) for f, a, p in components)


@given(wavelength_mm=st.floats(2.0, 5.0), shift_mm=st.floats(0.0, 10.0))
def test_invariant_to_lateral_shift_of_a_grating(wavelength_mm, shift_mm):
    # The crop cuts the pattern at another phase; with the Hann taper the leakage that would make the
    # amplitudes depend on that phase stays below 1 % of the peak (the paper's untapered DFT: ~10 %).
    # No fingerprint here: its 1 mm^-1 peak and the grating's 3rd harmonic are unresolved near 3 mm and
    # beat with the shift, as two components closer than the line's resolution must (see docs/sensor.md).
    reference = spatial_spectrum(np.tile(grating_line(wavelength_mm, edge=3.0, ridges=0), (3, 1)), roi="0,0,1900,3")
    moved = grating_line(wavelength_mm, shift_mm=shift_mm, edge=3.0, ridges=0)
    shifted = spatial_spectrum(np.tile(moved, (3, 1)), roi="0,0,1900,3")
    assert np.max(np.abs(shifted - reference)) <= 0.01 * reference.max()


@given(
    freqs=st.lists(st.floats(0.1, 1.0), min_size=2, max_size=4).filter(
        lambda f: np.min(np.diff(np.sort(f))) > 0.1  # resolved: more than the Hann main lobe (4/L = 0.074 mm^-1)
    ),
    seed=st.integers(0, 2**16),
    shift_mm=st.floats(0.0, 20.0),
)
def test_invariant_to_lateral_shift_of_resolved_components(freqs, seed, shift_mm):
    rng = np.random.default_rng(seed)
    components = [(f, rng.uniform(0.2, 1.0), rng.uniform(0, 2 * np.pi)) for f in freqs]
    reference = spatial_spectrum(np.tile(_line_of(components, 0.0), (3, 1)), roi="0,0,1900,3")
    shifted = spatial_spectrum(np.tile(_line_of(components, shift_mm), (3, 1)), roi="0,0,1900,3")
    assert np.max(np.abs(shifted - reference)) <= 0.01 * reference.max()


@given(level=st.integers(0, 255), shift_px=st.integers(0, 60))
def test_neutral_rgb_equals_gray(level, shift_px):
    gray = np.clip(np.round(255 * grating_line(3.0, 1960)[shift_px : shift_px + 1920] * 0.9) + level // 10, 0, 255)
    gray = np.tile(gray.astype(np.uint8), (1080, 1))
    rgb = np.repeat(gray[:, :, None], 3, axis=2)
    np.testing.assert_allclose(spatial_spectrum(rgb), spatial_spectrum(gray), rtol=1e-12)


def test_rgb_and_gray_files_agree_and_8_and_16_bit_agree(tmp_path):
    gray8 = np.tile(np.round(255 * 0.9 * grating_line(4.0, 1920, edge=2.0)).astype(np.uint8), (1080, 1))
    gray16 = gray8.astype(np.uint16) * 257
    paths = [
        encode(tmp_path / "g8.png", gray8),
        encode(tmp_path / "g16.png", gray16),
        encode(tmp_path / "rgb8.png", np.repeat(gray8[:, :, None], 3, axis=2)),
        encode(tmp_path / "rgb16.tif", np.repeat(gray16[:, :, None], 3, axis=2)),
        encode(tmp_path / "g8.bmp", gray8),
    ]
    assert cv2.imread(str(paths[1]), cv2.IMREAD_UNCHANGED).dtype == np.uint16
    spectra = SpatialSpectrum().fit_transform(paths)
    for row in spectra[1:]:
        np.testing.assert_allclose(row, spectra[0], rtol=1e-12)
    np.testing.assert_allclose(spectra[0], spatial_spectrum(gray8), rtol=1e-12)


def test_crop_middle_row_and_rows_average_match_a_manual_computation():
    rng = np.random.default_rng(3)
    rgb = rng.integers(0, 256, size=(1080, 1920, 3), dtype=np.uint8)
    gray = to_gray(rgb)
    grid = frequency_grid()
    x0, y0 = 10, 465  # 1900 x 150 centred on 1920 x 1080
    for rows, first in [(1, 74), (4, 73), (150, 0)]:
        line = gray[y0 + first : y0 + first + rows, x0 : x0 + 1900].mean(axis=0)
        amplitude = line_amplitude(line, px_per_mm=PX_PER_MM, freq_per_mm=grid)
        expected = amplitude / np.trapezoid(amplitude, grid)
        np.testing.assert_allclose(spatial_spectrum(rgb, rows=rows), expected, rtol=1e-12)


def test_auto_roi_finds_the_textured_band():
    image = np.full((600, 1000), 0.3)
    rng = np.random.default_rng(0)
    image += 0.01 * rng.normal(size=image.shape)  # uniform noise everywhere
    image[400:520] += 0.4 * np.tile(grating_line(2.5, 1000) - 0.5, (120, 1))
    x, y, w, h = resolve_roi("auto", image)
    assert (x, w, h) == (0, 1000, 150)
    assert 370 <= y <= 400 and y + h >= 520


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "kwargs, shape, message",
    [
        ({}, (1000, 1800), "smaller than the 1900x150"),
        ({"roi": "100,900,1900,200"}, (1080, 1920), "reaches outside it"),
        ({"roi": "0,0,300,150"}, (1080, 1920), "shorter than 1/f_min"),
        ({"roi": "auto", "rows": 120}, (100, 1920), "more than the crop height"),
    ],
)
def test_image_problems_name_the_file(tmp_path, kwargs, shape, message):
    path = encode(tmp_path / "frame.png", np.tile(np.uint8(np.arange(shape[1]) % 7 * 30), (shape[0], 1)))
    with pytest.raises(InputError, match=message) as info:
        spatial_spectrum(path, **kwargs)
    assert info.value.path == path


@pytest.mark.parametrize("kwargs", [{"rows": 151}, {"roi": (0, 0, 1900, 20), "rows": 21}, {"rows": 0}, {"n_freqs": 1}])
def test_settings_that_cannot_fit_any_image_are_config_errors(kwargs):
    with pytest.raises(ConfigError):
        spatial_spectrum(np.zeros((1080, 1920)), **kwargs)


@pytest.mark.parametrize("px_per_mm", [0, -34.9, float("nan"), float("inf")])
def test_px_per_mm_must_be_positive(px_per_mm):
    with pytest.raises(ConfigError, match="px_per_mm"):
        spatial_spectrum(np.zeros((1080, 1920)), px_per_mm=px_per_mm)


@pytest.mark.parametrize("content", [b"", b"not an image at all", "truncated"])
def test_unreadable_images_raise_input_error_naming_the_file(tmp_path, content):
    path = tmp_path / "bad.png"
    if content == "truncated":
        ok, data = cv2.imencode(".png", np.random.default_rng(0).integers(0, 255, (1080, 1920), dtype=np.uint8))
        content = data.tobytes()[: data.size // 2]
    path.write_bytes(content)
    with pytest.raises(InputError) as info:
        spatial_spectrum(path)
    assert info.value.path == path


def test_flat_image_cannot_be_normalised():
    with pytest.raises(InputError, match="no texture"):
        spatial_spectrum(np.full((1080, 1920), 0.5))


# --------------------------------------------------------------------------- the transformer


def _images(n, rng):
    wavelengths = rng.uniform(2.0, 5.0, size=n)
    images = [np.tile(grating_line(w, 1920, edge=2.0), (160, 1)) + 0.01 * rng.normal(size=(160, 1920)) for w in wavelengths]
    return images, wavelengths


def test_transformer_matches_the_function_and_threads_keep_order():
    images, _ = _images(9, np.random.default_rng(1))
    expected = np.vstack([spatial_spectrum(im, roi="auto", rows=3) for im in images])
    for n_jobs in (1, 2, -1):
        got = SpatialSpectrum(roi="auto", rows=3, n_jobs=n_jobs).fit(images).transform(images)
        np.testing.assert_array_equal(got, expected)
    streamed = SpatialSpectrum(roi="auto", rows=3, n_jobs=2).iter_transform(iter(images))
    np.testing.assert_array_equal(np.vstack(list(streamed)), expected)


def test_streaming_is_lazy_and_reports_the_failing_item():
    images, _ = _images(3, np.random.default_rng(2))
    consumed = []

    def source():
        for i, image in enumerate(images):
            consumed.append(i)
            yield image
        yield np.full((160, 1920), 0.5)  # flat: fails

    stream = SpatialSpectrum(roi="auto").iter_transform(source())
    next(stream)
    assert consumed == [0]
    with pytest.raises(InputError, match="image 3 of the batch"):
        list(stream)


@pytest.mark.parametrize(
    "check",
    [
        "check_no_attributes_set_in_init",
        "check_parameters_default_constructible",
        "check_get_params_invariance",
        "check_set_params",
        "check_estimator_cloneable",
        "check_estimator_repr",
    ],
)
def test_passes_the_sklearn_checks_that_apply_to_an_image_list_transformer(check):
    # The data-driven checks feed 2-D numeric arrays, which are not lists of images; these do not.
    from sklearn.utils import estimator_checks

    getattr(estimator_checks, check)("SpatialSpectrum", SpatialSpectrum())


def test_sklearn_params_clone_and_feature_definition_round_trip():
    estimator = SpatialSpectrum(px_per_mm=20.0, roi=(0, 0, 400, 10), rows=2, n_freqs=30)
    assert estimator.get_params()["px_per_mm"] == 20.0
    twin = clone(estimator).set_params(rows=5)
    assert twin.rows == 5 and estimator.rows == 2
    definition = json.loads(json.dumps(estimator.fit().feature_definition()))
    np.testing.assert_array_equal(definition["freq_per_mm"], frequency_grid(0.1, 1.0, 30))
    rebuilt = SpatialSpectrum.from_definition(definition)
    assert rebuilt.get_params() == estimator.get_params()
    image = np.tile(grating_line(3.0, 400, px_per_mm=20.0), (10, 1))
    np.testing.assert_array_equal(rebuilt.transform([image]), estimator.transform([image]))
    assert [float(name) for name in estimator.get_feature_names_out()] == list(estimator.freq_per_mm_)


def test_pipeline_with_pls_equals_pls_on_precomputed_features():
    rng = np.random.default_rng(5)
    images, wavelengths = _images(12, rng)
    y = np.log(wavelengths)
    pipeline = Pipeline([("spectrum", SpatialSpectrum(roi="auto", rows=5)), ("pls", PLSRegression(n_components=3))])
    X = np.vstack([spatial_spectrum(im, roi="auto", rows=5) for im in images])
    direct = PLSRegression(n_components=3).fit(X, y)
    np.testing.assert_allclose(pipeline.fit(images, y).predict(images), direct.predict(X), rtol=1e-10)
    folds = KFold(4, shuffle=True, random_state=0)
    np.testing.assert_allclose(
        cross_val_predict(pipeline, images, y, cv=folds),
        cross_val_predict(PLSRegression(n_components=3), X, y, cv=folds),
        rtol=1e-10,
    )


def test_combine_forces_concatenates_in_force_order():
    blocks = [np.full((4, 45), force) for force in (1.0, 2.0, 3.0)]
    combined = combine_forces(blocks)
    assert combined.shape == (4, 135)
    np.testing.assert_array_equal(combined[:, ::45][0], [1.0, 2.0, 3.0])
    with pytest.raises(InputError):
        combine_forces([np.ones((4, 45)), np.ones((3, 45))])


def test_shipped_samples_peak_at_their_named_wavelength():
    paths = sorted(p for p in SAMPLES.iterdir() if p.name.startswith("synthetic_grating_"))
    assert {p.suffix for p in paths} == {".png", ".jpg", ".tif", ".bmp"}
    assert sum(p.stat().st_size for p in paths) < 1_000_000
    grid = frequency_grid()
    spectra = SpatialSpectrum(roi="auto").transform(paths)
    for path, spectrum in zip(paths, spectra):
        wavelength_mm = float(re.search(r"_([\d.]+)mm_", path.name).group(1))
        assert abs(grid[np.argmax(spectrum)] - 1 / wavelength_mm) <= (grid[1] - grid[0]) / 2 + 1e-12, path.name


# --- decoding only the rows above the line ---------------------------------------------------------


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_png_top_rows_decode_equals_full_decode(tmp_path, channels):
    import cv2

    from roughsense.io.images import decode_png_top_rows, png_size, read_bytes, read_image

    rng = np.random.default_rng(channels)
    shape = (90, 200) if channels == 1 else (90, 200, channels)
    pixels = rng.integers(0, 256, size=shape, dtype=np.uint8)
    path = tmp_path / f"c{channels}.png"
    assert cv2.imwrite(str(path), pixels)
    data = read_bytes(path)
    assert png_size(data) == (90, 200)
    top = decode_png_top_rows(data, 37)
    full = read_image(path)
    assert top.shape[:2] == (37, 200)
    np.testing.assert_array_equal(top, full[:37])


def test_spectrum_from_png_file_equals_spectrum_from_array(tmp_path):
    import cv2

    from roughsense.sensor.line import spatial_spectrum

    rng = np.random.default_rng(7)
    x_mm = np.arange(400) / 20.0
    frame = (120 + 60 * np.sin(2 * np.pi * x_mm / 3.0))[None, :] + rng.normal(0, 5, (120, 400))
    frame = np.clip(frame, 0, 255).astype(np.uint8)
    rgb = np.dstack([frame, np.roll(frame, 3, axis=1), frame])
    path = tmp_path / "frame.png"
    assert cv2.imwrite(str(path), rgb[:, :, ::-1])
    for rows in (1, 9):
        kwargs = dict(px_per_mm=20.0, roi=(0, 30, 400, 40), rows=rows)
        np.testing.assert_array_equal(spatial_spectrum(path, **kwargs), spatial_spectrum(rgb, **kwargs))


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
@pytest.mark.parametrize("where", [(0, 0), (599, 999), (10, 500)])
def test_one_non_finite_pixel_outside_the_crop_does_not_move_the_auto_band(bad, where):
    """36.8: a float TIFF with NaN at (0, 0) moved the band (1.29 -> 1.25, unflagged): the crop must be the clean
    image's, and its spectrum identical."""
    import numpy as np

    from roughsense.sensor.line import resolve_roi, spatial_spectrum

    rng = np.random.default_rng(0)
    clean = 0.3 + 0.01 * rng.normal(size=(600, 1000))
    x_px = np.arange(1000)
    clean[400:520] += 0.2 * np.sin(2 * np.pi * x_px / (2.5 * 34.9))  # the one textured band
    dirty = clean.copy()
    dirty[where] = bad
    assert resolve_roi("auto", dirty) == resolve_roi("auto", clean)
    x, y, w, h = resolve_roi("auto", clean)
    assert 370 <= y <= 400 and y + h >= 520
    np.testing.assert_array_equal(spatial_spectrum(dirty, roi="auto"), spatial_spectrum(clean, roi="auto"))
