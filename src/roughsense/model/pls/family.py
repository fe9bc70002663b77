"""The paper's family, PLS1 (SIMPLS) on the spectral amplitudes, as the analysis cross-validates and controls it.

PLS chooses its component count from the targets, so every held-out prediction is made at a count chosen without
the held-out data: LOO reads the curve's minimum (the paper's protocol), leave-one-specimen-out nests a second LOSO
over the other specimens (:func:`roughsense.model.pls.cv.nested_group_predictions`), and the permutation control
reruns that same choice on every shuffled target in one batch (:func:`roughsense.model.pls.cv.pls_cv_many`).
Its extras: the applicability flags of each held-out fit (model/pls/applicability.py), stricter held-out schemes with
a nested count per fold, and the jackknife+ fold models. It has no cheap leave-two-out fits, so no nested interval
check, and reads every press alone. The rest of its life is its modules': ``fit``'s CV and record
(model/pls/training.py), its model-file section (model/pls/file.py) and its jackknife+ folds (model/pls/jackknife.py).
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np
import pandas as pd

from ..family import FamilyEngine, FoldResult, FoldSettings, cv_rmse
from ..readout_domain import ReadoutSettings
from ..registry import PLS
from . import file
from .applicability import nested_domain_flags
from .cv import nested_group_predictions, pls_cv, pls_cv_many
from .jackknife import FOLD_SCHEMA, load_linear_folds, pls_jackknife
from .training import TRAINING_SCHEMA, check_pls_options, check_pls_training, pls_report, train_pls


def loso_nested(X: np.ndarray, y: np.ndarray, specimens: np.ndarray, outer, max_components: int):
    """Nested leave-one-specimen-out: choose each held-out specimen's component count without it.

    The outer LOSO run already holds every held-out specimen's prediction at every count, so the nested
    prediction for specimen s is the outer one at the count an inner LOSO over the other specimens picks
    (:func:`roughsense.model.pls.cv.nested_group_predictions`, which the permutation control reuses).
    """
    predictions, counts = nested_group_predictions(X, y[:, None], specimens,
                                                   outer.predictions[None, :, : max_components + 1])
    names = pd.unique(specimens)
    return predictions[0], {str(name): int(k) for name, k in zip(names, counts[0])}


def permuted_cv_rmse(X: np.ndarray, Y: np.ndarray, specimens: np.ndarray, cv: str, max_components: int) -> np.ndarray:
    """CV RMSE of each target column of Y after the same selection the study applies to the real target.

    LOO: the argmin over 1..max_components of the LOO RMSE. LOSO: nested leave-one-specimen-out (each
    held-out specimen's count chosen by LOSO over the others), pooled over all trials.
    """
    if cv == "loo":
        batch = pls_cv_many(X, Y, max_components=max_components, cv="loo", cap=True)
        return batch.rmse[:, 1:].min(axis=1)
    outer = pls_cv_many(X, Y, max_components=max_components, groups=specimens, cap=True)
    nested, _ = nested_group_predictions(X, Y, specimens, outer.predictions)
    return cv_rmse(nested, Y.T)


def pls_scheme_predictions(X: np.ndarray, y: np.ndarray, specimens: np.ndarray, folds: np.ndarray,
                           max_components: int) -> np.ndarray | None:
    """PLS's out-of-fold predictions under ``folds``, each fold's component count chosen by leave-one-specimen-out
    within its training data only (a shape held out leaves one training shape: its specimens are the inner folds).
    None where a fold leaves too few trials or specimens to choose a count without it."""
    largest = int(pd.Series(folds).value_counts().max())
    usable = int(min(max_components, len(y) - largest - 1, X.shape[1]))
    inner_usable = {}
    for fold in pd.unique(folds):
        rest = pd.Series(specimens[folds != fold])
        inner_usable[fold] = int(min(usable, len(rest) - rest.value_counts().max() - 1, X.shape[1]))
        if rest.nunique() < 3 or inner_usable[fold] < 1:
            return None
    outer = pls_cv_many(X, y[:, None], max_components=usable, groups=folds, cap=True).predictions[0]
    predictions = np.empty(len(y))
    for fold, inner_max in inner_usable.items():
        held = folds == fold
        inner = pls_cv_many(X[~held], y[~held, None], max_components=inner_max, groups=specimens[~held], cap=True)
        predictions[held] = outer[held, int(inner.best_n_components[0])]
    return predictions


class PLSFamily(FamilyEngine):
    """PLS1 by SIMPLS with its component count chosen by cross-validation (nested under LOSO)."""

    name: ClassVar[str] = PLS
    kind: ClassVar[str] = file.KIND
    section_schema: ClassVar[dict] = file.SCHEMA
    training_schema: ClassVar[dict] = TRAINING_SCHEMA
    fold_schema: ClassVar[dict] = FOLD_SCHEMA
    ridge_period_place: ClassVar[str | None] = "applicability.peak.pad_ridge_period_mm"

    def cross_validate(self, X, y, specimens, cv, settings, max_components) -> FoldResult:
        """LOO at the curve's minimum, or nested LOSO; ``max_components`` is what the folds support."""
        per_specimen: dict[str, int] = {}
        if cv == "loo":
            result = pls_cv(X, y, max_components=max_components, cv="loo", cap=True)
            out_of_fold = result.predictions[:, result.best_n_components]
        else:
            result = pls_cv(X, y, max_components=max_components, groups=specimens, cap=True)
            out_of_fold, per_specimen = loso_nested(X, y, specimens, result, result.max_components)
        return FoldResult(out_of_fold, np.asarray(result.rmse, float), int(result.best_n_components),
                          int(result.one_se_n_components), per_specimen)

    def largest_count(self, max_components: int) -> int:
        return max_components

    def permuted_rmse(self, X, Y, specimens, cv, settings, max_components) -> np.ndarray:
        return permuted_cv_rmse(X, Y, specimens, cv, max_components)

    def held_out_flags(self, X, y, specimens, settings, fold) -> np.ndarray:
        """model/pls/applicability.py's flags, each specimen's model at its nested count (LOO: the chosen one), with
        the peak readout of the pad's grid beside the spectrum's shape."""
        law = FoldSettings.of(settings)
        readout = ReadoutSettings(law.freq_per_mm, law.n_blocks, law.pad_ridge_period_mm)
        counts = fold.per_specimen or {str(s): fold.best for s in specimens}
        return nested_domain_flags(X, y, specimens, counts, readout)

    def scheme_predictions(self, X, targets, specimens, folds, settings, max_components):
        """The real target only: a nested count search per shuffling would double the study's controls."""
        y = np.ascontiguousarray(targets[:, 0])
        prediction = pls_scheme_predictions(X, y, specimens, folds, max_components)
        return None if prediction is None else (prediction[None, :], None)

    def jackknife(self, X, y, specimens, settings, fold, seed):
        return pls_jackknife(X, y, specimens, fold.per_specimen, seed)

    def check_options(self, options) -> None:
        check_pls_options(options)

    def train(self, data):
        return train_pls(data)

    def fit_report(self, trained):
        return pls_report(trained)

    def section(self, model) -> dict:
        return file.pls_section(model)

    def check_fields(self, section, path):
        return file.check_fields(section, path)

    def load(self, section, features, *, training, roughsense_version, path):
        return file.loaded_pls(section, features, training=training, roughsense_version=roughsense_version, path=path)

    def check_written(self, section, features, training) -> None:
        file.check_written(section, features)

    def check_section(self, section, document, fail) -> None:
        file.check_section(section, document, fail)

    def check_training(self, training, section, fail) -> None:
        check_pls_training(training, section, fail)

    def load_folds(self, stored, loaded, names, path):
        return load_linear_folds(stored, loaded, names, path)
