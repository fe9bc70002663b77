"""``model/trials.py``: what predict is given, grouped into the trials its model reads (``gather_trials``)."""
from __future__ import annotations

import pytest

from roughsense.errors import ConfigError, InputError
from roughsense.model.trials import Trials, gather_trials, refuse_repeats


class Model:
    """A loaded model as the grouping reads it: force conditions, training record and path."""

    path = None

    def __init__(self, *conditions: str, pad: str = "smooth"):
        self.conditions = list(conditions)
        self.training = {"pad": pad}


def test_bare_images_are_one_trial_each_with_the_models_pad_and_condition(tmp_path):
    trials = gather_trials(Model("2N"), ["a_2N.png", "b_2N.png"])
    assert trials == Trials([("a_2N.png",), ("b_2N.png",)], "smooth", "2N")
    assert trials.images == ["a_2N.png", "b_2N.png"] and trials.surfaces is None


def test_one_flag_per_force_makes_trials_of_the_ith_images_read_force_after_force(tmp_path):
    by_force = {"2N": ["a_2N.png", "b_2N.png"], "1N": ["a_1N.png", "b_1N.png"]}
    trials = gather_trials(Model("1N", "2N", pad="fingerprint"), images_by_force=by_force, same_surface=True)
    assert trials.groups == [("a_1N.png", "a_2N.png"), ("b_1N.png", "b_2N.png")]
    assert trials.images == ["a_1N.png", "a_2N.png", "b_1N.png", "b_2N.png"]  # the order scoring reads
    assert (trials.pad, trials.condition, trials.surfaces) == ("fingerprint", "combined", ["surface"] * 2)


def test_a_press_given_twice_under_two_names_is_refused_for_a_surface(tmp_path):
    image = tmp_path / "a_2N.png"
    image.write_bytes(b"x")
    (tmp_path / "link_2N.png").symlink_to(image)
    with pytest.raises(ConfigError, match="link_2N.png is the same file as"):
        gather_trials(Model("2N"), [image, tmp_path / "link_2N.png"], same_surface=True)
    refuse_repeats([image, tmp_path / "missing.png"])  # a file that does not exist is left to the reading


def test_a_name_that_says_another_force_than_its_slot_is_refused():
    with pytest.raises(InputError, match="fills the 2N slot but its name says 1N"):
        gather_trials(Model("2N"), ["a_1N.png"])
