"""A press's descriptors against analytic truth: a grating's angle, white noise's level and whiteness, a sine's
contrast, a grating's peak over its noise; and a reading that returns an unreadable image's error, not raises it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from roughsense.errors import InputError
from roughsense.sensor.descriptors import DN, line_shift_angle, press_descriptors, press_strips
from roughsense.sensor.spectrum import SpatialSpectrum

PX_PER_MM = 34.9


def _grating(angle_deg: float, period_mm: float = 3.0, shape=(320, 1920), noise: float = 0.0, seed: int = 0):
    y, x = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    phase = 2 * np.pi * (x - y * math.tan(math.radians(angle_deg))) / (period_mm * PX_PER_MM)
    image = 0.5 + 0.3 * np.sin(phase) + np.random.default_rng(seed).normal(0, noise, shape)
    return np.clip(image, 0, 1)


@pytest.mark.parametrize("angle", [0.0, 2.0, -7.5, 15.0, 30.0])
def test_the_angle_of_a_turned_grating(angle):
    image = _grating(angle, noise=0.02)
    box = (10, 85, 1900, 150)
    spaced, _ = press_strips(image, box, 1)
    found, residual = line_shift_angle(spaced, 1 / (3.0 * PX_PER_MM), 4)
    assert found == pytest.approx(angle, abs=0.1) and residual < 0.05


def test_white_noise_level_and_whiteness_and_a_smoothed_copy():
    rng = np.random.default_rng(1)
    frame = np.clip(0.5 + rng.normal(0, 10 / DN, (320, 1920)), 0, 1)
    line = frame[159, 10:1910]
    values = press_descriptors(press_strips(frame, (10, 85, 1900, 150), 1), line, PX_PER_MM, 0.1, 1.0)
    assert values["noise_dn"] == pytest.approx(10, rel=0.05)
    assert values["noise_whiteness"] == pytest.approx(3.0, abs=0.1)  # var of 2nd differences / 1st: 6/2
    smoothed = (frame[:-1] + frame[1:]) / 2  # what interpolation does to a magnified frame's rows
    values = press_descriptors(press_strips(smoothed, (10, 85, 1900, 150), 1), line, PX_PER_MM, 0.1, 1.0)
    assert values["noise_whiteness"] == pytest.approx(2.0, abs=0.1)  # (1, 1)/2 smoothing: sigma^2 over sigma^2 / 2


def test_a_grating_stands_above_its_noise_and_a_sine_has_its_contrast():
    image = _grating(0.0, noise=0.01)
    line = image[159, 10:1910]
    values = press_descriptors(press_strips(image, (10, 85, 1900, 150), 1), line, PX_PER_MM, 0.1, 1.0)
    assert values["peak_over_noise"] > 100
    # a sine of amplitude a spans 2 a sin(0.45 pi) between its 5th and 95th percentiles
    assert values["contrast_dn"] == pytest.approx(2 * 0.3 * math.sin(0.45 * math.pi) * DN, rel=0.03)
    assert values["coherence"] > 0.8 and abs(values["orientation_deg"]) < 0.2
    noise = np.random.default_rng(2).uniform(0, 1, (320, 1920))
    values = press_descriptors(press_strips(noise, (10, 85, 1900, 150), 1), noise[159, 10:1910], PX_PER_MM, 0.1, 1.0)
    assert values["peak_over_noise"] < 5 and values["coherence"] < 0.2


def test_a_reading_returns_the_error_of_an_unreadable_image(tmp_path):
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"not an image")
    good = (_grating(0.0) * 255).astype(np.uint8)
    spectrum = SpatialSpectrum().fit()
    first, second = list(spectrum.iter_readings([broken, good]))
    assert isinstance(first, InputError) and "broken.png" in str(first)
    row, line, values = second
    np.testing.assert_array_equal(row, spectrum.transform([good])[0])  # the same spectrum as ever
    assert set(values) >= {"peak_over_noise", "orientation_deg"}
