"""Training one model file's worth of PLS1: a study, a pad and a condition become a cross-validated SIMPLS.

This is ``roughsense fit`` without the command line: the CLI parses options, calls :func:`train_model`, prints
the CV curve and writes the file. Nothing here prints or writes, so a notebook gets the same model as the CLI.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .._util.checks import POSITIVE_INT, Options, check
from ..errors import ConfigError, InputError
from ..io.study import MANIFEST_CSV, RATINGS_CSV, Study
from ..model.modelfile import feature_definition_for
from ..model.pls import SIMPLS
from ..model.pls_cv import DEFAULT_MAX_COMPONENTS, PLSConfigError, PLSCVResult, pls_cv
from ..paper import PAPER_CONDITIONS as CONDITIONS
from . import dataset

RULES = ("min", "1se")


@dataclass(frozen=True)
class TrainedModel:
    """A fitted model with the cross-validation that chose it and the record a model file keeps."""

    model: SIMPLS
    cv: PLSCVResult
    n_components: int
    feature_definition: dict
    training: dict
    n_samples: int
    n_features: int


def parse_cv(text: str) -> str | int:
    """'loo' | 'loso' | K (shuffled K-fold, K >= 2), case and spaces ignored."""
    value = text.strip().lower()
    if value in ("loo", "loso"):
        return value
    try:
        k = int(value)
    except ValueError:
        raise ConfigError(f"--cv must be loo, loso or a number of folds, got {text!r}") from None
    if k < 2:
        raise ConfigError(f"--cv K-fold needs K >= 2, got {k}")
    return k


def check_training_options(condition: str, rule: str, max_components: int | None) -> None:
    """Refuse options before any image is read."""
    check(condition, Options(CONDITIONS), name="--condition", must=f"one of {', '.join(CONDITIONS)}")
    check(rule, Options(RULES), name="--rule", must="min or 1se")
    if max_components is not None:
        check(max_components, POSITIVE_INT, name="--max-components", must="at least 1")


def training_data(study: Study, pad: str, condition: str, *, n_jobs: int = 1,
                  progress: Callable | None = None) -> tuple[np.ndarray, np.ndarray, pd.DataFrame]:
    """X, y and their trials (specimen, repetition, images) for one pad and condition; only those images are read."""
    manifest_path = study.root / MANIFEST_CSV
    if pad not in study.pads:
        raise InputError(f"no images of pad {pad!r} (pads in the study: {', '.join(study.pads)})", path=manifest_path)
    needed = study.manifest["pad"].eq(pad) & study.manifest["condition"].isin(dataset.conditions_of(condition))
    if not needed.any():
        present = sorted(set(study.manifest.loc[study.manifest["pad"].eq(pad), "condition"]))
        raise InputError(
            f"no images of pad {pad!r} at {condition} (conditions present: {', '.join(present)})", path=manifest_path
        )
    subset = dataclasses.replace(study, manifest=study.manifest[needed].reset_index(drop=True))
    features = dataset.study_features(subset, n_jobs=n_jobs, progress=progress)
    X, meta = dataset.condition_matrix(features, pad, condition, source=manifest_path)
    y = dataset.targets(meta, dataset.perceived_roughness(study), path=study.root / RATINGS_CSV)
    return X, y, meta


def cross_validate(X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, scheme: str | int, *, seed: int,
                   max_components: int | None, what: str) -> PLSCVResult:
    """PLS CV over 0..max components; the default maximum shrinks to what the folds support, a user's does not.

    How many components the data support is pls_cv's to say (rank, smallest training fold): a maximum the user
    did not give is capped there, and data that support none are refused in words that name the problem.
    """
    groups = meta["specimen"].to_numpy() if scheme == "loso" else None
    # The seed, not a Generator: a capped retry must shuffle the K folds exactly as the first try did.
    try:
        return pls_cv(
            X, y, max_components=DEFAULT_MAX_COMPONENTS if max_components is None else max_components,
            cv=None if scheme == "loso" else scheme, groups=groups, random_state=seed, cap=max_components is None,
        )
    except PLSConfigError as exc:
        if exc.supported is not None and exc.supported < 1:
            cv_text = scheme if isinstance(scheme, str) else str(scheme)
            raise ConfigError(f"too few samples ({len(y)}) for {cv_text} cross-validation of {what}") from None
        raise


def train_model(study: Study, *, pad: str, condition: str, cv: str | int = "loo", rule: str = "min", seed: int = 0,
                max_components: int | None = None, study_path: str = "", n_jobs: int = 1,
                progress: Callable | None = None) -> TrainedModel:
    """Cross-validate, choose the component count by ``rule``, and fit on every trial (the paper's §3.3)."""
    check_training_options(condition, rule, max_components)
    X, y, meta = training_data(study, pad, condition, n_jobs=n_jobs, progress=progress)
    result = cross_validate(X, y, meta, cv, seed=seed, max_components=max_components,
                            what=f"pad {pad!r} at {condition}")
    chosen = result.best_n_components if rule == "min" else result.one_se_n_components
    model = SIMPLS(n_components=chosen).fit(X, y)
    definition = feature_definition_for(dataset.spectrum_for(study), dataset.conditions_of(condition))
    training = {
        "study": study.name,
        "study_path": study_path,
        "pad": pad,
        "condition": condition,
        "n_samples": int(len(y)),
        "specimens": sorted(map(str, meta["specimen"].unique())),
        "reference_specimen": study.reference_specimen,
        "cv": cv if isinstance(cv, str) else f"{cv}-fold",
        "seed": int(seed),
        "rule": rule,
        "max_components": int(result.max_components),
        "cv_rmse": [float(v) for v in result.rmse],
        "cv_rmse_se": [float(v) for v in result.rmse_se],
        "best_n_components": int(result.best_n_components),
        "one_se_n_components": int(result.one_se_n_components),
        "n_components": int(chosen),
    }
    return TrainedModel(model, result, int(chosen), definition, training, int(len(y)), int(X.shape[1]))


def curve_table(result: PLSCVResult, chosen: int) -> pd.DataFrame:
    """The CV curve as printed by ``fit``: RMSE and its SE per component count, the minimum, 1-SE and chosen marked."""
    marks = []
    for k in range(result.rmse.size):
        tags = []
        if k == result.best_n_components:
            tags.append("min")
        if k == result.one_se_n_components:
            tags.append("1-SE")
        if k == chosen:
            tags.append("chosen")
        marks.append(", ".join(tags))
    return pd.DataFrame(
        {"components": range(result.rmse.size), "rmse": result.rmse, "rmse_se": result.rmse_se, "note": marks}
    )
