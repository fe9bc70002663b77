"""The peak power law (:class:`roughsense.model.peak_law.law.PeakPowerLaw`) as the analysis cross-validates and controls it.

The law chooses nothing from the targets, so its held-out prediction under any folds is its fit on the training
fold, and every fold and every shuffled target goes through one batched IRLS
(:func:`~roughsense.model.peak_law.cv.peak_law_cv`): the permutation control, the stricter schemes' own shufflings,
the leave-two-out fits of the nested jackknife+ check (model/peak_law/folds.py) and the laws that read a surface
from a few of its presses all cost one batch each. Its CV curve is two numbers: the training mean's RMSE under the
same folds (model/folds.py, computed as PLS computes its 0-component CV) and the law's, whose out-of-fold
predictions are the one CV of the law ``fit`` runs too (:func:`roughsense.model.peak_law.training.law_out_of_fold`).
The rest of its life is its modules': ``fit``'s training (model/peak_law/training.py), its model-file section
(model/peak_law/file.py) and its jackknife+ folds (model/peak_law/jackknife.py).
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np
import pandas as pd

from ...sensor.grid import grid_step
from ..family import FamilyEngine, FoldResult, FoldSettings, cv_rmse
from ..folds import error_curve, fold_ids, training_mean_predictions
from ..jackknife_plus import nested_check
from ..peak_search import held_features, peak_features
from ..readout_domain import domain_margins
from ..registry import PEAK_LAW
from . import file
from .cv import law_domain_flags, peak_law_cv
from .folds import law_fold_models, law_nested_press_check, law_pair_log_predictions, law_pair_models, specimen_codes
from .jackknife import FOLD_SCHEMA, law_jackknife, load_law_folds
from .training import TRAINING_SCHEMA, law_out_of_fold, law_report, train_law

#: The law's shufflings run in chunks of about this many cells (folds fitted x shufflings x presses) a working
#: array: 4 MiB of float64 (the built-in study's 199 shufflings in one chunk), whatever the number of presses. Its IRLS
#: and kept ranges take one fold per specimen (peak_law_cv), so what is left at this size is the kept ranges' arrays:
#: 2^21 cells held the two control threads ~40 MiB higher at the same CPU, 2^17 cost 13 % more CPU
#: (benchmarks/bench_issue37.py --chunks).
LAW_CHUNK_CELLS = 1 << 19


def permuted_law_rmse(X: np.ndarray, Y: np.ndarray, specimens: np.ndarray, cv: str, law) -> np.ndarray:
    """CV RMSE of the peak power law on each target column of Y, pooled over all trials (LOO or LOSO).

    ``law``: the pad x condition's settings (:class:`FoldSettings`, or peak_law_cv's keywords). Shufflings go
    through in chunks of about :data:`LAW_CHUNK_CELLS` folds x shufflings x presses, so the memory stays flat in the
    number of presses (leave-one-out has as many folds as presses); each shuffling's fit is its own.
    """
    law = FoldSettings.of(law).law()
    groups = np.asarray(specimens) if cv == "loso" else None
    n = Y.shape[0]
    # Leave-one-out's folds of one specimen's presses pose one problem (its targets are the specimen's one value):
    # peak_law_cv fits each once, so both schemes fit as many folds as there are specimens.
    size = max(1, LAW_CHUNK_CELLS // (n * len(pd.unique(np.asarray(specimens)))))
    predictions = np.vstack([peak_law_cv(X, Y[:, start:start + size], groups=groups, **law)
                             for start in range(0, Y.shape[1], size)])
    return cv_rmse(predictions, Y.T)


def loso_laws(X: np.ndarray, y: np.ndarray, specimens: np.ndarray, law):
    """The law fitted without each specimen (as the study fits it): coefficients (S, p + 1) and domains (S, p)."""
    law = FoldSettings.of(law).law()
    codes, names = specimen_codes(specimens)
    held = codes[None, :] == np.arange(names.size)[:, None]
    beta, low, high, _ = law_fold_models(X, y, ~held, **law)
    low, high = domain_margins(grid_step(law["freq_per_mm"]), low, high)
    return beta, low, high


class PeakLawFamily(FamilyEngine):
    """The peak power law: one law, nothing chosen, every fold and shuffling in one batch."""

    name: ClassVar[str] = PEAK_LAW
    kind: ClassVar[str] = file.KIND
    section_schema: ClassVar[dict] = file.SCHEMA
    training_schema: ClassVar[dict] = TRAINING_SCHEMA
    fold_schema: ClassVar[dict] = FOLD_SCHEMA
    ridge_period_place: ClassVar[str | None] = "pad_ridge_period_mm"
    reads_surfaces: ClassVar[bool] = True

    def cross_validate(self, X, y, specimens, cv, settings, max_components) -> FoldResult:
        """Its fit on each training fold predicts the held-out trials; curve = [training mean's RMSE, the law's]."""
        y = np.asarray(y, dtype=np.float64)
        fid, _ = fold_ids(y.size, None, specimens, None) if cv == "loso" else fold_ids(y.size, "loo", None, None)
        folds = specimens if cv == "loso" else np.arange(len(y))
        out_of_fold = law_out_of_fold(X, y, folds, FoldSettings.of(settings))
        null_rmse = error_curve(np.column_stack([training_mean_predictions(y, fid), out_of_fold]), y, fid)[0][0]
        law_rmse = float(np.sqrt(np.mean((out_of_fold - y) ** 2)))
        return FoldResult(out_of_fold, np.array([float(null_rmse), law_rmse]))

    def permuted_rmse(self, X, Y, specimens, cv, settings, max_components) -> np.ndarray:
        return permuted_law_rmse(X, Y, specimens, cv, settings)

    def held_out_flags(self, X, y, specimens, settings, fold) -> np.ndarray:
        """The law's own domain (peak position, strength, shape, clarity) of each specimen's held-out fit."""
        return law_domain_flags(X, y, specimens, **FoldSettings.of(settings).law())

    def interval_check(self, X, y, specimens, settings, seed) -> pd.DataFrame:
        """The fully nested jackknife+ check of a LOSO fit's intervals: of each surface (all its presses) and of
        each press read alone (``press_covered``, ``press_log_halfwidth``), as predict gives them; the
        leave-two-out fits are one batch."""
        law = FoldSettings.of(settings).law()
        codes, names = specimen_codes(specimens)
        log_targets = np.log(pd.Series(y).groupby(codes).first().to_numpy())
        models = law_pair_models(X, y, specimens, **law)
        check = nested_check(law_pair_log_predictions(X, y, specimens, models=models, **law), log_targets, names)
        presses = law_nested_press_check(X, y, specimens, 1, seed, models=models, **law)
        return check.assign(press_readings=presses["readings"].to_numpy(),
                            press_covered=presses["covered"].to_numpy(),
                            press_log_halfwidth=presses["log_halfwidth"].to_numpy())

    def scheme_predictions(self, X, targets, specimens, folds, settings, max_components):
        """Every target column at once (the shufflings cost one batch), and the law's flags under ``folds``."""
        law = FoldSettings.of(settings).law()
        every = peak_law_cv(X, targets, groups=folds, **law)
        return every, law_domain_flags(X, np.ascontiguousarray(targets[:, 0]), folds, **law)

    def surface_reader(self, X, y, specimens, settings):
        """Rows of one label read as one surface, each by the law fitted without its specimen."""
        law = FoldSettings.of(settings).law()
        codes, _ = specimen_codes(specimens)
        beta, low, high = loso_laws(X, y, specimens, law)

        def read(rows: np.ndarray, surfaces: np.ndarray) -> np.ndarray:
            features = peak_features(X[rows], **{**law, "surfaces": surfaces})
            owner = codes[rows]
            held = held_features(features, low[owner], high[owner])
            return np.exp(beta[owner, 0] + np.einsum("nf,nf->n", held, beta[owner, 1:]))

        return read

    def jackknife(self, X, y, specimens, settings, fold, seed):
        return None if settings is None else law_jackknife(X, y, specimens, FoldSettings.of(settings).law(), seed)

    def train(self, data):
        return train_law(data)

    def fit_report(self, trained):
        return law_report(trained)

    def section(self, model) -> dict:
        return file.law_section(model)

    def check_fields(self, section, path):
        return file.check_fields(section, path)

    def load(self, section, features, *, training, roughsense_version, path):
        return file.loaded_law(section, features, training=training, roughsense_version=roughsense_version, path=path)

    def check_written(self, section, features, training) -> None:
        """As loading it would (its fields are the writer's own: no field check first)."""
        self.load(section, features, training=training, roughsense_version="", path=None)

    def load_folds(self, stored, loaded, names, path):
        return load_law_folds(stored, loaded, names, path)
