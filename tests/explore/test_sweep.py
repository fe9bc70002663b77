"""explore/sweep.py: a sweep file's name and size are bounded; a large sweep shows its estimate and needs --yes."""
from __future__ import annotations

from pathlib import Path

import pytest

from tests.commands import error_line, one_error
from tests.sweeps import SWEEP, big_sweep


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
    code, _, err = run_cli("explore", path, "--out", tmp_path / "out", "--jobs", 1, "--yes")
    assert ran and f"roughsense: {sweep_module.CONFIRM_CELLS + 1} cells, about {hours:.1f} core-hours" in err


def test_a_sweep_within_the_confirmation_size_needs_no_yes(tmp_path):
    from roughsense.explore.sweep import CONFIRM_CELLS, check_size_confirmed, read_sweep

    assert check_size_confirmed(read_sweep(big_sweep(tmp_path, CONFIRM_CELLS)), yes=False, workers=2) is None


def test_the_explore_docs_state_the_confirmation_size_in_force():
    from roughsense.explore.sweep import CELL_SECONDS_PER_FRAME, CONFIRM_CELLS

    text = (Path(__file__).parents[2] / "docs" / "explore.md").read_text()
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


def test_a_sweep_of_few_but_long_cells_needs_yes_too(tmp_path):
    """36.11: the confirmation counted cells only, and a cell may render 20,000 frames: 30 cells of 19,500 frames
    (about 2.6 core-hours, more than 1000 paper-sized cells) started with no estimate."""
    from roughsense.errors import ConfigError
    from roughsense.explore.sweep import CELL_SECONDS_PER_FRAME, CONFIRM_CELLS, check_size_confirmed, read_sweep

    path = tmp_path / "sweep.toml"
    path.write_text(f"[sweep]\nseeds = {list(range(30))}\nrepetitions = 1300\n"
                    "specimens = ['R2', 'R3', 'R4', 'C3', 'rect:1.5']\nimage_size_px = [480, 160]\n[axes]\npad = ['smooth']\n")
    sweep = read_sweep(path)
    hours = 30 * 5 * 3 * 1300 * CELL_SECONDS_PER_FRAME / 3600
    assert len(sweep.cells) == 30 and hours > CONFIRM_CELLS * 420 * CELL_SECONDS_PER_FRAME / 3600
    with pytest.raises(ConfigError) as info:
        check_size_confirmed(sweep, yes=False, workers=2)
    assert str(info.value) == (f"{path}: 30 cells, about {hours:.1f} core-hours ({hours / 2:.1f} h on 2 workers): a sweep "
                               "of more than 1.9 core-hours (as long as 1000 paper-sized cells) runs only with --yes")
    estimate = f"30 cells, about {hours:.1f} core-hours ({hours / 2:.1f} h on 2 workers)"
    assert check_size_confirmed(sweep, yes=True, workers=2) == estimate


def test_a_sweep_file_is_held_to_the_same_rule(run_cli, tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('[sweep]\nname = """x \\""" max_components = 1 """\n' + SWEEP.format(seed=0, spec='"R4"')
                     .replace("[sweep]\n", "").replace("max_components = 4", "max_components = 0x4") + '# """\n')
    line = one_error(run_cli, "explore", sweep, "--out", tmp_path / "x")
    assert "'0x4' is not a number as roughsense reads one" in line


def test_a_sweep_names_the_twins_specimen_sets_whole_or_in_a_list(tmp_path):
    """``specimens = "paper+grooves"`` (sim/specimens.SPECIMEN_SETS, the one table) and a set inside a list."""
    from roughsense.explore.sweep import read_sweep
    from roughsense.sim.specimens import SPECIMEN_SETS

    path = tmp_path / "sweep.toml"
    path.write_text('[sweep]\nseeds = [0]\nrepetitions = 2\nspecimens = "Paper+Grooves"\n[axes]\npad = ["smooth"]\n')
    (cell,) = read_sweep(path).cells
    assert cell.specimens == SPECIMEN_SETS["paper+grooves"] and cell.specimens_label == "paper+grooves"
    path.write_text('[sweep]\nseeds = [0]\nrepetitions = 2\nspecimens = ["circular", "rect:3:1:0.9"]\n'
                    '[axes]\npad = ["smooth"]\n')
    (cell,) = read_sweep(path).cells
    assert cell.specimens == (*SPECIMEN_SETS["circular"], "rect:3:1:0.9")
