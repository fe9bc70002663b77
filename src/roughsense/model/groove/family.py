"""The groove model (:class:`roughsense.model.groove.law.GrooveLaw`) as the analysis cross-validates and controls it.

Every fold scheme, every shuffled target column and every leave-two-out fit goes through one batch of sufficient
statistics (model/groove/cv.py), the terms chosen anew inside each training fold by inner leave-one-specimen-out.
Its CV curve is two numbers: the training mean's RMSE under the same folds (model/folds.py) and the model's. Its
held-out flags are its domain on land and groove widths (model/groove/domain.py) trained without each fold.

Where the settings carry no contact measures (a study read before they existed) no term can be offered: the model is
the training mean of log roughness and every row is flagged (its geometry was not read); ``fit`` refuses.
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np
import pandas as pd

from ..family import FamilyEngine, FoldResult, FoldSettings, cv_rmse
from ..folds import error_curve, fold_ids, training_mean_predictions
from ..jackknife_plus import nested_check, surface_means
from ..registry import GROOVE
from . import file
from .cv import fold_centres, fold_ranges, nested_fit, offered
from .domain import axis_values, held_out_flags
from .jackknife import FOLD_SCHEMA, groove_jackknife, load_groove_folds
from .terms import contact_terms, term_names
from .training import TRAINING_SCHEMA, groove_report, train_groove


def settings_terms(settings: FoldSettings | dict | None, n: int) -> tuple[np.ndarray, tuple[str, ...]]:
    """Each row's terms (n, T) from the settings' contact measures; (n, 0) where there are none."""
    settings = FoldSettings.of(settings)
    if settings is None or not settings.has_contact:
        return np.zeros((n, 0)), ()
    return contact_terms(settings.contact, settings.contact_names, settings.surfaces)


def log_predictions_under(terms: np.ndarray, log_y: np.ndarray, train: np.ndarray, specimens: np.ndarray
                          ) -> np.ndarray:
    """(O, B, n) log prediction of every row by the model chosen and fitted on each training mask (O, n)."""
    terms = offered(terms)
    chosen, beta, centre = nested_fit(terms, log_y, train, specimens)
    imputed = fold_centres(terms, train, centre)  # (O, T)
    low, high = fold_ranges(terms, train)
    held = np.clip(terms[None], low[:, None, :], high[:, None, :])  # (O, n, T)
    centred = np.where(np.isfinite(terms)[None], held - centre, imputed[:, None, :])
    D = np.concatenate([np.ones((*centred.shape[:2], 1)), centred], axis=2)
    return np.einsum("onq,oqb->obn", D, beta)


def out_of_fold(terms: np.ndarray, targets: np.ndarray, folds: np.ndarray, specimens: np.ndarray) -> np.ndarray:
    """(B, n) out-of-fold predictions of each target column (n, B) under fold labels ``folds``."""
    from .cv import nested_log_predictions

    return np.exp(nested_log_predictions(terms, np.log(targets), folds, specimens)[0])


def domain_flags(terms: np.ndarray, names: tuple[str, ...], specimens: np.ndarray, folds: np.ndarray) -> np.ndarray:
    """Whether each row lies outside the land/groove domain trained without its fold (every row, with no widths)."""
    if not names:
        return np.ones(len(terms), dtype=bool)
    return held_out_flags(axis_values(terms, names), specimens, folds)


class GrooveFamily(FamilyEngine):
    """The groove model: named contact terms chosen by nested LOSO, every fold and shuffling in one batch."""

    name: ClassVar[str] = GROOVE
    kind: ClassVar[str] = file.KIND
    section_schema: ClassVar[dict] = file.SCHEMA
    training_schema: ClassVar[dict] = TRAINING_SCHEMA
    fold_schema: ClassVar[dict] = FOLD_SCHEMA
    reads_contact: ClassVar[bool] = True
    reads_surfaces: ClassVar[bool] = True

    def cross_validate(self, X, y, specimens, cv, settings, max_components) -> FoldResult:
        """Its nested fit on each training fold predicts the held-out trials; curve = [training mean's, its own]."""
        y = np.asarray(y, dtype=np.float64)
        fid, _ = fold_ids(y.size, None, specimens, None) if cv == "loso" else fold_ids(y.size, "loo", None, None)
        terms, _ = settings_terms(settings, y.size)
        predicted = out_of_fold(terms, y[:, None], fid, specimens)[0]
        # As the peak law computes it (two columns: the same reduction order), bit for bit PLS's 0-component RMSE.
        null_rmse = error_curve(np.column_stack([training_mean_predictions(y, fid), predicted]), y, fid)[0][0]
        return FoldResult(predicted, np.array([float(null_rmse), float(np.sqrt(np.mean((predicted - y) ** 2)))]))

    def permuted_rmse(self, X, Y, specimens, cv, settings, max_components) -> np.ndarray:
        Y = np.asarray(Y, dtype=np.float64)
        folds = np.asarray(specimens) if cv == "loso" else np.arange(Y.shape[0])
        terms, _ = settings_terms(settings, Y.shape[0])
        return cv_rmse(out_of_fold(terms, Y, folds, specimens), Y.T)

    def held_out_flags(self, X, y, specimens, settings, fold) -> np.ndarray:
        """The land/groove domain of each specimen's held-out fit."""
        terms, names = settings_terms(settings, len(y))
        return domain_flags(terms, names, specimens, specimens)

    def scheme_predictions(self, X, targets, specimens, folds, settings, max_components):
        """Every target column at once under ``folds``, and the domain's flags under them."""
        targets = np.asarray(targets, dtype=np.float64)
        terms, names = settings_terms(settings, targets.shape[0])
        return out_of_fold(terms, targets, folds, specimens), domain_flags(terms, names, specimens, folds)

    def interval_check(self, X, y, specimens, settings, seed) -> pd.DataFrame:
        """The fully nested jackknife+ check of each surface's interval: the model chosen and fitted without every
        pair of specimens (one batch), so no specimen's interval ever saw it."""
        y = np.asarray(y, dtype=np.float64)
        codes, names = pd.factorize(pd.Series(np.asarray(specimens).astype(str)), sort=False)
        first, second = np.triu_indices(names.size)
        pair = np.empty((names.size, names.size), dtype=int)
        pair[first, second] = pair[second, first] = np.arange(first.size)
        held = (codes[None, :] == first[:, None]) | (codes[None, :] == second[:, None])
        terms, _ = settings_terms(settings, y.size)
        predicted = np.exp(log_predictions_under(terms, np.log(y)[:, None], ~held, specimens)[:, 0])
        log_means = np.log(surface_means(predicted, codes, names.size))[pair]
        log_targets = np.log(pd.Series(y).groupby(codes).first().to_numpy())
        return nested_check(log_means, log_targets, names)

    def jackknife(self, X, y, specimens, settings, fold, seed):
        """Its leave-one-specimen-out models (each its own nested choice) and residuals, for the model file; None
        without contact measures."""
        settings = FoldSettings.of(settings)
        if settings is None or not settings.has_contact:
            return None
        return groove_jackknife(X, y, specimens, settings.contact, settings.contact_names, seed,
                                surfaces=settings.surfaces)

    def load_folds(self, stored, loaded, names, path):
        return load_groove_folds(stored, loaded, names, path)

    def check_options(self, options) -> None:
        """It declares no option of its own."""

    def train(self, data):
        return train_groove(data)

    def fit_report(self, trained):
        return groove_report(trained)

    def section(self, model) -> dict:
        return file.groove_section(model)

    def check_fields(self, section, path):
        return file.check_fields(section, path)

    def check_training(self, training, section, fail) -> None:
        """The terms whose keeping the record states are the ones the section's contact columns offer."""
        kept, names = training.get("terms_kept"), section.get("contact_names")
        if isinstance(kept, dict) and isinstance(names, list):
            try:
                offered = term_names(names)
            except ValueError:
                return  # the section's own check names it
            if sorted(kept) != sorted(offered):
                fail("terms_kept", f"must state each offered term ({', '.join(offered)}), got {', '.join(kept)}")

    def load(self, section, features, *, training, roughsense_version, path):
        return file.loaded_groove(section, features, training=training, roughsense_version=roughsense_version,
                                  path=path)
