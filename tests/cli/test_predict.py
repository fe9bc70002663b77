"""cli/predict.py's lines about a model (issue 44: right after ``fit``, predict advised "refit it with roughsense fit"
when the real cause of a missing interval was too few specimens, 4 < 9)."""
from __future__ import annotations

import pytest

from roughsense.cli.predict import no_interval_line
from roughsense.model.interval import conformal_halfwidth
from tests.commands import LEGACY_MODEL, error_line, grating_png


def test_too_few_specimens_is_named_as_the_cause_and_refitting_is_not_advised():
    line = no_interval_line({"specimens": ["R2", "R3", "C4", "R4"], "interval": {"trial_log_halfwidth": None}})
    assert "fitted on 4 specimens, too few for a 90 % interval (at least 9)" in line
    assert "refit" not in line and "more specimens" in line


def test_nine_is_the_fewest_residuals_a_90_percent_interval_takes():
    """The number the line quotes, against the conformal rank it comes from (independent of the line's code)."""
    assert conformal_halfwidth(range(8)) == float("inf") and conformal_halfwidth(range(9)) < float("inf")


def test_a_design_too_small_to_be_judged_left_out_is_that_cause():
    line = no_interval_line({"specimens": ["R2", "R3"], "unseen": {"failure": "could not be judged"}})
    assert "fitted on 2 specimens, too few" in line and "refit" not in line


@pytest.mark.parametrize("training", [{"specimens": ["R2"] * 12}, {}, None])
def test_only_a_file_written_before_intervals_is_told_to_refit(training):
    assert no_interval_line(training).endswith("written before intervals; refit it with roughsense fit")


@pytest.mark.parametrize("columns", [60, 80, 132])
def test_tables_fit_the_terminal_without_a_continuation(monkeypatch, columns):
    """pandas' to_string broke a wide table into blocks ending in ``\\`` at 80 columns; every line now fits the
    terminal's width ($COLUMNS off a terminal) and every cell is still there, folded within its column."""
    import pandas as pd

    from roughsense.cli._common import terminal_table
    from roughsense.cli.predict import _terminal_table

    monkeypatch.setenv("COLUMNS", str(columns))
    frame = pd.DataFrame({
        "image": [f"some/long/folder/name/press_{i:03d}_of_the_reference_surface.png" for i in range(3)],
        "roughness_rel_R3": ["1.25", "0.466", "12.5"], "pi90_low": ["0.9", "0.3", "10"],
        "pi90_high": ["1.7", "0.7", "15"], "extrapolates": ["false", "true", "false"],
        "outside": ["", "spectrum unusual within the model", ""], "pad": ["smooth"] * 3,
    })
    for text in (terminal_table(frame.drop(columns="outside")), _terminal_table(frame, from_study=False)):
        lines = text.splitlines()
        assert all(len(line) <= columns for line in lines), text
        assert not any(line.rstrip().endswith("\\") for line in lines)
        for value in ("1.25", "0.466", "12.5", "true"):
            assert value in text
    wide = terminal_table(frame.drop(columns="outside"))
    if columns >= 132:
        assert frame["image"][2] in wide  # room enough: nothing folded


def test_same_surface_refuses_one_image_given_twice(run_cli, tmp_path):
    """Also seen: ``--same-surface`` with one image twice counted 2 trials (a narrower surface interval)."""
    image = grating_png(tmp_path / "a.png")
    (tmp_path / "link.png").symlink_to(image)
    code, _, err = run_cli("predict", LEGACY_MODEL, image, tmp_path / "link.png", "--same-surface")
    assert code == 2 and error_line(err) == (f"roughsense: error: --same-surface: {tmp_path / 'link.png'} is the same "
                                             f"file as {image}; give each press once")
