"""explore/sweep_cells.py: a cell's forces are labelled as a sweep file writes them (1,2.5,3), in their order."""
from __future__ import annotations

from roughsense.explore.sweep_cells import forces_label


def test_forces_are_labelled_as_numbers_are_written():
    assert forces_label((1.0, 2.5, 3)) == "1,2.5,3"
    assert forces_label([0.25]) == "0.25"
