"""Training one model file's worth: a study, a pad and a condition become a cross-validated model of a family.

This is ``roughsense fit`` without the command line: the CLI parses options, calls :func:`train_model`, prints
the CV result and writes the file. Nothing here prints or writes, so a notebook gets the same model as the CLI.
``pls`` (the paper's) chooses its component count by CV; the peak law (``peak-law``, the default: the family that
passes its controls for surfaces never seen) chooses nothing from the data, so its CV only reports how well it
predicts held-out trials, beside the training mean under the same folds. Whatever the CV, every model is also judged
as the study judges it for new surfaces (analysis/assessment.py): the file records its controls, its 90 % interval
and its applicability domain.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from sklearn.base import clone

from .. import defaults
from .._util.checks import POSITIVE_INT, Options, check
from ..errors import ConfigError, InputError
from ..io.sensor_settings import Roi
from ..io.study import MANIFEST_CSV, RATINGS_CSV, Study
from ..model import gate_file
from ..model.families import check_model_name, default_family, family, paper_family, registry
from ..model.folds import FoldConfigError, fold_ids
from ..model.modelfile import feature_definition_for
from ..model.peak_law.cv import peak_law_cv
from ..model.peak_law.family import PeakLawFamily
from ..model.peak_law.law import PeakPowerLaw
from ..model.pls.applicability import SpectrumDomain, fit_domain
from ..model.pls.cv import PLSCVResult, pls_cv
from ..model.pls.simpls import SIMPLS, PLSConfigError
from ..model.training_file import UNJUDGED
from ..paper import PAPER_CONDITIONS as CONDITIONS
from . import dataset
from .assessment import UnseenAssessment, assess_unseen
from .controls import fold_mean_predictions
from .presses import presses_curve, presses_needed

RULES = ("min", "1se")


#: What the peak law's CV rows are, in order (the training mean under the same folds first, as PLS's 0 components).
LAW_CV_MODELS = ("training mean", PeakLawFamily.name)


@dataclass(frozen=True)
class LawCVResult:
    """Cross-validated peak law beside the training mean under the same folds (index 0 the mean, 1 the law)."""

    rmse: np.ndarray  # (2,)
    rmse_se: np.ndarray  # (2,): delta method on the per-fold mean squared errors, as pls_cv's
    predictions: np.ndarray  # (n, 2) out-of-fold
    folds: np.ndarray
    scheme: str


@dataclass(frozen=True)
class TrainedModel:
    """A fitted model with its cross-validation and the record a model file keeps."""

    model: SIMPLS | PeakPowerLaw
    cv: PLSCVResult | LawCVResult
    n_components: int  # PLS's chosen count; 1 for the peak law (one law, nothing chosen)
    feature_definition: dict
    training: dict
    n_samples: int
    n_features: int
    family: str = field(default_factory=lambda: paper_family().name)
    unseen: UnseenAssessment | None = None
    domain: SpectrumDomain | None = None  # PLS's applicability domain (the law's is in the fitted law)


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


def check_training_options(condition: str, rule: str | None, max_components: int | None,
                           model: str | None = None) -> str:
    """Refuse options before any image is read; returns the model family's name (default: fit's default).

    ``rule`` and ``max_components`` choose a component count: given with a family that has none to choose (the
    peak law) they are refused rather than silently ignored.
    """
    name = check_model_name(model) if model is not None else default_family().name
    check(condition, Options(CONDITIONS), name="--condition", must=f"one of {', '.join(CONDITIONS)}")
    if not family(name).chooses_components:
        chooser = next(f for f in registry() if f.chooses_components)
        for option, value in (("--rule", rule), ("--max-components", max_components)):
            if value is not None:
                raise ConfigError(f"{option} chooses {chooser.name.upper()} components; the {family(name).title} has "
                                  f"none to choose (drop {option} or use --model {chooser.name})")
        return name
    if rule is not None:
        check(rule, Options(RULES), name="--rule", must="min or 1se")
    if max_components is not None:
        check(max_components, POSITIVE_INT, name="--max-components", must="at least 1")
    return name


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


def training_gate(study: Study, pad: str, condition: str, *, seed: int, n_jobs: int = 1,
                  progress: Callable | None = None):
    """The contact-image gate (model/contact_gate.py) of the pad's training images at the model's forces, each image
    one press, calibrated over specimens: ``{KEY: its model-file section}``, or ``{}`` where none can be fitted (one
    specimen, a crop too small: predict then says the model has no gate). The images are read once more for their
    descriptors (the features' cache keeps spectra only); an image the features read cannot fail here."""
    from ..model.contact_gate import fit_gate
    from ..sensor.descriptors import descriptor_names

    rows = study.manifest[study.manifest["pad"].eq(pad)
                          & study.manifest["condition"].isin(dataset.conditions_of(condition))]
    ridge = study.pad_ridge_period_mm.get(pad)
    spectrum = dataset.spectrum_for(study, n_jobs=n_jobs)
    stream = spectrum.iter_readings([study.root / image for image in rows["image"]], ridge_period_mm=ridge)
    if progress is not None:
        stream = progress(stream, total=len(rows), description="contact-image gate")
    names = descriptor_names(ridge is not None)
    values = []
    for image, reading in zip(rows["image"], stream):
        if isinstance(reading, InputError):
            raise InputError(f"{image}: {reading.message}", path=study.root / MANIFEST_CSV)
        values.append([reading[2][n] for n in names])
    try:
        gate = fit_gate(np.array(values), names, rows["specimen"].astype(str).to_numpy(), seed=seed)
    except ValueError:
        return {}
    return {gate_file.KEY: gate_file.gate_section(gate)}


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
            X, y, max_components=defaults.MAX_COMPONENTS if max_components is None else max_components,
            cv=None if scheme == "loso" else scheme, groups=groups, random_state=seed, cap=max_components is None,
        )
    except PLSConfigError as exc:
        if exc.supported is not None and exc.supported < 1:
            cv_text = scheme if isinstance(scheme, str) else str(scheme)
            raise ConfigError(f"too few samples ({len(y)}) for {cv_text} cross-validation of {what}") from None
        raise


