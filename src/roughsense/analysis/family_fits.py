"""Every model family cross-validated on one pad x condition x CV scheme, under the same folds, as the study does it.

A fit record (:class:`FamilyFit`) holds one family's out-of-fold predictions, its CV curve (index 0: the training
mean under the same folds) and its per-specimen table, judged the same way whatever the family. The numerics are the
family's engine's (roughsense.model.family); building the frames, judging them and naming the pad and condition in
a message happen here, once for every family."""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .. import defaults
from ..errors import InputError
from ..model.family import FoldResult, FoldSettings
from ..model.registry import engine, family, paper_family
from .metrics import specimen_table
from .spread import predictive_ovl

PRED_SD_DDOF = 0


@dataclass(frozen=True)
class FamilyFit:
    """One family on one pad x condition x CV scheme: its CV curve, what it chose and the per-specimen table.

    ``predictions`` holds one out-of-fold prediction per trial (specimen, repetition, image, prediction).
    ``curve``: index 0 the training mean's RMSE under the same folds, then the family's own (PLS: one per
    component count; a family that chooses nothing: one). ``best``/``one_se``: the index the family's prediction
    is read at; ``per_specimen``: a nested choice per held-out specimen (PLS's LOSO: no choice ever sees the
    specimen it predicts), else empty. ``model`` names the family (roughsense.model.registry).
    """

    pad: str
    condition: str
    cv: str
    curve: np.ndarray
    best: int
    one_se: int
    predictions: pd.DataFrame
    table: pd.DataFrame
    per_specimen: dict[str, int] = field(default_factory=dict)
    model: str = field(default_factory=lambda: paper_family().name)
    #: LOSO only: whether each trial lay outside the applicability domain of the model fitted without its specimen.
    held_out_flags: np.ndarray | None = None
    #: LOSO only: each specimen's jackknife+ surface interval from models that never saw it (the family's
    #: ``interval_check``); None for a family without cheap leave-two-out fits.
    interval_check: pd.DataFrame | None = None

    def fold(self) -> FoldResult:
        """The fit's cross-validation as its family's engine returned it."""
        return FoldResult(self.predictions["prediction"].to_numpy(dtype=float), self.curve, self.best, self.one_se,
                          self.per_specimen)


def _usable_components(n_train: int, n_features: int, max_components: int) -> int:
    return int(min(max_components, n_train - 1, n_features))


def _check_cv_size(X: np.ndarray, y: np.ndarray, specimens: np.ndarray, pad: str, condition: str, cv: str,
                   max_components: int) -> int:
    """The largest usable component count; one line naming the model when the design is too small for the CV."""
    held_out = int(pd.Series(specimens).value_counts().max()) if cv == "loso" else 1
    usable = _usable_components(len(y) - held_out, X.shape[1], max_components)
    if usable < 1:
        raise InputError(f"{pad} {condition}: too few samples for {cv.upper()} cross-validation ({len(y)} trials)")
    if cv == "loso" and len(np.unique(specimens)) < 4:
        raise InputError(f"{pad} {condition}: leave-one-specimen-out needs at least 4 specimens "
                         "(3 to choose the components of each held-out one)")
    return usable


def _prediction_frame(meta: pd.DataFrame, out_of_fold: np.ndarray) -> pd.DataFrame:
    """One row per trial: specimen, repetition, its image(s) and its out-of-fold prediction."""
    image_columns = [c for c in meta.columns if c.startswith("image")]
    predictions = meta[["specimen", "repetition"]].copy()
    predictions["image"] = meta[image_columns].astype(str).agg(";".join, axis=1)
    predictions["prediction"] = out_of_fold
    return predictions


def _judged(predictions: pd.DataFrame, perceived: pd.DataFrame) -> pd.DataFrame:
    """The per-specimen table (Tables 1-6) of out-of-fold predictions, with the predictive OVL."""
    # The paper's Tables 1-6 are consistent with the population SD of the predictions (RMSE^2 = bias^2 + SD^2
    # holds for all 112 rows with ddof=0, 107 with ddof=1; docs/perception.md), so we report the same.
    table = specimen_table(predictions, perceived, pred_sd_ddof=PRED_SD_DDOF)
    return pd.concat([table, predictive_ovl(table, perceived)], axis=1)


