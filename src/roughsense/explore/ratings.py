"""The one place where a sweep asks the twin for its panel's ratings (the paper's values, or physics-based).

Physics-based ratings are a keyword of :func:`roughsense.sim.panel.simulate_panel` in builds that have them;
everything in ``explore`` goes through this adapter, so that keyword is spelled once.
"""
from __future__ import annotations

import inspect

import pandas as pd

from ..errors import ConfigError
from ..sim.panel import REFERENCE, simulate_panel
from ..sim.specimens import Specimen

PANEL_SPAWN_KEY = (4,)  # the study path's key for the panel: a cell draws the same ratings as `simulate` does


def physics_available() -> bool:
    return "ratings_from" in inspect.signature(simulate_panel).parameters


def config_options(ratings_from: str) -> dict:
    """The ``SimulationConfig`` keyword for the ratings source, in builds whose config has one."""
    from dataclasses import fields

    from ..sim.simulate import SimulationConfig

    return {"ratings_from": ratings_from} if "ratings_from" in {f.name for f in fields(SimulationConfig)} else {}


def check_ratings_source(ratings_from: str) -> None:
    if ratings_from != "paper" and not physics_available():
        raise ConfigError("physics ratings are not available in this build")


def panel_ratings(specimens: list[Specimen], seed: int, *, ratings_from: str = "paper", participants: int = 10,
                  sessions: int = 3) -> pd.DataFrame:
    """ratings.csv rows of the simulated panel for these specimens, drawn from ``seed``."""
    check_ratings_source(ratings_from)
    extra = {"ratings_from": ratings_from} if physics_available() else {}
    return simulate_panel(list(specimens), seed, spawn_key=PANEL_SPAWN_KEY, participants=participants,
                          sessions=sessions, reference=REFERENCE, **extra)
