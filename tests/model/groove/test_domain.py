"""The groove model's domain (model/groove/domain.py): land and groove widths on separate axes, so a grating's
mirror (land and groove swapped: the same period and duty about 1/2 read either way) is flagged."""
from __future__ import annotations

import math

import numpy as np
import pytest

from roughsense.model.groove.domain import MIN_LOG_MARGIN, domain_reasons, held_out_flags, trained_box


def _values(pairs, reps=3, noise=0.0, seed=0):
    """Rows of (log groove, log land) for (groove, land) pairs in mm, ``reps`` presses each."""
    rng = np.random.default_rng(seed)
    logs = np.log(np.repeat(np.array(pairs, dtype=float), reps, axis=0))
    return logs + noise * rng.standard_normal(logs.shape), np.repeat(np.arange(len(pairs)), reps)


def test_the_box_is_the_specimens_medians_range_with_each_axis_own_margin():
    values, codes = _values([(1.0, 1.0), (2.0, 2.0), (1.5, 0.5)], noise=0.02)
    low, high, margin = trained_box(values, codes, np.ones(len(codes), dtype=bool))
    medians = np.array([[np.median(values[codes == s, a]) for a in range(2)] for s in range(3)])
    np.testing.assert_allclose(low, medians.min(axis=0))
    np.testing.assert_allclose(high, medians.max(axis=0))
    assert (margin >= MIN_LOG_MARGIN).all()


def test_a_mirror_geometry_outside_training_is_flagged_on_its_own_axis():
    # Trained on lands wider than grooves; its mirror (groove 2, land 0.5) has the same period and 1 - duty.
    values, codes = _values([(0.5, 1.5), (1.0, 2.0), (0.6, 1.4), (0.8, 3.0)])
    box = trained_box(values, codes, np.ones(len(codes), dtype=bool))
    reasons = domain_reasons(np.log([[2.0, 0.5], [0.7, 1.6], [0.7, 5.0], [np.nan, 1.6]]), *box)
    assert reasons[0] == ("groove width 2.00 mm outside the trained 0.50-1.00 mm; "
                          "land width 0.50 mm outside the trained 1.40-3.00 mm")
    assert reasons[1] == ""
    assert reasons[2].startswith("land width 5.00 mm") and "groove" not in reasons[2]
    assert reasons[3] == "groove width unreadable in this press"


def test_held_out_flags_are_the_box_retrained_without_each_fold():
    values, codes = _values([(0.5, 0.5), (1.0, 1.0), (2.0, 2.0), (1.2, 0.9)], noise=0.01)
    specimens = np.array([f"s{c}" for c in codes])
    flags = held_out_flags(values, specimens, specimens)
    for s in np.unique(specimens):
        held = specimens == s
        box = trained_box(values, codes, ~held)
        assert list(flags[held]) == [bool(r) for r in domain_reasons(values[held], *box)]
    assert flags[specimens == "s0"].all() and flags[specimens == "s2"].all()  # the ends: outside when left out
    assert not flags[specimens == "s3"].any()  # inside the others' box on both axes


@pytest.mark.parametrize("noise", [0.01, 0.05])
def test_presses_of_a_trained_geometry_are_not_flagged_for_their_noise(noise):
    values, codes = _values([(0.5, 0.5), (1.0, 2.0), (2.0, 1.0)], reps=30, noise=noise, seed=3)
    box = trained_box(values, codes, np.ones(len(codes), dtype=bool))
    flagged = np.mean([bool(r) for r in domain_reasons(values, *box)])
    assert flagged < 0.02
    assert box[2] == pytest.approx(np.maximum(MIN_LOG_MARGIN, 3 * 1.4826 * np.median(
        np.abs(values - np.array([np.median(values[codes == c], axis=0) for c in codes])), axis=0)))
    assert math.isfinite(box[0][0])


def test_a_wild_width_is_named_in_a_short_reason():
    values, codes = _values([(1.0, 1.0), (2.0, 2.0)])
    box = trained_box(values, codes, np.ones(len(codes), dtype=bool))
    reason = domain_reasons(np.log([[1e300, 1e-300]]), *box)[0]
    assert reason == ("groove width 1e+300 mm outside the trained 1.00-2.00 mm; "
                      "land width 1e-300 mm outside the trained 1.00-2.00 mm")
