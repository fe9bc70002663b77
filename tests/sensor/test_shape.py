"""Features of shape (sensor/shape.py) read through the real sensor from pulse trains of known duty cycle: the
second harmonic's ratio is |cos(pi d)| (the Fourier series of a pulse train), and 2 f0 on a pad's ridges is NaN."""
from __future__ import annotations

import numpy as np
import pytest

from roughsense.sensor.grid import frequency_grid
from roughsense.sensor.line import spatial_spectrum
from roughsense.sensor.shape import duty_cycle, harmonic_ratio

PX_PER_MM = 34.9


def _pulse_image(period_mm: float, duty: float) -> np.ndarray:
    x_mm = np.arange(1920) / PX_PER_MM
    line = ((x_mm % period_mm) < duty * period_mm).astype(float)
    return np.tile(0.2 + 0.6 * line, (1080, 1))


@pytest.mark.parametrize(("period_mm", "duty"), [(4.0, 0.15), (4.0, 0.3), (2.5, 0.2), (3.0, 0.4)])
def test_the_duty_cycle_of_a_pulse_train_is_read_back(period_mm, duty):
    freq = frequency_grid()
    spectrum = spatial_spectrum(_pulse_image(period_mm, duty), px_per_mm=PX_PER_MM)
    ratio = harmonic_ratio(np.log(spectrum)[None], freq, np.array([1 / period_mm]))
    assert ratio[0] == pytest.approx(np.log(abs(np.cos(np.pi * duty))), abs=0.08)
    assert duty_cycle(ratio)[0] == pytest.approx(duty, abs=0.02)


def test_a_square_wave_has_almost_no_second_harmonic_and_a_ridge_hides_it():
    freq = frequency_grid()
    spectrum = spatial_spectrum(_pulse_image(3.0, 0.5), px_per_mm=PX_PER_MM)
    assert harmonic_ratio(np.log(spectrum)[None], freq, np.array([1 / 3.0]))[0] < np.log(0.1)
    # A 2 mm grating's second harmonic (1 mm^-1) lies on a fingerprint pad's ridges: unreadable, not a number.
    two_mm = spatial_spectrum(_pulse_image(2.0, 0.2), px_per_mm=PX_PER_MM)
    assert np.isnan(harmonic_ratio(np.log(two_mm)[None], freq, np.array([0.5]), pad_ridge_period_mm=1.0)[0])
    assert harmonic_ratio(np.log(two_mm)[None], freq, np.array([0.5]))[0] == pytest.approx(
        np.log(np.cos(0.2 * np.pi)), abs=0.08)  # the band's last bin: read as it is


def _gratings(duty: float, periods, presses: int, rng) -> tuple[np.ndarray, np.ndarray]:
    rows, names = [], []
    for period in periods:
        for _ in range(presses):
            image = _pulse_image(period, duty) + rng.normal(0, 0.02, size=(1080, 1920))
            rows.append(spatial_spectrum(image, px_per_mm=PX_PER_MM))
            names.append(f"{duty}-{period}")
    return np.array(rows), np.array(names)


def test_a_shape_the_law_never_learnt_is_flagged_in_words():
    """Fitted on square gratings only (lands half the period), the law flags narrow-contact gratings of the same
    periods as an unlearnt contact pattern, and PLS's domain, which keeps the law's readout, does too."""
    from roughsense.model.peak_law.law import PeakPowerLaw
    from roughsense.model.pls.applicability import fit_domain
    from roughsense.model.pls.simpls import SIMPLS

    rng = np.random.default_rng(0)
    periods = (2.5, 3.0, 3.5, 4.0, 4.5, 5.0)
    X, surfaces = _gratings(0.5, periods, 2, rng)
    y = np.repeat(np.array(periods) / 3.0, 2)
    freq = frequency_grid()
    law = PeakPowerLaw(freq_per_mm=freq).fit(X, y, surfaces=surfaces)
    assert law.coef_[1] == 0  # the amplitude is no term
    narrow, narrow_names = _gratings(0.15, (3.0, 4.0), 2, rng)
    reasons = law.applicability(narrow, surfaces=narrow_names)
    assert all("contact pattern unlike any trained surface: narrower ridges" in r for r in reasons), reasons
    assert not any(law.applicability(X, surfaces=surfaces))  # the trained shape is inside
    domain = fit_domain(SIMPLS(n_components=2).fit(X, y), X, y, surfaces, PeakPowerLaw(freq_per_mm=freq))
    assert all("narrower ridges" in r for r in domain.reasons(narrow, narrow_names))


def test_the_ridge_exclusion_is_the_bands():
    """One half-width around the pad's ridges is left out everywhere the sensor reads a peak (sensor/band.py's)."""
    import inspect

    from roughsense.sensor.band import RIDGE_EXCLUSION_PER_MM
    from roughsense.sensor.shape import harmonic_ratio, readable

    for function in (readable, harmonic_ratio):
        assert inspect.signature(function).parameters["exclusion_per_mm"].default is RIDGE_EXCLUSION_PER_MM
    freq = np.linspace(0.1, 1.0, 46)  # ridges of 1 mm: 1.0 mm^-1; a step of 0.02
    assert list(readable(freq, [0.88, 0.92], pad_ridge_period_mm=1.0)) == [True, False]
