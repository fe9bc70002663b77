"""What a model file says about itself: how it predicts surfaces it never saw, its controls, and its interval.

``roughsense fit`` writes a model for new surfaces, so whatever CV the user chose for the fit, the model is also
judged the way the study judges it (analysis/unseen.py): nested leave-one-specimen-out against the training mean
and against specimen-shuffled targets, with the same functions, folds and shufflings. A model that fails them is
still written (a user may want it), but the file records the failure and ``fit`` and ``predict`` say it in one line.
The 90 % prediction intervals come from the same leave-one-specimen-out fits: per press the plain jackknife
(model/interval.py), per surface the jackknife+ (model/jackknife_file.py), whose fold models the file keeps.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import defaults
from ..model.family import FoldSettings
from ..model.interval import PredictionInterval
from ..model.jackknife_file import KEY as JACKKNIFE_KEY
from ..model.jackknife_file import DeployedJackknife
from ..model.registry import engine
from ..model.training_file import FAILS
from . import controls as _controls
from .family_fits import family_fit
from .metrics import ALPHA
from .unseen import null_specimen_rmse


@dataclass(frozen=True)
class UnseenAssessment:
    """Nested LOSO of one model: per-specimen and pooled RMSE beside the training mean's, the permutation
    control, and the prediction interval its out-of-fold residuals give."""

    rmse: float
    null_rmse: float
    pooled_rmse: float
    null_pooled_rmse: float
    permutation_p: float
    n_permutations: int
    passes: bool
    interval: PredictionInterval
    #: The fold models and residuals by presses a model file keeps for the jackknife+ (model/jackknife_file.py).
    jackknife: DeployedJackknife | None = None

    @property
    def failure(self) -> str:
        """One line naming each control the model fails, with its numbers ('' when it passes them all)."""
        problems = []
        if not self.pooled_rmse < self.null_pooled_rmse:
            problems.append(f"no better than the training mean (pooled RMSE {self.pooled_rmse:.3f} vs "
                            f"{self.null_pooled_rmse:.3f})")
        if self.n_permutations and not self.permutation_p < ALPHA:
            problems.append(f"not better than shuffled targets (permutation p = {self.permutation_p:.3f} >= "
                            f"{ALPHA:g}, {self.n_permutations} shufflings)")
        if not problems:
            return ""
        verdict = ("Its predictions for new surfaces are no better than guessing" if len(problems) == 2 else
                   "Its predictions for new surfaces are not shown to be better than guessing")
        return (f"{FAILS} for a grating left out of training (nested leave-one-specimen-out): "
                + "; ".join(problems) + f". {verdict}")

    def interval_record(self) -> dict:
        """The model file's interval entries: the plain jackknife's half-widths (``interval``) and the jackknife+'s
        fold models and residuals by presses (``jackknife_plus``), when there are folds to keep."""
        record = {"interval": self.interval.to_dict()}
        if self.jackknife is not None:
            record[JACKKNIFE_KEY] = self.jackknife.to_dict()
        return record

    def record(self) -> dict:
        """The model file's ``unseen`` entry (JSON values; a number the design cannot give is null)."""
        def finite(value: float) -> float | None:
            return value if math.isfinite(value) else None

        return {"cv": "loso (nested)", "rmse": finite(self.rmse), "null_rmse": finite(self.null_rmse),
                "pooled_rmse": finite(self.pooled_rmse), "null_pooled_rmse": finite(self.null_pooled_rmse),
                "permutation_p": finite(self.permutation_p), "n_permutations": self.n_permutations,
                "passes_controls": self.passes, "failure": self.failure}


def assess_unseen(family: str, X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, perceived: pd.DataFrame, *,
                  pad: str, condition: str, law: dict | None, max_components: int, seed: int,
                  n_permutations: int = defaults.PERMUTATIONS) -> UnseenAssessment:
    """Nested LOSO of ``family`` on one pad x condition, its controls and its interval (the study's arithmetic)."""
    fit = family_fit(family, X, y, meta, perceived, pad, condition, "loso", law=law, max_components=max_components)
    specimens = meta["specimen"].astype(str).to_numpy()
    permutations = _controls.specimen_permutations(len(pd.unique(specimens)), n_permutations, seed)
    row = _controls.control_row(fit, X, y, specimens, permutations, law)
    predictions = fit.predictions["prediction"].to_numpy(dtype=float)
    numerics, settings = engine(fit.model), FoldSettings.of(law)
    alone = None
    if numerics.reads_surfaces and settings is not None and settings.surfaces is not None:  # a press read alone
        alone = family_fit(family, X, y, meta, perceived, pad, condition, "loso",
                           law=dataclasses.replace(settings, surfaces=None),
                           max_components=max_components).predictions["prediction"].to_numpy(dtype=float)
    interval = PredictionInterval.from_cv(predictions, y, specimens, alone_predictions=alone)
    jackknife = numerics.jackknife(X, y, specimens, settings, fit.fold(), seed)
    return UnseenAssessment(
        rmse=float(fit.table["rmse"].mean()),
        null_rmse=float(null_specimen_rmse(fit.predictions, perceived).mean()),
        pooled_rmse=float(row["rmse"]), null_pooled_rmse=float(row["null_rmse"]),
        permutation_p=float(row["permutation_p"]), n_permutations=int(row["n_permutations"]),
        passes=bool(row["passes"]), interval=interval, jackknife=jackknife)
