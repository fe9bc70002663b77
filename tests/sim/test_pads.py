"""The fingerprint pad's ridges show in the image as the paper's Fig. 7 shows them: a peak at 1 mm^-1."""
from __future__ import annotations

import numpy as np
import pandas as pd

from roughsense.sensor.spectrum import SpatialSpectrum
from roughsense.sim.config import SimulationConfig, with_image_size
from roughsense.sim.simulate import simulate_study


def test_fingerprint_ridges_add_a_peak_at_their_own_frequency(tmp_path):
    # R2.5 and C3.5 have no harmonic at 1 mm^-1 (0.4, 0.8, 1.2 and 0.29, 0.57, 0.86, 1.14 mm^-1).
    config = SimulationConfig(pads=("smooth", "fingerprint"), specimens=("R2.5", "C3.5"), forces_n=(1.0, 3.0),
                              repetitions=2, seed=5, participants=2, sessions=1)
    root = simulate_study(tmp_path / "s", with_image_size(config, 1920, 170), jobs=1)
    manifest = pd.read_csv(root / "manifest.csv")
    spectra = SpatialSpectrum().fit_transform([root / p for p in manifest["image"]])
    freq = SpatialSpectrum().fit().freq_per_mm_
    fingerprint = manifest["pad"].to_numpy() == "fingerprint"
    near_ridges = freq >= 0.94  # the ridge period scales with each mount's magnification (about 2 %)
    peak = spectra[:, near_ridges].max(axis=1)
    assert freq[-1] == 1.0
    assert np.median(peak[fingerprint]) > 10 * np.median(peak[~fingerprint])
    # ...and in every fingerprint image it is the largest amplitude of the upper band.
    upper = freq >= 0.7
    assert np.all(freq[upper][np.argmax(spectra[fingerprint][:, upper], axis=1)] >= 0.94)
