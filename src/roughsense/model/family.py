"""What a model family's numerics must offer, so the analysis can loop over families instead of naming them.

A family engine (:class:`FamilyEngine`) takes arrays and gives arrays: its cross-validation under the study's
folds, its CV on shuffled targets (the permutation control), the applicability flags its held-out fits would have
raised, and the optional extras only some families can afford (a nested interval check, stricter schemes, surfaces
read from a few presses, the jackknife+ a model file keeps). Frames, judging and messages naming a pad or condition
stay in the analysis layer. The registry (:mod:`.families`) lists the engines in table order.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import ClassVar, Protocol

import numpy as np
import pandas as pd

#: The keywords a family's settings pass on to the peak law's kernels, in the order they always had.
SETTING_KEYS = ("freq_per_mm", "n_blocks", "pad_ridge_period_mm", "surfaces")


@dataclass(frozen=True, eq=False)
class FoldSettings:
    """What a pad x condition fixes for every family's folds: the frequency grid, how many spectra a row holds,
    the pad's ridge period (left out of a peak search) and each row's surface (its specimen: presses of one surface
    share where its peak is read). A PLS fit needs none of it; a peak readout needs all of it."""

    freq_per_mm: np.ndarray
    n_blocks: int = 1
    pad_ridge_period_mm: float | None = None
    surfaces: np.ndarray | None = None

    @classmethod
    def of(cls, settings: FoldSettings | Mapping | None) -> FoldSettings | None:
        """The settings from the keyword dict the analysis has always passed (``law_settings``), or as given."""
        if settings is None or isinstance(settings, FoldSettings):
            return settings
        return cls(**{key: settings[key] for key in SETTING_KEYS if key in settings})

    def law(self) -> dict:
        """The peak law's keywords (peak_law_cv, held_out_flags, law_fold_models ...), in their usual order."""
        return {key: getattr(self, key) for key in SETTING_KEYS}


@dataclass(frozen=True)
class FoldResult:
    """One family cross-validated under one set of folds.

    ``curve``: index 0 the training mean's RMSE under the same folds, then the family's own (PLS: one per component
    count; a family that chooses nothing: one). ``best``/``one_se``: the index ``curve`` is read at (the chosen
    count, or 1). ``per_specimen``: a nested choice per held-out specimen (PLS under LOSO), else empty.
    """

    out_of_fold: np.ndarray
    curve: np.ndarray
    best: int = 1
    one_se: int = 1
    per_specimen: dict[str, int] = field(default_factory=dict)


def cv_rmse(prediction: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Root mean squared error over the last axis: one per target column of a batch of shufflings."""
    return np.sqrt(np.mean((prediction - target) ** 2, axis=-1))


class FamilyEngine(Protocol):
    """The numeric side of a registered family (:func:`roughsense.model.families.engines`); NumPy in, NumPy out.

    The optional capabilities default to "none" here, so a family that subclasses this protocol states only
    what it has; the analysis skips a table's rows where a family returns None.
    """

    #: The registry's name of the family (:class:`roughsense.model.families.Family`).
    name: ClassVar[str]
    #: Whether a surface's presses are read together (a press alone reads differently): the model file's interval
    #: then also covers a press read without its surface.
    reads_surfaces: ClassVar[bool] = False

    def cross_validate(self, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, cv: str,
                       settings: FoldSettings | None, max_components: int) -> FoldResult:
        """Out-of-fold predictions under LOO (``cv="loo"``) or leave-one-specimen-out (``"loso"``)."""
        ...

    def permuted_rmse(self, X: np.ndarray, Y: np.ndarray, specimens: np.ndarray, cv: str,
                      settings: FoldSettings | None, max_components: int) -> np.ndarray:
        """The pooled CV RMSE of each shuffled target column of Y, the whole selection rerun on each."""
        ...

    def held_out_flags(self, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, settings: FoldSettings | None,
                       fold: FoldResult) -> np.ndarray | None:
        """Whether each trial lay outside the applicability domain of the model fitted without its specimen."""
        return None

    def interval_check(self, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, settings: FoldSettings | None,
                       seed: int) -> pd.DataFrame | None:
        """The fully nested jackknife+ check of each surface's interval, where leave-two-out fits are affordable."""
        return None

    def scheme_predictions(self, X: np.ndarray, targets: np.ndarray, specimens: np.ndarray, folds: np.ndarray,
                           settings: FoldSettings | None, max_components: int
                           ) -> tuple[np.ndarray, np.ndarray | None] | None:
        """Out-of-fold predictions (B, n) under any ``folds`` of the target columns (n, B) it can afford (at least
        the first, the real one), and the held-out flags under those folds; None where the folds are too small."""
        return None

    def surface_reader(self, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, settings: FoldSettings | None
                       ) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
        """``read(rows, surfaces)``: each row's prediction by the model fitted without its specimen, the rows of
        one label read as one surface (how many presses a surface needs); None when a press is read alone."""
        return None

    def jackknife(self, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, settings: FoldSettings | None,
                  fold: FoldResult, seed: int):
        """The leave-one-specimen-out fold models and residuals a model file keeps for the jackknife+, or None."""
        return None
