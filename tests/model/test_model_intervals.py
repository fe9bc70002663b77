"""``model/model_intervals.py``: the interval each prediction gets from its model file, against the plain jackknife's
definition (a log half-width w gives [r e^-w, r e^w]) and the file's own fields."""
from __future__ import annotations

import math

import numpy as np
import pytest

from roughsense.model.model_intervals import PLAIN_METHOD, interval_bounds, model_interval, plain_fallback_line

ROUGHNESS = np.array([0.5, 1.0, 2.0])
X = np.zeros((3, 4))


class Model:
    """A loaded model as the interval code reads it: its training record and path (no jackknife+ kept)."""

    path = None

    def __init__(self, interval=None):
        self.training = {} if interval is None else {"interval": interval}


def plain(trial=0.2, surface=0.1, alone=0.3) -> Model:
    return Model({"level": 0.9, "trial_log_halfwidth": trial, "surface_log_halfwidth": surface,
                  "alone_log_halfwidth": alone})


def test_a_press_read_alone_gets_the_alone_width_and_one_read_with_its_surface_the_trial_width():
    (low, high, method), surface = interval_bounds(plain(), X, ROUGHNESS)
    np.testing.assert_allclose(low, ROUGHNESS * math.exp(-0.3), rtol=1e-15)
    np.testing.assert_allclose(high, ROUGHNESS * math.exp(0.3), rtol=1e-15)
    assert method == [PLAIN_METHOD] * 3 and surface is None
    surfaces = np.array(["a", "a", "b"])
    means = np.array([0.75, 0.75, 2.0])
    (low, high, _), (s_low, s_high, s_method) = interval_bounds(plain(), X, ROUGHNESS, surfaces, means)
    np.testing.assert_allclose(high, ROUGHNESS * math.exp(0.2), rtol=1e-15)
    np.testing.assert_allclose([s_low, s_high], [means * math.exp(-0.1), means * math.exp(0.1)], rtol=1e-15)
    assert s_method == [PLAIN_METHOD] * 3


def test_an_unknown_alone_width_falls_back_to_the_trial_width():
    (low, _, _), _ = interval_bounds(plain(alone=None), X, ROUGHNESS)
    np.testing.assert_allclose(low, ROUGHNESS * math.exp(-0.2), rtol=1e-15)


@pytest.mark.parametrize("model", [Model(), plain(trial=None)], ids=["no interval", "too few residuals"])
def test_without_an_interval_every_bound_is_nan_and_no_method_is_named(model):
    assert model_interval(model) is None
    (low, high, method), (s_low, s_high, s_method) = interval_bounds(model, X, ROUGHNESS, np.array(["a"] * 3),
                                                                     ROUGHNESS)
    assert np.isnan([low, high, s_low, s_high]).all() and method is None and s_method is None
    assert plain_fallback_line(model) == ""


def test_a_surface_without_a_known_width_has_no_bound_but_its_presses_do():
    (low, _, _), (s_low, _, s_method) = interval_bounds(plain(surface=None), X, ROUGHNESS, np.array(["a"] * 3),
                                                        ROUGHNESS)
    assert np.isfinite(low).all() and np.isnan(s_low).all() and s_method is None


def test_a_file_with_the_plain_jackknife_alone_says_so_once():
    assert "keeps no leave-one-specimen-out fold models" in plain_fallback_line(plain())
