"""Training one model file's worth: a study, a pad and a condition become a cross-validated model of a family.

This is ``roughsense fit`` without the command line: the CLI parses options, calls :func:`train_model`, prints
the CV result and writes the file. Nothing here prints or writes, so a notebook gets the same model as the CLI.
Nothing here names a family either: the registry's family (model/registry.py) runs the CV ``fit`` asks for and fits
the model (``pls``, the paper's, chooses its component count by CV; the peak law, ``peak-law``, the default,
chooses nothing, so its CV only reports how well it predicts held-out trials beside the training mean), and it says
which options it takes. Whatever the CV, every model is also judged as the study judges it for new surfaces
(analysis/assessment.py): the file records its controls, its 90 % interval and its applicability domain.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import defaults
from .._util.checks import Options, check
from ..errors import ConfigError, InputError
from ..io.sensor_settings import Roi
from ..io.study import MANIFEST_CSV, RATINGS_CSV, Study
from ..model import gate_file
from ..model.family import FoldSettings, TrainingSet
from ..model.folds import fold_ids
from ..model.modelfile import feature_definition_for
from ..model.registry import check_model_name, default_model, engine, family, registry
from ..model.training_file import UNJUDGED
from ..paper import PAPER_CONDITIONS as CONDITIONS
from . import dataset
from .assessment import UnseenAssessment, assess_unseen
from .controls import fold_mean_predictions
from .geometry import specimen_geometries
from .presses import presses_curve, presses_needed


@dataclass(frozen=True)
class TrainedModel:
    """A fitted model with its cross-validation and the record a model file keeps.

    ``model``: the family's fitted estimator (its registry engine writes its model-file section); ``cv``: the CV
    ``fit`` ran, as the family reports it (``cv.scheme`` names the folds); ``n_components``: the count chosen (1
    where the family chooses nothing)."""

    model: object
    cv: object
    n_components: int
    feature_definition: dict
    training: dict
    n_samples: int
    n_features: int
    family: str
    unseen: UnseenAssessment | None = None


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
    """Refuse options before any image is read; returns the model family's name (default: fit's default on a study
    whose rectangles are one land/groove geometry; :func:`train_model` chooses it by the study's own).

    An option only some families take (``rule`` and ``max_components`` choose PLS's component count) is refused
    with a family that does not declare it (model/registry.py), rather than silently ignored; its value is the
    family's to check.
    """
    name = check_model_name(model) if model is not None else default_model()
    check(condition, Options(CONDITIONS), name="--condition", must=f"one of {', '.join(CONDITIONS)}")
    options = _family_options(name, {"rule": rule, "max_components": max_components})
    engine(name).check_options(options)
    return name


def _family_options(name: str, given: dict) -> dict:
    """The family's declared options by keyword; one it does not declare, given, is refused naming a family that
    takes it."""
    chosen = family(name)
    declared = {option.keyword for option in chosen.options}
    for keyword, value in given.items():
        if value is None or keyword in declared:
            continue
        owner, option = next((f, o) for f in registry() for o in f.options if o.keyword == keyword)
        raise ConfigError(f"{option.flag} {option.purpose}; the {chosen.title} takes no {option.flag} (drop "
                          f"{option.flag} or use --model {owner.name})")
    return {keyword: given.get(keyword) for keyword in sorted(declared)}


def training_data(study: Study, pad: str, condition: str, *, n_jobs: int = 1,
                  progress: Callable | None = None) -> tuple[np.ndarray, np.ndarray, pd.DataFrame, tuple]:
    """X, y, their trials (specimen, repetition, images) and their contact measures (``condition_contact``: the
    array and its names) for one pad and condition; only those images are read."""
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
    return X, y, meta, dataset.condition_contact(features, meta, condition)


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


def train_model(study: Study, *, pad: str, condition: str, cv: str | int = "loo", rule: str | None = None,
                seed: int = defaults.SEED, max_components: int | None = None, study_path: str = "", n_jobs: int = 1,
                progress: Callable | None = None, model: str | None = None, roi: Roi | None = None) -> TrainedModel:
    """Cross-validate and fit the family's model on every trial (PLS: its count chosen by ``rule``, the paper's
    §3.3, "min" by default; the peak law: the pad's ridge period left out of its peak search), and the
    contact-image gate. ``roi`` reads the line there instead of at the study's [sensor] roi; the model file records
    both.
    """
    if model is None:  # fit's default, by what the study's design can tell apart (model/registry.py)
        model = default_model(bool(specimen_geometries(study.specimens)[0]))
    name = check_training_options(condition, rule, max_components, model)
    study_roi = study.sensor.roi
    if roi is not None:
        study = dataclasses.replace(study, sensor=dataclasses.replace(study.sensor, roi=roi))
    X, y, meta, (contact, contact_names) = training_data(study, pad, condition, n_jobs=n_jobs, progress=progress)
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
    _refuse_constant_spectra(X, what, study.root / MANIFEST_CSV)  # any family: copies of one image teach nothing
    training["target_range"] = [float(np.min(y)), float(np.max(y))]
    training["pad_ridge_period_mm"] = study.pad_ridge_period_mm.get(pad)  # predict's band and scale checks read it
    training.update(training_gate(study, pad, condition, seed=seed, n_jobs=n_jobs, progress=progress))
    specimens = meta["specimen"].astype(str).to_numpy()
    settings = FoldSettings(np.asarray(spectrum.freq_per_mm_), len(definition["conditions"]),
                            study.pad_ridge_period_mm.get(pad), specimens, contact, contact_names)
    options = _family_options(name, {"rule": rule, "max_components": max_components})
    groups = meta["specimen"].to_numpy()
    try:  # the folds of ``cv``, the same for every family (the seed shuffles K folds as PLS's own CV does)
        folds, fold_scheme = fold_ids(len(y), None if cv == "loso" else cv, groups if cv == "loso" else None, seed)
    except ConfigError as exc:
        raise ConfigError(f"{exc.message} ({what})") from None
    fitted = engine(name).train(TrainingSet(X, y, groups, cv, seed, folds, fold_scheme,
                                            fold_mean_predictions(y, folds), settings, options, what,
                                            study.root / MANIFEST_CSV))
    training.update(fitted.record)
    trained = TrainedModel(fitted.model, fitted.cv, fitted.n_components, definition, training, int(len(y)),
                           int(X.shape[1]), family=name)
    return _judged(trained, X, y, meta, study, settings, max_components=max_components, seed=seed)


def _judged(trained: TrainedModel, X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, study: Study,
            settings: FoldSettings, *, max_components: int | None, seed: int) -> TrainedModel:
    """The model judged as the study judges it for new surfaces, its interval and the presses a surface needs,
    added to its record (a design too small to judge says so)."""
    training, name = trained.training, trained.family
    pad, condition = training["pad"], training["condition"]
    law = settings.keywords()
    try:
        unseen = assess_unseen(name, X, y, meta, dataset.perceived_roughness(study), pad=pad, condition=condition,
                               law=law, max_components=max_components or defaults.MAX_COMPONENTS, seed=seed)
    except InputError as exc:  # a design too small for leave-one-specimen-out: said, never silently skipped
        training["unseen"] = {"cv": "loso (nested)", "passes_controls": None,
                              "failure": f"{UNJUDGED} for a grating left out of training "
                                         f"({exc.message}); its predictions for new surfaces are untested and carry no "
                                         "interval"}
        return trained
    training["unseen"] = unseen.record()
    training.update(unseen.interval_record())
    # How many presses a surface needs (analysis/presses.py; None: presses read alone); predict warns below it.
    curve = presses_curve(X, y, law["surfaces"], law, seed, model=name)
    if curve is not None:
        training["presses"] = {"needed": presses_needed(curve), "null_rmse": float(curve["null_rmse"].iloc[0]),
                               "rmse_by_presses": {str(int(k)): float(v) for k, v in zip(curve["n_presses"],
                                                                                        curve["rmse"])}}
    return dataclasses.replace(trained, unseen=unseen)


#: Spectra whose spread across trials is below this fraction of their size are the same spectrum (rounding noise).
CONSTANT_SPECTRA_RTOL = 1e-9


def _refuse_constant_spectra(X: np.ndarray, what: str, manifest_path) -> None:
    """Refuse spectra that do not vary between trials: PLS would fit rounding noise (or find no component)."""
    spread = float(np.ptp(X, axis=0).max()) if X.size else 0.0
    if spread <= CONSTANT_SPECTRA_RTOL * float(np.abs(X).max(initial=0.0)):
        raise InputError(f"every trial of {what} has the same spectrum (are the images copies of one?); "
                         "a model needs spectra that differ between specimens", path=manifest_path)


