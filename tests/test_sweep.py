"""explore/sweep.py: a sweep file's name and size are bounded; a large sweep shows its estimate and needs --yes."""
from __future__ import annotations

from pathlib import Path

import pytest

from tests.commands import error_line
from tests.sweeps import big_sweep


def test_a_sweep_beyond_the_confirmation_size_shows_its_estimate_and_needs_yes(run_cli, tmp_path, monkeypatch):
    """36.11: explore started a grid of 10,100 cells (about 6 hours) with no estimate, cap or confirmation."""
    from roughsense.explore import sweep as sweep_module

    path = big_sweep(tmp_path, sweep_module.CONFIRM_CELLS + 1)
    code, _, err = run_cli("explore", path, "--out", tmp_path / "out", "--jobs", 1)
    frames = (sweep_module.CONFIRM_CELLS + 1) * 5 * 3 * 2  # cells x specimens x the default 3 forces x repetitions
    hours = frames * sweep_module.CELL_SECONDS_PER_FRAME / 3600
    assert code == 2 and error_line(err) == (
        f"roughsense: error: {path}: {sweep_module.CONFIRM_CELLS + 1} cells, about {hours:.1f} core-hours "
        f"({hours:.1f} h on 1 worker): a sweep of more than {sweep_module.CONFIRM_CELLS} cells runs only with --yes")
    assert not (tmp_path / "out").exists()
    ran = []
    monkeypatch.setattr("roughsense.explore.runner.run_sweep", lambda *a, **k: ran.append(a) or 1 / 0)
    code, _, err = run_cli("explore", path, "--out", tmp_path / "out", "--workers", 1, "--yes")
    assert ran and f"roughsense: {sweep_module.CONFIRM_CELLS + 1} cells, about {hours:.1f} core-hours" in err


def test_a_sweep_within_the_confirmation_size_needs_no_yes(tmp_path):
    from roughsense.explore.sweep import CONFIRM_CELLS, check_size_confirmed, read_sweep

    assert check_size_confirmed(read_sweep(big_sweep(tmp_path, CONFIRM_CELLS)), yes=False, workers=2) is None


def test_the_explore_docs_state_the_confirmation_size_in_force():
    from roughsense.explore.sweep import CELL_SECONDS_PER_FRAME, CONFIRM_CELLS

    text = (Path(__file__).parents[1] / "docs" / "explore.md").read_text()
    assert f"more than {CONFIRM_CELLS:,} cells" in text and CELL_SECONDS_PER_FRAME == 6.7 / 420


@pytest.mark.parametrize("name", ["a\x1b[31mred", "line\nbreak", "x" * 201])
def test_a_sweep_name_is_one_printable_line_of_bounded_length(tmp_path, name):
    """Also seen: a sweep name with control characters went raw into the page's <title>; 100,000 characters were
    accepted."""
    import json

    from roughsense.errors import ConfigError
    from roughsense.explore.sweep import MAX_NAME_CHARS, read_sweep

    path = big_sweep(tmp_path, 1)
    text = path.read_text().replace("[sweep]\n", f"[sweep]\nname = {json.dumps(name)}\n")
    path.write_text(text)
    with pytest.raises(ConfigError, match=f"at most {MAX_NAME_CHARS} printable characters"):
        read_sweep(path)
