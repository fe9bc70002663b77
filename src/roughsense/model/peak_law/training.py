"""The peak law trained for a model file (``roughsense fit --model peak-law``) and cross-validated as the study does.

The law chooses nothing from the targets, so its CV under any folds is its fit on each training fold:
:func:`law_out_of_fold` is that one cross-validation, taking fold ids, run by the study's engine (LOO, LOSO) and by
``fit`` (LOO, LOSO or shuffled K-fold). ``fit`` reports it beside the training mean under the same folds, RMSE and
SE (:func:`cross_validate_law`), then fits the law on every trial with the pad's ridge period left out of its peak
search; and it prints the law and the range of peaks it was trained on.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...errors import ConfigError
from ..family import FoldSettings, Trained, TrainingSet
from .law import NAME

#: What the law's CV rows are, in order (the training mean under the same folds first, as PLS's 0 components).
LAW_CV_MODELS = ("training mean", NAME)
#: The fields the law adds to a model file's training record (model/training_file.py), as JSON Schema.
TRAINING_SCHEMA = {"model": {"const": NAME}, "cv_models": {"type": "array", "items": {"type": "string"}}}


def law_out_of_fold(X: np.ndarray, y: np.ndarray, folds: np.ndarray, settings: FoldSettings) -> np.ndarray:
    """The law's out-of-fold predictions (n,) under fold ids ``folds`` (one label per row: each label a fold left
    out): the law's one cross-validation, the same arithmetic as refitting it on every training fold."""
    from .cv import peak_law_cv

    return peak_law_cv(X, y, groups=folds, **settings.law())[0]


@dataclass(frozen=True)
class LawCVResult:
    """Cross-validated peak law beside the training mean under the same folds (index 0 the mean, 1 the law)."""

    rmse: np.ndarray  # (2,)
    rmse_se: np.ndarray  # (2,): delta method on the per-fold mean squared errors, as pls_cv's
    predictions: np.ndarray  # (n, 2) out-of-fold
    folds: np.ndarray
    scheme: str


def cross_validate_law(data: TrainingSet) -> LawCVResult:
    """Out-of-fold predictions of the training mean and of the law under the folds ``fit`` was given (LOO,
    leave-one-specimen-out, or shuffled K-fold: the folds PLS's ``fit`` uses), with their RMSE and its SE."""
    y, fid = np.asarray(data.y, dtype=np.float64), data.folds
    n_folds = int(fid.max()) + 1
    fold_size = np.bincount(fid, minlength=n_folds)
    predictions = np.column_stack([data.baseline, law_out_of_fold(data.X, y, fid, data.settings)])
    err2 = (predictions - y[:, None]) ** 2
    rmse = np.sqrt(err2.mean(axis=0))
    fold_mse = np.stack([np.bincount(fid, weights=e, minlength=n_folds) for e in err2.T], axis=1) / fold_size[:, None]
    se_mse = fold_mse.std(axis=0, ddof=1) / np.sqrt(n_folds)
    rmse_se = np.divide(se_mse, 2 * rmse, out=np.zeros_like(rmse), where=rmse > 0)
    return LawCVResult(rmse=rmse, rmse_se=rmse_se, predictions=predictions, folds=fid, scheme=data.fold_scheme)


def train_law(data: TrainingSet) -> Trained:
    """The law's CV beside the training mean's, and the law fitted on every trial (nothing is chosen)."""
    from .law import PeakPowerLaw

    settings = data.settings
    law = PeakPowerLaw(freq_per_mm=settings.freq_per_mm, n_blocks=settings.n_blocks,
                       pad_ridge_period_mm=settings.pad_ridge_period_mm)
    try:
        result = cross_validate_law(data)
        fitted = law.fit(data.X, data.y, surfaces=np.asarray(data.specimens).astype(str))
    except ValueError as exc:
        raise ConfigError(f"the peak law cannot be fitted to {data.what}: {exc}") from None
    record = {"model": NAME, "cv_models": list(LAW_CV_MODELS), "cv_rmse": [float(v) for v in result.rmse],
              "cv_rmse_se": [float(v) for v in result.rmse_se]}
    return Trained(fitted, result, 1, record)


def law_table(result: LawCVResult) -> pd.DataFrame:
    """The peak law's CV as printed by ``fit``: the training mean and the law, RMSE and SE under the same folds."""
    return pd.DataFrame({"model": list(LAW_CV_MODELS), "rmse": result.rmse, "rmse_se": result.rmse_se})


def law_report(trained) -> tuple[pd.DataFrame, list[str]]:
    """What ``fit`` prints: the CV beside the training mean's, the law, and the peaks (and shapes) it was trained on."""
    result, law = trained.cv, trained.model
    low, high = np.exp(law.feature_min_[0]), np.exp(law.feature_max_[0])
    return law_table(result), [
        f"peak law: CV RMSE {result.rmse[1]:.5f} (training mean {result.rmse[0]:.5f}); "
        f"log(roughness) = {law.intercept_:.4f} {law.coef_[0]:+.4f} log(peak frequency, mm^-1)"
        + (f" {law.coef_[2]:+.4f} log(second-harmonic ratio)" if law.coef_[2] else
           " (the contact's shape not read on every training surface: no shape term)"),
        f"trained on spectral peaks at {low:.3f}-{high:.3f} mm^-1 (periods {1 / high:.2f}-{1 / low:.2f} mm)"
        f"{_shape_range(law)}; a surface outside that range is flagged as extrapolating when predicted"]


def _shape_range(law) -> str:
    """The contact patterns a law that reads the shape was trained on ('' where it reads none): they bound its
    domain as the periods do, so the line that states the domain states them too."""
    from ...sensor.shape import duty_cycle
    from ..peak_search import HARMONIC

    if len(law.feature_min_) <= HARMONIC or not np.isfinite([law.feature_min_[HARMONIC],
                                                              law.feature_max_[HARMONIC]]).all():
        return ""
    return (f" and contact patterns {duty_cycle(law.feature_max_[HARMONIC]):.2f}-"
            f"{duty_cycle(law.feature_min_[HARMONIC]):.2f} of the period in contact")
