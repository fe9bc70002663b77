"""The 90 % interval a prediction gets from its model file, chosen once per batch: the jackknife+ over specimens
(``model/jackknife_file.py``) where the file keeps one that bounds, else the plain jackknife (``model/interval.py``),
else none.

A surface's (and a press read alone) is the jackknife+'s; a press read with its surface's others gets the plain
jackknife (the peak law reads it less surely alone: its own calibration).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .modelfile import FittedModel


#: How predict names the plain jackknife's interval (model/interval.py), beside the jackknife+'s.
PLAIN_METHOD = "jackknife (no coverage guarantee)"


def interval_bounds(loaded: FittedModel, X: np.ndarray, roughness: np.ndarray, surfaces=None, surface=None,
                    contact: dict | None = None):
    """Each trial's 90 % bounds and method and, given ``surfaces`` (and ``surface``, each trial's surface's mean),
    its surface's: ``((low, high, method), (s_low, s_high, s_method) or None)``, NaN and None without an interval.

    A press read alone is a surface of one press, so it gets the jackknife+ of one-press surfaces where the file
    keeps one; a press read with its surface's others gets the plain jackknife (the peak law reads it less surely
    alone: its own calibration). A surface gets the jackknife+ with the residuals of surfaces read from as many
    presses as it (model/jackknife_file.py), else (an older file) the plain jackknife. ``contact``: the keyword a
    family that reads the contact takes (``scoring.contact_inputs``), passed to its folds.
    """
    from .jackknife_file import deployed_jackknife

    plain = model_interval(loaded)
    jackknife = deployed_jackknife(loaded)  # a malformed entry is refused in one line naming the field
    bounded = jackknife is not None and jackknife.bounded
    if surfaces is None and bounded:
        trial = jackknife.intervals(X, **(contact or {}))
    elif plain is None:
        trial = (np.full(roughness.shape, np.nan), np.full(roughness.shape, np.nan), None)
    else:
        trial = (*plain.trial_bounds(roughness, read_alone=surfaces is None), [PLAIN_METHOD] * roughness.size)
    if surfaces is None:
        return trial, None
    if bounded:
        return trial, jackknife.intervals(X, surfaces, **(contact or {}))
    if plain is None or not math.isfinite(plain.surface_log_halfwidth):
        return trial, (np.full(surface.shape, np.nan), np.full(surface.shape, np.nan), None)
    return trial, (*plain.surface_bounds(surface), [PLAIN_METHOD] * surface.size)


def model_interval(loaded: FittedModel):
    """The model file's prediction interval, or None (a file written before intervals, or too few specimens for a
    trial's). Its fields were checked when the file was loaded (``interval.SCHEMA``, model/schema.py): null is too
    few residuals for the level (no bound; ``alone_log_halfwidth`` absent or null: not known)."""
    from .interval import PredictionInterval

    stored = loaded.training.get("interval") if isinstance(loaded.training, dict) else None
    if stored is None:
        return None

    def width(name: str, missing: float) -> float:
        value = stored.get(name)
        return missing if value is None else float(value)

    interval = PredictionInterval(width("trial_log_halfwidth", math.inf), width("surface_log_halfwidth", math.inf),
                                  float(stored["level"]),
                                  alone_log_halfwidth=width("alone_log_halfwidth", math.nan))
    return interval if math.isfinite(interval.trial_log_halfwidth) else None


def plain_fallback_line(loaded: FittedModel) -> str:
    """One line when a file's intervals fall back to the plain jackknife: written before the jackknife+ was kept,
    or from too few specimens for it (9 at 90 %). Said, never failed."""
    from .jackknife_file import deployed_jackknife

    jackknife = deployed_jackknife(loaded)
    if model_interval(loaded) is None or (jackknife is not None and jackknife.bounded):
        return ""
    if jackknife is not None:
        return (f"the {jackknife.name} needs at least {jackknife.fewest_specimens} training specimens for a 90 % "
                "interval: these intervals are "
                f"the plain {PLAIN_METHOD}, where it has one")
    return ("this model file keeps no leave-one-specimen-out fold models (written before they were kept): its "
            f"intervals are the plain {PLAIN_METHOD}; refit it with roughsense fit for the jackknife+ over specimens")
