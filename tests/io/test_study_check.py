"""io/study_check.py: `check`'s verdict on a folder: every problem collected (none for a good folder) and the
folder's size counted as its tables say."""
from __future__ import annotations

import pandas as pd

from roughsense.io.study_check import check_study


def test_a_good_folder_has_no_problems_and_counts_its_tables(tiny_smooth):
    result = check_study(tiny_smooth)
    manifest = pd.read_csv(tiny_smooth / "manifest.csv")
    ratings = pd.read_csv(tiny_smooth / "ratings.csv")
    specimens = pd.read_csv(tiny_smooth / "specimens.csv")
    assert result.ok and len(result.problems) == 0
    assert (result.n_images, result.n_specimens, result.n_ratings) == (len(manifest), len(specimens), len(ratings))
    assert result.summary() == f"study OK: {len(manifest)} images, {len(specimens)} specimens, {len(ratings)} ratings"


def test_every_problem_is_collected_and_the_failure_line_counts_them(tiny_copy):
    lines = (tiny_copy / "manifest.csv").read_text().splitlines()
    lines[1] += ",extra"
    lines[2] += ",extra"
    (tiny_copy / "manifest.csv").write_text("\n".join(lines) + "\n")
    (tiny_copy / "ratings.csv").unlink()
    result = check_study(tiny_copy)
    assert not result.ok and len(result.problems) == 2 and result.n_ratings is None
    assert result.failure() == f"2 problems (listed above); fix them and run `roughsense check {tiny_copy}` again"
