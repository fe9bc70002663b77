"""cli/image_flags.py: predict's ``--images-XN`` slots: the images after each flag go to its force, spelled as every
number roughsense reads; anything else that looks like an option is refused, not taken for a file."""
from __future__ import annotations

from pathlib import Path

import pytest

from roughsense.cli.image_flags import split_image_flags
from roughsense.errors import ConfigError


def test_images_go_to_the_slot_before_them():
    positional, slots = split_image_flags(["a.png", "--images-1n", "b.png", "c.png", "--images-2.50N=d.png", "e.png"])
    assert positional == [Path("a.png")]
    assert slots == {"1N": [Path("b.png"), Path("c.png")], "2.5N": [Path("d.png"), Path("e.png")]}


@pytest.mark.parametrize("tokens, message", [
    (["--images-xn", "a.png"], "--images-xn: expected a force like --images-1n or --images-2.5n"),
    (["--images-2", "a.png"], "--images-2: expected a force like --images-1n or --images-2.5n"),
    (["a.png", "--same-surfce"], "no such option: --same-surfce"),
])
def test_a_slot_or_option_it_cannot_read_is_refused(tokens, message):
    with pytest.raises(ConfigError, match=f"^{message}$"):
        split_image_flags(tokens)