def train_model(study: Study, *, pad: str, condition: str, cv: str | int = "loo", rule: str | None = None,
                seed: int = defaults.SEED, max_components: int | None = None, study_path: str = "", n_jobs: int = 1,
                progress: Callable | None = None, model: str | None = None, roi: Roi | None = None) -> TrainedModel:
    """Cross-validate and fit on every trial: PLS with its count chosen by ``rule`` (the paper's §3.3, "min" by
    default), or the peak law with the pad's ridge period left out of its peak search; and the contact-image gate.
    ``roi`` reads the line there instead of at the study's [sensor] roi; the model file records both.
    """
    name = check_training_options(condition, rule, max_components, model)
    study_roi = study.sensor.roi
    if roi is not None:
        study = dataclasses.replace(study, sensor=dataclasses.replace(study.sensor, roi=roi))
    X, y, meta = training_data(study, pad, condition, n_jobs=n_jobs, progress=progress)
    spectrum = dataset.spectrum_for(study)
    definition = feature_definition_for(spectrum, dataset.conditions_of(condition))
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
    }
    if roi is not None:
        training["study_roi"] = study_roi if isinstance(study_roi, str) else list(study_roi)
    what = f"pad {pad!r} at {condition}"
    _refuse_constant_spectra(X, what, study.root / MANIFEST_CSV)  # either family: copies of one image teach nothing
    training["target_range"] = [float(np.min(y)), float(np.max(y))]
    training["pad_ridge_period_mm"] = study.pad_ridge_period_mm.get(pad)  # predict's band and scale checks read it
    training.update(training_gate(study, pad, condition, seed=seed, n_jobs=n_jobs, progress=progress))
    specimens = meta["specimen"].astype(str).to_numpy()
    law = PeakPowerLaw(freq_per_mm=np.asarray(spectrum.freq_per_mm_), n_blocks=len(definition["conditions"]),
                       pad_ridge_period_mm=study.pad_ridge_period_mm.get(pad))
    if family(name).chooses_components:  # a count to choose by ``rule``; else one fit, nothing chosen
        trained = _train_pls(X, y, meta, cv, rule=rule, seed=seed, max_components=max_components, law=law,
                             definition=definition, training=training, what=what, manifest=study.root / MANIFEST_CSV)
    else:
        trained = _train_law(law, X, y, meta, cv, seed=seed, definition=definition, training=training, what=what)
    settings = {"freq_per_mm": law.freq_per_mm, "n_blocks": law.n_blocks,
                "pad_ridge_period_mm": law.pad_ridge_period_mm, "surfaces": specimens}
    try:
        unseen = assess_unseen(name, X, y, meta, dataset.perceived_roughness(study), pad=pad, condition=condition,
                               law=settings, max_components=max_components or defaults.MAX_COMPONENTS, seed=seed)
    except InputError as exc:  # a design too small for leave-one-specimen-out: said, never silently skipped
        training["unseen"] = {"cv": "loso (nested)", "passes_controls": None,
                              "failure": f"{UNJUDGED} for a grating left out of training "
                                         f"({exc.message}); its predictions for new surfaces are untested and carry no "
                                         "interval"}
        return trained
    training["unseen"] = unseen.record()
    training.update(unseen.interval_record())
    # How many presses a surface needs (analysis/presses.py; None: presses read alone); predict warns below it.
    curve = presses_curve(X, y, specimens, settings, seed, model=name)
    if curve is not None:
        training["presses"] = {"needed": presses_needed(curve), "null_rmse": float(curve["null_rmse"].iloc[0]),
                               "rmse_by_presses": {str(int(k)): float(v) for k, v in zip(curve["n_presses"],
                                                                                        curve["rmse"])}}
    return dataclasses.replace(trained, unseen=unseen)


