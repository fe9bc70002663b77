"""A peak's prominence over the line's noise floor (sensor/prominence.py), against the Rayleigh law of white noise."""
from __future__ import annotations

import numpy as np
import pytest

from roughsense.sensor.period import ZOOM
from roughsense.sensor.prominence import CLEAR_PROMINENCE, LineSpectrum, clear_peaks, scale_grid


@pytest.mark.parametrize("k", [1.5, 2.0, 2.5])
def test_white_noise_exceeds_k_times_its_floor_as_the_rayleigh_law_says(k):
    """Each DFT bin of white noise has a Rayleigh amplitude whose median is sqrt(2 ln 2) sigma, so
    P(amplitude > k x median) = 2^(-k^2); the floor is that median, so the share of bins above k x floor is it."""
    rng = np.random.default_rng(3)
    ratios = []
    for _ in range(60):
        spectrum = LineSpectrum.of(rng.standard_normal(1900))
        bins = slice(20 * ZOOM, 900 * ZOOM, ZOOM)
        ratios.append(spectrum.amplitude[bins] / spectrum.floor[bins])
    share = np.mean(np.concatenate(ratios) > k)
    assert share == pytest.approx(2.0 ** (-k * k), abs=0.006)


def test_a_grating_stands_clear_where_its_period_falls_and_nowhere_else_of_its_own():
    x = np.arange(1900)
    line = np.sin(2 * np.pi * x / 104.7) + 0.3 * np.random.default_rng(0).standard_normal(1900)
    scales = scale_grid([3.0], [1900])
    clear, resolvable = clear_peaks(LineSpectrum.of(line), 3.0, scales)
    assert resolvable.any() and (clear <= resolvable).all()
    found = scales[clear]  # 18 periods on the line: the Hann main lobe (+-2 bins) is +-11 %, the mount spread 5 %
    assert found.min() >= 34.9 / 1.17 and found.max() <= 34.9 * 1.17
    assert not clear_peaks(LineSpectrum.of(np.full(1900, 7.0)), 3.0, scales)[0].any()
    assert CLEAR_PROMINENCE == 5.0  # the docstring's false-alarm figures are for 5
