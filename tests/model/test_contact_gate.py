"""The contact-image gate's conformal p-values: valid on exchangeable data, calibrated over specimens, and its
reasons in the user's words."""
from __future__ import annotations

import math

import numpy as np
import pytest

from roughsense.model.contact_gate import ALPHA, fit_gate, orientation_reason, withheld_reason

NAMES = ("peak_over_noise", "contrast_dn", "noise_dn", "coherence")


def _presses(rng, n_specimens: int, per: int, shift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Descriptors of presses: a specimen effect (presses of one specimen alike) plus press noise."""
    effect = rng.normal(size=(n_specimens, len(NAMES)))
    noise = rng.normal(scale=0.5, size=(n_specimens, per, len(NAMES)))
    z = (effect[:, None, :] + noise).reshape(-1, len(NAMES)) + shift
    values = np.column_stack([np.exp(3 + 0.3 * z[:, 0]), np.exp(4 + 0.2 * z[:, 1]), np.exp(2.5 + 0.05 * z[:, 2]),
                              0.6 + 0.05 * z[:, 3]])
    return values, np.repeat([f"S{i}" for i in range(n_specimens)], per)


def test_p_values_of_new_specimens_are_valid_at_alpha():
    """Exchangeable at the specimen level: presses of new specimens from the same law reject at most alpha (plus
    the binomial error of the count), at several levels."""
    rng = np.random.default_rng(0)
    values, specimens = _presses(rng, 20, 6)
    gate = fit_gate(values, NAMES, specimens, seed=0)
    test, _ = _presses(np.random.default_rng(1), 400, 1)
    p = gate.p_values(test)
    for alpha in (0.05, 0.1, 0.2):
        rate = float(np.mean(p <= alpha))
        assert rate <= alpha + 3 * math.sqrt(alpha * (1 - alpha) / p.size), (alpha, rate)
    assert p.min() >= 1 / (values.shape[0] + 1)


def test_group_calibration_holds_out_each_specimen():
    """Each calibration score comes from the detector that never saw its specimen: refitting without that specimen
    gives the same location; and a press-wise calibration (in-sample scores) would be smaller."""
    rng = np.random.default_rng(2)
    values, specimens = _presses(rng, 8, 5)
    gate = fit_gate(values, NAMES, specimens, seed=0)
    assert gate.locations.shape == (8, len(NAMES)) and gate.calibration.shape == (40,)
    assert np.array_equal(gate.folds, np.repeat(np.arange(8), 5))
    z = gate.standardised(values)
    in_sample = np.einsum("ni,ij,nj->n", z - np.median(z, axis=0), np.linalg.inv(np.cov(z.T)),
                          z - np.median(z, axis=0))
    assert np.median(gate.calibration) > np.median(in_sample)  # held-out specimens look further away


def test_an_outlier_gets_the_smallest_p_and_a_reason_naming_what_is_unlike():
    rng = np.random.default_rng(3)
    values, specimens = _presses(rng, 14, 10)
    gate = fit_gate(values, NAMES, specimens, seed=0)
    blank = np.array([1.1, 2.0, 12.2, 0.6])  # noise and coherence as in training: the band and contrast named
    p = float(gate.p_values(blank[None, :])[0])
    assert p == pytest.approx(1 / 141) and p <= ALPHA
    reason = withheld_reason(gate, blank, p)
    assert "no grating: the band's peak stands 1.1x above its noise (training presses" in reason
    assert "contrast 2 DN (training" in reason and "p = 0.0071" in reason


def test_an_unmeasured_descriptor_is_like_no_training_press():
    rng = np.random.default_rng(4)
    values, specimens = _presses(rng, 5, 4)
    gate = fit_gate(values, NAMES, specimens, seed=0)
    odd = values[:1].copy()
    odd[0, 3] = math.nan
    assert gate.p_values(odd)[0] == pytest.approx(1 / 21)
    assert "coherence could not be measured" in gate.reason(odd[0], 1 / 21)


def test_one_specimen_is_not_enough_to_calibrate_over_specimens():
    values, _ = _presses(np.random.default_rng(5), 1, 8)
    with pytest.raises(ValueError, match="two specimens"):
        fit_gate(values, NAMES, ["R3"] * 8, seed=0)


def test_orientation_within_tolerance_is_quiet():
    assert orientation_reason(5.9) == "" and orientation_reason(math.nan) == ""
    assert orientation_reason(-12.04).startswith("rotated: the grating's lines lean -12.0 degrees")
