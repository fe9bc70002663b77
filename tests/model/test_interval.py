"""model/interval.py: the 90 % interval from leave-one-specimen-out residuals, against the conformal rank and
coverage on exchangeable errors."""
from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense.model.interval import PredictionInterval, conformal_halfwidth, held_out_coverage


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 60), level=st.sampled_from([0.8, 0.9, 0.95]), seed=st.integers(0, 2**16))
def test_the_conformal_halfwidth_is_the_ceil_n_plus_one_level_th_residual(n, level, seed):
    residuals = np.random.default_rng(seed).exponential(size=n)
    rank = math.ceil((n + 1) * level)
    expected = np.sort(residuals)[rank - 1] if rank <= n else math.inf
    assert conformal_halfwidth(residuals, level) == expected


def test_intervals_cover_held_out_specimens_at_their_level_on_exchangeable_errors():
    """Log errors drawn alike for every specimen: each held-out specimen's interval, from the others' residuals,
    covers ~90 % of trials and of specimens (the split-conformal guarantee, checked rather than trusted)."""
    rng = np.random.default_rng(0)
    specimens = np.repeat([f"S{i}" for i in range(400)], 5)
    target = np.exp(rng.normal(size=specimens.size).repeat(1))
    prediction = target * np.exp(rng.normal(0, 0.3, size=specimens.size))
    trials, surfaces = held_out_coverage(prediction, target, specimens, floor=1e-9)
    assert 0.87 <= trials <= 0.93 and 0.86 <= surfaces <= 0.94
    interval = PredictionInterval.from_cv(prediction, target, specimens, floor=1e-9)
    low, high = interval.trial_bounds(prediction)
    assert np.all(low > 0) and np.all(low < prediction) and np.all(high > prediction)
    assert 0.87 <= np.mean((target >= low) & (target <= high)) <= 0.93


def test_an_interval_too_few_residuals_cannot_give_is_null_in_the_file():
    interval = PredictionInterval.from_cv([1.0, 1.2, 0.9], [1.1, 1.0, 1.0], ["a", "b", "c"], floor=0.1)
    assert not interval.finite and interval.to_dict()["surface_log_halfwidth"] is None
