"""Issue 35: the law's domain flags a surface read from few presses by their own scatter (model/press_spread.py).

Synthetic spectra with a known scatter: each press of a surface is magnified by its own mount (log period jitter of
known SD), so the truth is the jitter's SD; scipy's median absolute deviation is the independent reference for the
robust spread.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.stats import median_abs_deviation

import roughsense as rs
from roughsense.errors import ModelFileError
from roughsense.model import modelfile as mf
from roughsense.model.press_spread import PRESS_Z, PressScatter, robust_spread, trained_presses

PERIODS_MM = (2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0)
JITTER_SD = 0.03  # log units of period per press (a mount magnifying by 3 %)


def _presses(periods_mm, presses: int, rng, jitter_sd: float = JITTER_SD):
    """Gaussian lobes at 1 / (period x a press's magnification) on a noise floor; labels per surface."""
    freq = rs.frequency_grid()
    period = np.repeat(periods_mm, presses) * np.exp(jitter_sd * rng.standard_normal(len(periods_mm) * presses))
    X = np.exp(-((freq - 1 / period[:, None]) / 0.03) ** 2) + 0.02 + 0.005 * rng.random((period.size, freq.size))
    return X, np.repeat([f"S{p}" for p in periods_mm], presses), freq


def test_the_robust_spread_is_scipys_normal_scaled_mad_about_zero_and_ignores_misreads():
    rng = np.random.default_rng(0)
    deviation = np.column_stack([0.02 * rng.standard_normal(4000), 0.3 * rng.standard_normal(4000),
                                 np.full(4000, np.nan), rng.standard_normal(4000)])
    deviation[:400, 0] = 1.5  # a tenth of the presses read another peak altogether
    train = np.ones((2, 4000), dtype=bool)
    train[1, 2000:] = False
    spread = robust_spread(deviation, train)
    reference = median_abs_deviation(deviation[:, [0, 1, 3]], axis=0, center=lambda x, axis: 0.0, scale="normal")
    np.testing.assert_allclose(spread[0, [0, 1, 3]], reference, rtol=1e-12)
    assert spread[0, 2] == 0.0  # nothing readable: the surface margins alone
    assert abs(spread[0, 0] - 0.02) < 0.004  # the misreads move the MAD by a little, the SD by ten times
    np.testing.assert_allclose(spread[1, 1], median_abs_deviation(deviation[:2000, 1], center=lambda x, axis: 0.0,
                                                                  scale="normal"), rtol=1e-12)
    # a surface of k presses scatters beyond a trained one of K by sqrt(1/k - 1/K) of a press; none where k >= K
    scatter = PressScatter(spread[0], trained_presses(np.repeat(np.arange(5), [4, 4, 5, 4, 3]), np.ones((1, 20), bool))[0])
    assert scatter.trained_presses == 4
    np.testing.assert_allclose(scatter.excess([1, 2, 4, 9]), PRESS_Z * spread[0] * np.sqrt(
        [[0.75], [0.25], [0.0], [0.0]]))


def test_a_press_read_alone_is_flagged_by_its_scatter_not_by_the_surface_range():
    """Ten presses per surface, each magnified by its mount: read alone, the training presses were flagged for a
    period just past the trained ones (the range is the surfaces' means); with their scatter kept, under 1 % are,
    while a grating of 8 mm read from one press is flagged still."""
    rng = np.random.default_rng(1)
    X, surfaces, freq = _presses(PERIODS_MM, 10, rng)
    y = (np.repeat(PERIODS_MM, 10) / 3.0) ** 0.9
    law = rs.PeakPowerLaw(freq_per_mm=freq).fit(X, y, surfaces=surfaces)
    assert abs(law.press_scatter_.spread[0] - JITTER_SD) < 0.01  # the mounts' jitter, seen by the training presses
    assert law.press_scatter_.trained_presses == 10
    flagged = law.extrapolates(X).mean()
    odd, _, _ = _presses((8.0,), 3, rng)
    assert law.extrapolates(odd).all()
    law.press_scatter_ = None  # the surface margins alone
    assert law.extrapolates(X).mean() >= 0.02 > 0.01 >= flagged
    assert not law.extrapolates(X, surfaces=surfaces).any()  # read together, no training surface is outside


def test_a_surface_of_a_few_presses_just_past_the_range_is_inside_but_one_far_past_it_is_not():
    rng = np.random.default_rng(2)
    X, surfaces, freq = _presses(PERIODS_MM, 10, rng)
    law = rs.PeakPowerLaw(freq_per_mm=freq).fit(X, (np.repeat(PERIODS_MM, 10) / 3.0) ** 0.9, surfaces=surfaces)
    near, _, _ = _presses((1.95,), 3, rng, jitter_sd=0.0)  # 2.5 % shorter than the shortest trained period
    far, _, _ = _presses((1.7,), 3, rng, jitter_sd=0.0)
    three = ["new"] * 3
    assert not law.extrapolates(near, surfaces=three).any()
    assert law.extrapolates(far, surfaces=three).all()
    reason = law.applicability(far, surfaces=three)[0]
    assert reason.startswith("period 1.70 mm outside the trained 2.0")


def _saved_law(tmp_path, presses: int, seed: int):
    """A law fitted on ``presses`` simulated presses per grating, saved as a model file: (presses X, law, path)."""
    X, surfaces, freq = _presses(PERIODS_MM, presses, np.random.default_rng(seed))
    law = rs.PeakPowerLaw(freq_per_mm=freq).fit(X, (np.repeat(PERIODS_MM, presses) / 3.0) ** 0.9, surfaces=surfaces)
    path = tmp_path / "law.json"
    features = {"spectrum": rs.SpatialSpectrum().feature_definition(), "conditions": ["2N"]}
    mf.save_model(path, law, feature_definition=features, training={"study": "gratings"})
    return X, law, path


def test_the_scatter_is_kept_in_the_model_file_and_the_loaded_law_flags_alike(tmp_path):
    X, law, path = _saved_law(tmp_path, 10, seed=3)
    loaded = mf.load_model(path)
    np.testing.assert_array_equal(loaded.press_scatter_.spread, law.press_scatter_.spread)
    assert loaded.press_scatter_.trained_presses == 10
    assert loaded.applicability(X) == law.applicability(X)
    assert json.loads(path.read_text())["model"]["press_scatter"] == law.press_scatter_.to_dict()


@pytest.mark.parametrize("bad", [{"spread": [0.1, 0.2, 0.3], "trained_presses": 4},
                                 {"spread": [0.1, -0.2, 0.3, 0.4], "trained_presses": 4},
                                 {"spread": [0.1, 0.2, 0.3, 0.4], "trained_presses": 0}, "wide"])
def test_a_model_file_with_a_malformed_scatter_is_refused_in_one_line(tmp_path, bad):
    _, _, path = _saved_law(tmp_path, 4, seed=4)
    document = json.loads(path.read_text())
    document["model"]["press_scatter"] = bad
    document["sha256"] = mf._digest(document)  # re-signed: the field check, not the checksum, must refuse it
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match="press_scatter must be"):
        mf.load_model(path)
