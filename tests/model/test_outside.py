"""``model/outside.py``: the images' scale against a period they are stated to show (a grating of known period read
at a known scale), and the band test, on lines drawn with numbers."""
from __future__ import annotations

import numpy as np
import pytest

from roughsense.model.outside import images_scale_check, trial_band_reasons

PX_PER_MM = 34.9


class Spectrum:
    """What the checks read of the model's spectrum: its scale and its band (mm^-1)."""

    px_per_mm = PX_PER_MM
    freq_per_mm_ = np.linspace(0.1, 1.0, 64)


def grating(period_mm: float, phase: float = 0.0, n_px: int = 1900) -> np.ndarray:
    return 128 + 60 * np.sin(2 * np.pi * np.arange(n_px) / (PX_PER_MM * period_mm) + phase)


LINES = [grating(3.0, phase) for phase in np.linspace(0, 2, 6)]


def test_lines_of_their_stated_period_confirm_the_scale():
    check = images_scale_check(Spectrum(), LINES, 1, None, ("the stated period", np.full(6, 3.0)))
    assert check.checked and not check.off
    assert check.measured_px_per_mm == pytest.approx(PX_PER_MM, rel=0.01)


def test_lines_of_two_periods_each_twice_its_stated_one_measure_twice_the_scale():
    """Two known periods must agree on a scale far from the stated one; one alone only says where it peaks."""
    lines = LINES[:3] + [grating(2.0, phase) for phase in (0, 1, 2)]
    check = images_scale_check(Spectrum(), lines, 1, None, ("the stated periods", np.repeat([1.5, 1.0], 3)))
    assert check.off and check.measured_px_per_mm == pytest.approx(2 * PX_PER_MM, rel=0.01)
    assert check.reason().startswith("scale: the images measure")
    alone = images_scale_check(Spectrum(), LINES, 1, None, ("the stated period", np.full(6, 1.5)))
    assert not alone.checked and "clear peaks at 69." in alone.doubt


def test_two_images_per_trial_are_one_mount_and_one_band_reading():
    reasons = trial_band_reasons(Spectrum(), LINES, 2, None)
    assert reasons == ["", "", ""]  # a 3 mm grating (0.33 mm^-1) lies inside the band
    wide = [grating(20.0, phase) for phase in (0, 1)]  # 0.05 mm^-1: below the band
    assert trial_band_reasons(Spectrum(), wide, 2, None)[0] != ""
