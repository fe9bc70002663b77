"""analysis/evidence.py: "a surface you never trained on" names the surfaces the study's evidence covers, read from
its own rated specimens (issue 46: the paper's rectangles are all half land, half groove, and the first screen
promised any new surface)."""
from __future__ import annotations

import pandas as pd

from roughsense import paper
from roughsense.analysis.evidence import evidence_words


def _paper_specimens() -> pd.DataFrame:
    """The paper's 14 as the twin writes specimens.csv: rectangles' land (ridge) = groove = period / 2."""
    rows = [{"specimen": name, "shape": "rectangular" if name[0] == "R" else "circular", "wavelength_mm": float(name[1:]),
             "ridge_width_mm": float(name[1:]) / 2 if name[0] == "R" else float("nan")} for name in paper.PAPER_SPECIMENS]
    return pd.DataFrame(rows)


def test_the_papers_fourteen_cover_half_land_rectangles_and_circles_of_their_periods_only():
    specimens = _paper_specimens()
    words = evidence_words(specimens, specimens["specimen"])
    assert words == ("the study's 14 specimens, rectangular and circular gratings of 7 periods from 2 to 5 mm (the "
                     "rectangles half land, half groove), not other land and groove widths, shapes or periods")


def test_rectangles_of_other_lands_are_said_as_their_range_and_unrated_specimens_are_no_evidence():
    grooves = pd.DataFrame({"specimen": ["rect:3:1:0.9", "rect:3:1:2.1", "rect:9:1:4.5"],
                            "shape": ["rectangular"] * 3, "wavelength_mm": [3.0, 3.0, 9.0],
                            "ridge_width_mm": [0.9, 2.1, 4.5]})
    specimens = pd.concat([_paper_specimens(), grooves], ignore_index=True)
    rated = [*paper.PAPER_SPECIMENS, "rect:3:1:0.9", "rect:3:1:2.1"]  # rect:9:1:4.5 never rated: no evidence
    words = evidence_words(specimens, rated)
    assert words == ("the study's 16 specimens, rectangular and circular gratings of 7 periods from 2 to 5 mm (the "
                     "rectangles' land 30%-70% of the period), not other shapes or periods")


def test_a_study_that_records_no_land_says_so_and_one_of_nothing_says_nothing():
    specimens = _paper_specimens().drop(columns="ridge_width_mm").iloc[:3]
    words = evidence_words(specimens, specimens["specimen"])
    assert words == ("the study's 3 specimens, rectangular gratings of 3 periods from 2 to 3 mm (the rectangles' land "
                     "and groove widths not recorded), not other shapes or periods")
    assert evidence_words(specimens, []) == ""


def test_the_readmes_words_on_the_built_in_study_are_the_evidence_its_specimens_give():
    from pathlib import Path

    readme = " ".join((Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8").split())
    specimens = _paper_specimens()
    words = evidence_words(specimens, specimens["specimen"])
    quoted = "rectangular and circular gratings of 7 periods from 2 to 5 mm (the rectangles half land, half groove), not " \
        "other land and groove widths"
    assert quoted in readme and quoted in words