def _train_pls(X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, cv: str | int, *, rule: str | None, seed: int,
               max_components: int | None, law: PeakPowerLaw, definition: dict, training: dict, what: str,
               manifest) -> TrainedModel:
    """PLS: the component count chosen by ``rule`` under ``cv``, the model fitted on every trial, and its
    applicability domain (limits cross-validated over specimens; ``law``'s peak readout of the same trials)."""
    rule = rule or "min"
    result = cross_validate(X, y, meta, cv, seed=seed, max_components=max_components, what=what)
    _refuse_no_better_than_mean(result, what, manifest)
    chosen = result.best_n_components if rule == "min" else result.one_se_n_components
    training.update({
        "rule": rule,
        "max_components": int(result.max_components),
        "cv_rmse": [float(v) for v in result.rmse],
        "cv_rmse_se": [float(v) for v in result.rmse_se],
        "best_n_components": int(result.best_n_components),
        "one_se_n_components": int(result.one_se_n_components),
        "n_components": int(chosen),
    })
    fitted = SIMPLS(n_components=chosen).fit(X, y)
    domain = fit_domain(fitted, X, y, meta["specimen"].astype(str).to_numpy(), law=clone(law))
    return TrainedModel(fitted, result, int(chosen), definition, training, int(len(y)), int(X.shape[1]),
                        domain=domain)


#: Spectra whose spread across trials is below this fraction of their size are the same spectrum (rounding noise).
CONSTANT_SPECTRA_RTOL = 1e-9


def _refuse_constant_spectra(X: np.ndarray, what: str, manifest_path) -> None:
    """Refuse spectra that do not vary between trials: PLS would fit rounding noise (or find no component)."""
    spread = float(np.ptp(X, axis=0).max()) if X.size else 0.0
    if spread <= CONSTANT_SPECTRA_RTOL * float(np.abs(X).max(initial=0.0)):
        raise InputError(f"every trial of {what} has the same spectrum (are the images copies of one?); "
                         "a model needs spectra that differ between specimens", path=manifest_path)


