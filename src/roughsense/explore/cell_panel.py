"""The one place where a sweep asks the twin for its panel's ratings (the paper's values, or the simulated finger's).

A cell draws them with the study path's own key, so a cell and ``roughsense simulate`` of the same design rate
the specimens identically.
"""
from __future__ import annotations

import pandas as pd

from .. import defaults
from ..io.ratings_file import validate_ratings
from ..paper import PAPER_PARTICIPANTS, PAPER_SESSIONS, REFERENCE_SPECIMEN
from ..sim.panel import PANEL_SPAWN_KEY, simulate_panel
from ..sim.specimens import Specimen


def panel_ratings(specimens: list[Specimen], seed: int, *, ratings_from: str = defaults.RATINGS_FROM,
                  participants: int = PAPER_PARTICIPANTS, sessions: int = PAPER_SESSIONS) -> pd.DataFrame:
    """ratings.csv rows of the simulated panel for these specimens, drawn from ``seed``, checked as a file's are."""
    panel = simulate_panel(list(specimens), seed, spawn_key=PANEL_SPAWN_KEY, participants=participants,
                           sessions=sessions, reference=REFERENCE_SPECIMEN, ratings_from=ratings_from)
    return validate_ratings(panel, reference=REFERENCE_SPECIMEN)