def law_settings(X: np.ndarray, freq_per_mm: np.ndarray, pad_ridge_period_mm: float | None, specimens=None,
                 contact: np.ndarray | None = None, contact_names: Sequence[str] = ()) -> dict:
    """The families' settings for one pad x condition (:class:`FoldSettings`, as the keyword dict peak_law_cv
    takes, with each row's contact measures beside): the grid, how many spectra a row holds, the pad's ridges, the
    surface of each row (its specimen: a specimen's presses share where its peak is, docs/peak_law.md) and its
    contact measures (``dataset.condition_contact``)."""
    freq = np.asarray(freq_per_mm, dtype=float)
    if freq.size == 0 or X.shape[1] % freq.size:
        raise InputError(f"{X.shape[1]} features are not whole spectra of the {freq.size}-frequency grid")
    return FoldSettings(freq, X.shape[1] // freq.size, pad_ridge_period_mm,
                        None if specimens is None else np.asarray(specimens).astype(str),
                        contact, tuple(contact_names)).keywords()


def _cross_validated(model: str, X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, pad: str, condition: str, cv: str,
                     law, max_components: int) -> FoldResult:
    """The family's engine under ``cv``, after refusing a design too small for it (in words naming the pad)."""
    specimens = meta["specimen"].astype(str).to_numpy()
    numerics = engine(model)
    usable = _check_cv_size(X, y, specimens, pad, condition, cv, numerics.largest_count(max_components))
    return numerics.cross_validate(X, y, specimens, cv, FoldSettings.of(law), usable)


def _record(model: str, fold: FoldResult, meta: pd.DataFrame, perceived: pd.DataFrame, pad: str, condition: str,
            cv: str, **flags) -> FamilyFit:
    predictions = _prediction_frame(meta, fold.out_of_fold)
    return FamilyFit(pad, condition, cv, fold.curve, int(fold.best), int(fold.one_se), predictions,
                     _judged(predictions, perceived), fold.per_specimen, family(model).name, **flags)


def family_fit(model: str, X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, perceived: pd.DataFrame, pad: str,
               condition: str, cv: str, *, law: dict | FoldSettings | None = None,
               max_components: int = defaults.MAX_COMPONENTS) -> FamilyFit:
    """One family cross-validated on one pad x condition under ``cv`` (LOSO nested where it chooses), as the study
    does it; its curve starts with the training mean's RMSE under the same folds (the null model)."""
    fold = _cross_validated(model, X, y, meta, pad, condition, cv, law, max_components)
    return _record(model, fold, meta, perceived, pad, condition, cv)


def fit_all(models: Sequence[str], X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, perceived: pd.DataFrame,
            pad: str, condition: str, cv: str, law: dict, *, max_components: int = defaults.MAX_COMPONENTS,
            seed: int = defaults.SEED) -> list[FamilyFit]:
    """Every requested family on one pad x condition x CV scheme, under the same folds, in the order asked; a LOSO
    fit carries its held-out flags and interval check from the start."""
    fits = [family_fit(model, X, y, meta, perceived, pad, condition, cv, law=law, max_components=max_components)
            for model in models]
    if cv != "loso":
        return fits
    specimens, settings = meta["specimen"].astype(str).to_numpy(), FoldSettings.of(law)
    # Whether each held-out trial lay outside the domain of the model fitted without it, as its family's domain
    # says; and the fully nested jackknife+ check of its intervals where the family has cheap leave-two-out fits.
    return [dataclasses.replace(
        fit, held_out_flags=engine(fit.model).held_out_flags(X, y, specimens, settings, fit.fold()),
        interval_check=engine(fit.model).interval_check(X, y, specimens, settings, seed)) for fit in fits]