def _refuse_no_better_than_mean(result: PLSCVResult, what: str, manifest_path) -> None:
    """Refuse a PLS model whose every component count cross-validates worse than the training mean (0 components):
    its spectra carry nothing the CV can find about the ratings, and a model file would predict noise."""
    best = int(np.argmin(result.rmse[1:])) + 1
    if not result.rmse[best] < result.rmse[0]:
        raise InputError(f"no PLS component count beats the training mean for {what} in cross-validation (CV RMSE "
                         f"{result.rmse[best]:.4g} at {best} vs {result.rmse[0]:.4g} with none); the spectra do not "
                         "predict the ratings, so no model is written", path=manifest_path)


def _train_law(law: PeakPowerLaw, X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, scheme: str | int, *,
               seed: int, definition: dict, training: dict, what: str) -> TrainedModel:
    """The peak law's CV beside the training mean's, and the law fitted on every trial (nothing is chosen)."""
    try:
        result = cross_validate_law(law, X, y, meta, scheme, seed=seed)
        fitted = law.fit(X, y, surfaces=meta["specimen"].astype(str).to_numpy())
    except FoldConfigError as exc:
        raise ConfigError(f"{exc.message} ({what})") from None
    except ValueError as exc:
        raise ConfigError(f"the peak law cannot be fitted to {what}: {exc}") from None
    training.update({
        "model": PeakLawFamily.name,
        "cv_models": list(LAW_CV_MODELS),
        "cv_rmse": [float(v) for v in result.rmse],
        "cv_rmse_se": [float(v) for v in result.rmse_se],
    })
    return TrainedModel(fitted, result, 1, definition, training, int(len(y)), int(X.shape[1]), family=PeakLawFamily.name)


def cross_validate_law(law: PeakPowerLaw, X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, scheme: str | int, *,
                       seed: int) -> LawCVResult:
    """Out-of-fold predictions of the training mean and of ``law`` (its parameters) under the folds of ``scheme``.

    The folds are pls_cv's own (LOO, leave-one-specimen-out, or shuffled K-fold from ``seed``), so a peak law's
    RMSE and a PLS curve from the same options are on the same held-out trials.
    """
    y = np.asarray(y, dtype=np.float64)
    n = y.size
    groups = meta["specimen"].to_numpy() if scheme == "loso" else None
    fid, name = fold_ids(n, None if scheme == "loso" else scheme, groups, seed)
    law_predictions = peak_law_cv(X, y, groups=fid, freq_per_mm=law.freq_per_mm, n_blocks=law.n_blocks,
                                  pad_ridge_period_mm=law.pad_ridge_period_mm, exclusion_per_mm=law.exclusion_per_mm,
                                  epsilon=law.epsilon, surfaces=meta["specimen"].astype(str).to_numpy())[0]
    n_folds = int(fid.max()) + 1
    fold_size = np.bincount(fid, minlength=n_folds)
    predictions = np.column_stack([fold_mean_predictions(y, fid), law_predictions])
    err2 = (predictions - y[:, None]) ** 2
    rmse = np.sqrt(err2.mean(axis=0))
    fold_mse = np.stack([np.bincount(fid, weights=e, minlength=n_folds) for e in err2.T], axis=1) / fold_size[:, None]
    se_mse = fold_mse.std(axis=0, ddof=1) / np.sqrt(n_folds)
    rmse_se = np.divide(se_mse, 2 * rmse, out=np.zeros_like(rmse), where=rmse > 0)
    return LawCVResult(rmse=rmse, rmse_se=rmse_se, predictions=predictions, folds=fid, scheme=name)


def law_table(result: LawCVResult) -> pd.DataFrame:
    """The peak law's CV as printed by ``fit``: the training mean and the law, RMSE and SE under the same folds."""
    return pd.DataFrame({"model": list(LAW_CV_MODELS), "rmse": result.rmse, "rmse_se": result.rmse_se})


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
