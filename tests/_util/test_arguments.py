"""_util/arguments.py: a public call's argument of the wrong type is refused in one line naming it; one str is one
path or one name, never its characters."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from roughsense._util.arguments import (
    callable_argument,
    flag_argument,
    jobs_argument,
    names_argument,
    path_argument,
    paths_argument,
)
from roughsense._util.workers import MAX_JOBS_PER_CORE, usable_cores
from roughsense.errors import ConfigError


def test_one_str_is_one_path_or_one_name_and_a_list_is_kept_as_given():
    pixels = np.zeros((2, 3))
    assert paths_argument("a.png", "images") == ["a.png"]
    assert paths_argument(Path("a.png"), "images") == [Path("a.png")]
    assert paths_argument(pixels, "images")[0] is pixels
    assert paths_argument(("a.png", Path("b.png")), "images") == ["a.png", Path("b.png")]
    assert names_argument("R3", "specimens") == ["R3"]
    assert names_argument(["R2", "R3"], "specimens") == ["R2", "R3"]
    assert path_argument(Path("m.json"), "model") == Path("m.json")


@pytest.mark.parametrize("call, value, words", [
    (paths_argument, b"a.png", "images must be image paths"),
    (paths_argument, {"a.png": 1}, "images must be image paths"),
    (paths_argument, [1.5], "images must hold image paths or pixel arrays, got 1.5"),
    (names_argument, 3, "specimens must be a name or a list of names, got 3"),
    (names_argument, ["R2", 3], "specimens must hold names (str)"),
    (path_argument, "", "model must be a path (str or os.PathLike)"),
    (path_argument, 7, "model must be a path (str or os.PathLike), got 7"),
])
def test_a_wrong_type_is_refused_naming_the_argument(call, value, words):
    name = {paths_argument: "images", names_argument: "specimens", path_argument: "model"}[call]
    with pytest.raises(ConfigError) as info:
        call(value, name)
    assert words in str(info.value) and "\n" not in str(info.value)


def test_jobs_are_a_whole_number_within_the_clis_limit():
    limit = MAX_JOBS_PER_CORE * usable_cores()
    assert jobs_argument(1) == 1 and jobs_argument(limit) == limit
    for bad in (0, limit + 1, True, 2.0, "2"):
        with pytest.raises(ConfigError, match=f"n_jobs must be a whole number from 1 to {limit}"):
            jobs_argument(bad)


def test_a_flag_is_a_bool_and_progress_a_callable_or_none():
    assert flag_argument(False, "force") is False
    with pytest.raises(ConfigError, match="force must be True or False, got 1"):
        flag_argument(1, "force")
    assert callable_argument(None) is None and callable_argument(print) is print
    with pytest.raises(ConfigError, match="progress must be None or a callable"):
        callable_argument("yes")
