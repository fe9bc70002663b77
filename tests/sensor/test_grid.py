"""sensor/grid.py: the frequency grid every spectrum is read on, and one line's amplitude at its frequencies: a
sinusoid of amplitude A reads A at its own frequency (the windowed DFT's gain), whatever its phase and offset."""
from __future__ import annotations

import numpy as np
import pytest

from roughsense.errors import ConfigError
from roughsense.sensor.grid import frequency_grid, grid_step, line_amplitude


def test_the_grid_is_evenly_spaced_with_both_ends():
    grid = frequency_grid(0.1, 1.0, 45)
    np.testing.assert_allclose(np.diff(grid), 0.9 / 44, rtol=1e-12)
    assert grid[0] == 0.1 and grid[-1] == 1.0
    assert grid_step(grid) == pytest.approx(0.9 / 44) and grid_step(grid[:1]) == 0.0


@pytest.mark.parametrize("band", [(1.0, 0.1, 45), (0.0, 1.0, 45), (0.1, 1.0, 1)])
def test_a_band_that_is_no_band_is_refused(band):
    with pytest.raises(ConfigError):
        frequency_grid(*band)


@pytest.mark.parametrize("window", ["hann", "none"])
@pytest.mark.parametrize("phase", [0.0, 1.1])
def test_a_sinusoid_reads_its_amplitude_at_its_own_frequency(window, phase):
    px_per_mm, period_mm, amplitude = 20.0, 2.5, 0.3
    x_mm = np.arange(2000) / px_per_mm  # 40 periods: a whole number, so the plain window leaks nothing
    line = 0.5 + amplitude * np.sin(2 * np.pi * x_mm / period_mm + phase)
    spectrum = line_amplitude(line, px_per_mm=px_per_mm, freq_per_mm=[1 / period_mm, 0.9], window=window)
    assert spectrum[0] == pytest.approx(amplitude, rel=1e-3)
    assert spectrum[1] < 0.02 * amplitude  # 0.9 mm^-1 lies far from 0.4
