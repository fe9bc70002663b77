"""Every model family cross-validated on one pad x condition x CV scheme, under the same folds, as the study does it.

A fit record (:class:`ConditionFit`) holds one family's out-of-fold predictions, its CV curve (index 0: the training
mean under the same folds) and its per-specimen table, judged the same way whatever the family."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..errors import InputError
from ..model.applicability import held_out_flags as pls_flags
from ..model.families import PEAK_LAW, PLS
from ..model.jackknife_plus import nested_check
from ..model.peak_law import PeakPowerLaw, peak_law_cv
from ..model.peak_law import held_out_flags as peak_law_flags
from ..model.peak_law_folds import law_nested_press_check, law_pair_log_predictions, law_pair_models, specimen_codes
from ..model.pls_cv import DEFAULT_MAX_COMPONENTS, nested_group_predictions, pls_cv
from .metrics import specimen_table
from .spread import predictive_ovl

PRED_SD_DDOF = 0


@dataclass
class ConditionFit:
    """One pad x condition x CV scheme: the CV curve, the chosen count and the per-specimen table.

    ``predictions`` holds one out-of-fold prediction per trial (specimen, repetition, image, prediction).
    For LOSO they are nested: each held-out specimen's component count is chosen by LOSO over the other
    specimens only (``nested_n_components``), so no choice ever sees the specimen it predicts.
    ``model`` names the family (roughsense.model.families). A peak-law fit has ``cv_rmse`` = [training mean's
    RMSE under the same folds, the law's], counts of 1 and no nested counts: it chooses nothing.
    """

    pad: str
    condition: str
    cv: str
    cv_rmse: np.ndarray
    best_n_components: int
    one_se_n_components: int
    predictions: pd.DataFrame
    table: pd.DataFrame
    nested_n_components: dict[str, int] = field(default_factory=dict)
    model: str = PLS
    #: LOSO only: whether each trial lay outside the applicability domain of the model fitted without its specimen.
    held_out_flags: np.ndarray | None = None
    #: LOSO only: each specimen's jackknife+ surface interval from models that never saw it (model/jackknife_plus.py's
    #: ``nested_check``); None for a family without cheap leave-two-out fits (PLS).
    interval_check: pd.DataFrame | None = None


def _usable_components(n_train: int, n_features: int, max_components: int) -> int:
    return int(min(max_components, n_train - 1, n_features))


def _loso_nested(X: np.ndarray, y: np.ndarray, specimens: np.ndarray, outer, max_components: int):
    """Nested leave-one-specimen-out: choose each held-out specimen's component count without it.

    The outer LOSO run already holds every held-out specimen's prediction at every count, so the nested
    prediction for specimen s is the outer one at the count an inner LOSO over the other specimens picks
    (:func:`roughsense.model.pls_cv.nested_group_predictions`, which the permutation control reuses).
    """
    predictions, counts = nested_group_predictions(X, y[:, None], specimens,
                                                   outer.predictions[None, :, : max_components + 1])
    names = pd.unique(specimens)
    return predictions[0], {str(name): int(k) for name, k in zip(names, counts[0])}


def _condition_fit(
    X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, perceived: pd.DataFrame,
    pad: str, condition: str, cv: str, max_components: int,
) -> ConditionFit:
    specimens = meta["specimen"].astype(str).to_numpy()
    usable = _check_cv_size(X, y, specimens, pad, condition, cv, max_components)
    nested: dict[str, int] = {}
    if cv == "loo":
        result = pls_cv(X, y, max_components=usable, cv="loo", cap=True)
        out_of_fold = result.predictions[:, result.best_n_components]
    else:
        result = pls_cv(X, y, max_components=usable, groups=specimens, cap=True)
        out_of_fold, nested = _loso_nested(X, y, specimens, result, result.max_components)
    predictions = _prediction_frame(meta, out_of_fold)
    return ConditionFit(pad, condition, cv, np.asarray(result.rmse, float), int(result.best_n_components),
                        int(result.one_se_n_components), predictions, _judged(predictions, perceived), nested)


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


def law_settings(X: np.ndarray, freq_per_mm: np.ndarray, pad_ridge_period_mm: float | None, specimens=None) -> dict:
    """peak_law_cv's keywords for one pad x condition: the grid, how many spectra a row holds, the pad's ridges,
    and the surface of each row (its specimen: a specimen's presses share where its peak is, docs/peak_law.md)."""
    freq = np.asarray(freq_per_mm, dtype=float)
    if freq.size == 0 or X.shape[1] % freq.size:
        raise InputError(f"{X.shape[1]} features are not whole spectra of the {freq.size}-frequency grid")
    return {"freq_per_mm": freq, "n_blocks": X.shape[1] // freq.size, "pad_ridge_period_mm": pad_ridge_period_mm,
            "surfaces": None if specimens is None else np.asarray(specimens).astype(str)}


def _peak_law_fit(X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, perceived: pd.DataFrame, pad: str,
                  condition: str, cv: str, null_rmse: float, law: dict) -> ConditionFit:
    """The peak power law under LOO or LOSO: its fit on each training fold predicts the held-out trials.

    It chooses nothing from the targets, so LOSO needs no inner loop: each held-out specimen's predictions come
    from a fit to the other specimens only. ``null_rmse`` is the training mean's RMSE under the same folds.
    """
    specimens = meta["specimen"].astype(str).to_numpy()
    out_of_fold = peak_law_cv(X, y, groups=specimens if cv == "loso" else None, **law)[0]
    predictions = _prediction_frame(meta, out_of_fold)
    law_rmse = float(np.sqrt(np.mean((out_of_fold - y) ** 2)))
    return ConditionFit(pad, condition, cv, np.array([float(null_rmse), law_rmse]), 1, 1, predictions,
                        _judged(predictions, perceived), {}, PEAK_LAW)


def family_fit(model: str, X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, perceived: pd.DataFrame, pad: str,
               condition: str, cv: str, *, law: dict | None = None,
               max_components: int = DEFAULT_MAX_COMPONENTS) -> ConditionFit:
    """One family cross-validated on one pad x condition under ``cv`` (LOSO nested for PLS), as the study does it.

    The training mean's RMSE (the null model) is PLS's 0-component CV RMSE, the training-fold mean under these
    folds; the peak law's fit carries the same number (pls_cv at one component computes it).
    """
    if model == PLS:
        return _condition_fit(X, y, meta, perceived, pad, condition, cv, max_components)
    specimens = meta["specimen"].astype(str).to_numpy()
    _check_cv_size(X, y, specimens, pad, condition, cv, 1)
    kwargs = {"groups": specimens} if cv == "loso" else {"cv": "loo"}
    null_rmse = float(pls_cv(X, y, max_components=1, cap=True, **kwargs).rmse[0])
    return _peak_law_fit(X, y, meta, perceived, pad, condition, cv, null_rmse, law)


def held_out_flags(fit: ConditionFit, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, law: dict) -> np.ndarray:
    """The applicability flag each held-out trial of a LOSO fit would have carried (model/applicability.py for PLS,
    with each specimen's nested component count; the law's own domain for the peak law)."""
    if fit.model == PEAK_LAW:
        return peak_law_flags(X, y, specimens, **law)
    readout = PeakPowerLaw(**{k: law[k] for k in ("freq_per_mm", "n_blocks", "pad_ridge_period_mm")})
    counts = fit.nested_n_components or {str(s): fit.best_n_components for s in specimens}
    return pls_flags(X, y, specimens, counts, readout)


def interval_check(fit: ConditionFit, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, law: dict, seed: int = 0
                   ) -> pd.DataFrame | None:
    """The fully nested jackknife+ check of a LOSO fit's intervals: of each surface (all its presses) and of each
    press read alone (``press_covered``, ``press_log_halfwidth``), as predict gives them (the peak law's
    leave-two-out fits are one batch; PLS would need a nested component search per pair, and has none)."""
    if fit.model != PEAK_LAW:
        return None
    codes, names = specimen_codes(specimens)
    log_targets = np.log(pd.Series(y).groupby(codes).first().to_numpy())
    models = law_pair_models(X, y, specimens, **law)
    check = nested_check(law_pair_log_predictions(X, y, specimens, models=models, **law), log_targets, names)
    presses = law_nested_press_check(X, y, specimens, 1, seed, models=models, **law)
    return check.assign(press_readings=presses["readings"].to_numpy(), press_covered=presses["covered"].to_numpy(),
                        press_log_halfwidth=presses["log_halfwidth"].to_numpy())


def fit_all(models: Sequence[str], X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, perceived: pd.DataFrame,
            pad: str, condition: str, cv: str, law: dict, *, max_components: int = DEFAULT_MAX_COMPONENTS,
            seed: int = 0) -> list[ConditionFit]:
    """Every requested family on one pad x condition x CV scheme, under the same folds, in the order asked; a LOSO
    fit carries its held-out flags and interval check from the start."""
    fits = [family_fit(model, X, y, meta, perceived, pad, condition, cv, law=law, max_components=max_components)
            for model in models]
    if cv == "loso":
        for fit in fits:
            specimens = meta["specimen"].astype(str).to_numpy()
            fit.held_out_flags = held_out_flags(fit, X, y, specimens, law)
            fit.interval_check = interval_check(fit, X, y, specimens, law, seed)
    return fits
