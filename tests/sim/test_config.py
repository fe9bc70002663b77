"""sim/config.py: a simulated study's definition, checked whole before anything is written; a smaller frame keeps
the scale."""
from __future__ import annotations

import pytest

from roughsense.errors import ConfigError
from roughsense.sim.config import SimulationConfig, ridge_periods, with_image_size


def test_a_smaller_frame_keeps_everything_else():
    config = SimulationConfig(pads=("smooth",), specimens=("R2", "R3"), seed=3)
    small = with_image_size(config, 400, 30)
    assert (small.camera.width_px, small.camera.height_px) == (400, 30)
    assert small.camera.px_per_mm == config.camera.px_per_mm and small.specimens == config.specimens
    assert small.seed == 3 and config.camera.width_px != 400  # the original is left as it was


@pytest.mark.parametrize("change, message", [
    ({"pads": ()}, "--pads: give at least one pad"),
    ({"specimens": ("R2", "R3", "R2")}, "specimen 'R2' is listed twice"),
    ({"participants": 1000, "sessions": 3}, "above the simulated panel's limit of 2000"),
])
def test_a_definition_the_twin_cannot_simulate_is_refused_before_any_work(change, message):
    config = SimulationConfig(**{"pads": ("smooth",), "specimens": ("R2", "R3"), **change})
    with pytest.raises(ConfigError, match=message):
        config.validate()


def test_only_a_pad_with_ridges_has_a_ridge_period():
    pads, _ = SimulationConfig(pads=("smooth", "fingerprint"), fingerprint_period_mm=0.5).validate()
    assert ridge_periods(pads) == {"fingerprint": 0.5}


def test_a_named_set_is_expanded_where_the_specimens_are_parsed():
    _, specimens = SimulationConfig(pads=("smooth",), specimens=("paper+grooves",)).validate()
    names = [s.name for s in specimens]
    assert len(names) == 22 and names[:2] == ["R2", "R2.5"] and names[-1] == "rect_5_1_3.5"
    with pytest.raises(ConfigError, match="'R2' is listed twice"):
        SimulationConfig(pads=("smooth",), specimens=("paper", "R2")).validate()
