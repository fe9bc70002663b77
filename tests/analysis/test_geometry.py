"""Each specimen's land/groove geometry (analysis/geometry.py), read from specimens.csv's columns as a rig's user
writes them, against fractions computed by hand."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from roughsense.analysis.geometry import PAPER_GEOMETRY, land_fractions, land_label, specimen_geometries


def _table(rows):
    return pd.DataFrame(rows, columns=["specimen", "shape", "wavelength_mm", "ridge_width_mm", "groove_width_mm"])


def test_land_fraction_from_the_land_else_from_the_groove():
    table = _table([["a", "rectangular", 4.0, 1.2, np.nan], ["b", "rectangular", 4.0, np.nan, 1.2],
                    ["c", "rectangular", 4.0, 4.0, np.nan], ["d", "rectangular", 4.0, "wide", np.nan],
                    ["e", "rectangular", 5.0, 1.5, 3.5]])
    fractions = land_fractions(table)
    assert fractions.iloc[0] == pytest.approx(0.3) and fractions.iloc[1] == pytest.approx(0.7)
    assert np.isnan(fractions.iloc[2]) and np.isnan(fractions.iloc[3])  # a land as wide as the period; not a number
    assert fractions.iloc[4] == pytest.approx(0.3)
    assert land_label(1 / 3) == "land 0.3" and PAPER_GEOMETRY == "land 0.5"


def test_the_paper_plus_grooves_table_has_three_rectangular_geometries_and_circles_of_their_own():
    from roughsense.sim.specimens import SPECIMEN_SETS, parse_specimen

    table = pd.DataFrame([parse_specimen(s).table_row() for s in SPECIMEN_SETS["paper+grooves"]])
    geometries, note = specimen_geometries(table)
    assert note == ""
    assert geometries["R4"] == "land 0.5" and geometries["C4"] == "circular"
    assert geometries["rect_4_1_1.2"] == "land 0.3" and geometries["rect_5_1_3.5"] == "land 0.7"
    assert set(geometries.values()) == {"land 0.3", "land 0.5", "land 0.7", "circular"}


def test_one_rectangular_geometry_or_none_known_is_said_not_guessed():
    from roughsense.sim.specimens import PRESETS

    paper = pd.DataFrame([s.table_row() for s in PRESETS.values()])
    geometries, note = specimen_geometries(paper)
    assert geometries == {} and note == "every rectangle here is land 0.5 of its period (roughsense protocol recommends others)"
    bare = paper[["specimen", "shape", "wavelength_mm"]]  # a real study's specimens.csv need not give widths
    geometries, note = specimen_geometries(bare)
    assert (geometries, note) == ({}, "no land width (ridge_width_mm) in specimens.csv for R2 and 6 more")
    circles = paper[paper["shape"] == "circular"]
    assert specimen_geometries(circles) == ({}, "no rectangular gratings here")


def test_a_land_and_groove_that_do_not_make_the_period_are_refused_by_name():
    table = _table([["a", "rectangular", 4.0, 1.2, 2.8], ["b", "rectangular", 4.0, 1.0, 1.0],
                    ["c", "rectangular", 3.0, 0.9, 2.13]])  # c: 1 % off, a printing tolerance
    geometries, note = specimen_geometries(table)
    assert (geometries, note) == ({}, "in specimens.csv, ridge_width_mm + groove_width_mm is not wavelength_mm for b")
    geometries, note = specimen_geometries(table[table.specimen != "b"])
    assert geometries == {} and note.startswith("every rectangle here is land 0.3 of its period")
