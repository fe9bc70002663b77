"""The groove model trained for a model file (``roughsense fit --model groove``) and cross-validated as the study
does it: one function (:func:`groove_out_of_fold`) under any fold ids, the terms chosen anew inside every
training fold by inner leave-one-specimen-out, so no held-out trial ever influences its own fold's choice.

``fit`` reports the CV beside the training mean's under the same folds (RMSE and SE), how often each term was kept
across the folds, the law fitted on every trial and the widths it was trained on.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...errors import ConfigError
from ..family import FoldSettings, Trained, TrainingSet
from ..folds import error_curve
from .cv import nested_log_predictions
from .law import NAME
from .terms import TERM_NAMES, contact_terms

#: What the CV rows are, in order (the training mean under the same folds first).
CV_MODELS = ("training mean", NAME)
#: The fields the groove model adds to a model file's training record (model/training_file.py), as JSON Schema.
#: Every family's fields share one record, so none is named as another family's is unless its schema is the same
#: (the peak law's ``model`` is ``const "peak-law"``: the groove model records no ``model``).
TRAINING_SCHEMA = {
    "cv_models": {"type": "array", "items": {"type": "string"}},
    "terms_kept": {"type": "object", "propertyNames": {"enum": list(TERM_NAMES)},
                   "additionalProperties": {"type": "number", "minimum": 0, "maximum": 1}},
}


def contact_of(settings: FoldSettings | None, what: str = "the rows") -> tuple[np.ndarray, tuple[str, ...]]:
    """The contact measures and their names from the settings, or a refusal naming ``what`` lacks them."""
    if settings is None or not settings.has_contact:
        raise ConfigError(f"the groove model reads contact measures (land and groove widths), and {what} carry none")
    return np.asarray(settings.contact, dtype=np.float64), tuple(settings.contact_names)


def groove_out_of_fold(y: np.ndarray, folds: np.ndarray, specimens: np.ndarray, settings: FoldSettings | None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Out-of-fold predictions (B, n) of each target column of ``y`` (n,) or (n, B) under fold ids ``folds``,
    and the terms chosen in each fold (F, B bit masks over the terms offered)."""
    contact, names = contact_of(settings)
    terms, _ = contact_terms(contact, names, settings.surfaces)
    y = np.asarray(y, dtype=np.float64)
    log_y = np.log(y[:, None] if y.ndim == 1 else y)
    log_predictions, chosen = nested_log_predictions(terms, log_y, folds, specimens)
    return np.exp(log_predictions), chosen


def term_shares(chosen: np.ndarray, names: tuple[str, ...]) -> dict[str, float]:
    """How often each offered term was kept, over the folds (the first target column's)."""
    return {name: float(np.mean(chosen[:, 0] >> t & 1)) for t, name in enumerate(names)}


@dataclass(frozen=True)
class GrooveCVResult:
    """The groove model's CV beside the training mean under the same folds (index 0 the mean, 1 the model)."""

    rmse: np.ndarray
    rmse_se: np.ndarray
    predictions: np.ndarray  # (n, 2) out-of-fold
    folds: np.ndarray
    scheme: str
    terms_kept: dict


def train_groove(data: TrainingSet) -> Trained:
    """The nested CV under ``data.folds``, then the law chosen and fitted on every trial."""
    from .law import GrooveLaw

    what = f"the trials of {data.what}"
    contact, names = contact_of(data.settings, what)
    y = np.asarray(data.y, dtype=np.float64)
    try:
        out_of_fold, chosen = groove_out_of_fold(y, data.folds, data.specimens, data.settings)
        fitted = GrooveLaw().fit(data.X, y, contact=contact, contact_names=names, specimens=data.specimens,
                                 surfaces=data.settings.surfaces)
    except ValueError as exc:
        raise ConfigError(f"the groove model cannot be fitted to {data.what}: {exc}") from None
    predictions = np.column_stack([data.baseline, out_of_fold[0]])
    rmse, rmse_se, _ = error_curve(predictions, y, data.folds)
    kept = term_shares(chosen, fitted.term_names_)
    result = GrooveCVResult(rmse, rmse_se, predictions, data.folds, data.fold_scheme, kept)
    record = {"cv_models": list(CV_MODELS), "cv_rmse": [float(v) for v in rmse],
              "cv_rmse_se": [float(v) for v in rmse_se], "terms_kept": kept}
    return Trained(fitted, result, 1, record)


def groove_report(trained) -> tuple[pd.DataFrame, list[str]]:
    """What ``fit`` prints: the CV beside the training mean's, the terms' keeping, the law and its widths."""
    result, law = trained.cv, trained.model
    table = pd.DataFrame({"model": list(CV_MODELS), "rmse": result.rmse, "rmse_se": result.rmse_se})
    kept = ", ".join(f"{name} {share:.0%}" for name, share in result.terms_kept.items())
    low, high = np.exp(law.domain_low_), np.exp(law.domain_high_)
    return table, [
        f"groove model: CV RMSE {result.rmse[1]:.5f} (training mean {result.rmse[0]:.5f}); terms kept across the "
        f"folds: {kept}",
        f"{law.equation()}",
        f"trained on groove widths {low[0]:.2f}-{high[0]:.2f} mm and land widths {low[1]:.2f}-{high[1]:.2f} mm; "
        "a press outside either is flagged as extrapolating when predicted"]
