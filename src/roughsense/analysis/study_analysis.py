"""The paper's analysis of a study folder: every pad x predictor set, cross-validated, tabulated and tested.

For each pad and condition (1N, 2N, 3N, combined) it chooses the number of PLS components by
cross-validation (LOO as in the paper, and leave-one-specimen-out as the honest estimate for a
specimen never seen in training), keeps the out-of-fold predictions at that count, and judges them
per specimen by RMSE against the perceived geometric mean and by the overlap coefficient.

Beside the paper's PLS, every requested model family (``models``; roughsense.model.families) is
cross-validated under the same folds and judged the same way: the peak power law
(roughsense.model.peak_law), built for surfaces never seen in training, has nothing to choose from the
targets, so its out-of-fold predictions are its fit on each training fold.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pandas as pd

from .. import paper
from ..errors import ConfigError, InputError
from ..io.study import MANIFEST_CSV, RATINGS_CSV, Study
from ..model.families import MODEL_FAMILIES, check_model_name
from ..model.pls_cv import DEFAULT_MAX_COMPONENTS
from . import controls as _controls
from . import dataset
from .claims import evaluate_claims
from .family_fits import ConditionFit, fit_all, law_settings  # noqa: F401 (re-exported for one release)
from .held_out import held_out_analysis
from .presses import presses_analysis
from .results import CV_SCHEMES, RESULT_COLUMNS, StudyAnalysis  # noqa: F401 (re-exported)
from .signed_rank_tests import paper_comparability, signed_rank_tests
from .spread import paper_predictive


def analyse_study(study: Study, *, features: pd.DataFrame | None = None, max_components: int = DEFAULT_MAX_COMPONENTS,
                  conditions: Sequence[str] = paper.PAPER_CONDITIONS, cv_schemes: Sequence[str] = CV_SCHEMES,
                  n_jobs: int = 1, progress: Callable | None = None, n_permutations: int = _controls.DEFAULT_PERMUTATIONS,
                  seed: int = 0, combined_forces: Sequence[str] | None = None,
                  models: Sequence[str] = MODEL_FAMILIES, stricter: bool = True) -> StudyAnalysis:
    """The paper's whole analysis of a validated study, with every model's controls and the claims' verdicts.

    Parameters
    ----------
    study, features : Study, pandas.DataFrame
        A study with ratings (:func:`read_study`); its spectra if already computed (e.g. cached), else made here.
    max_components, conditions, cv_schemes
        PLS components cross-validated; force conditions ("1N", ..., "combined"); "loo" (the paper's) and/or "loso"
        (leave one specimen out). ``combined_forces``: what "combined" joins (1N, 2N, 3N). ``stricter``: also a
        period and a shape left out, and presses per surface (``held_out``, ``presses``; a sweep cell skips them).
    n_permutations, seed, models
        Specimen-level shufflings of the permutation control and their seed; the families fitted under the same
        folds and controls ("pls", "peak-law"; claims and signed-rank tests are the paper's PLS).
    n_jobs, progress : int, callable
        Threads computing the features; a wrapper of long loops (e.g. a progress bar).

    Returns
    -------
    StudyAnalysis
        ``results("loo"|"loso")``, ``controls``, ``claims``, ``held_out``, ``presses``: the report's content.

    Examples
    --------
    >>> import roughsense as rs
    >>> from roughsense.sim import SimulationConfig
    >>> config = SimulationConfig(pads=("smooth",), specimens=("R2", "R3", "R4", "C3", "C4"), forces_n=(2.0,),
    ...                           repetitions=2)
    >>> study = rs.read_study(rs.simulate_study("simulated", config))
    >>> analysis = rs.analyse_study(study, conditions=["2N"], max_components=3, n_permutations=19)
    >>> loso = analysis.results("loso")
    >>> list(loso.columns[:6]), sorted(set(loso["model"]))
    (['pad', 'specimen', 'condition', 'pred_mean', 'pred_sd', 'ovl'], ['peak-law', 'pls'])
    >>> list(analysis.controls[["cv", "model"]].itertuples(index=False, name=None))
    [('loo', 'pls'), ('loso', 'pls'), ('loo', 'peak-law'), ('loso', 'peak-law')]
    """
    models = _check_models(models)
    _controls.check_permutations(n_permutations)  # before the features: the shufflings are held in memory at once
    perceived = _perceived_by_enough_people(study)
    if features is None:
        features = dataset.study_features(study, n_jobs=n_jobs, progress=progress)
    _check_repetitions(features, study)
    analysis = _empty_analysis(study, perceived, features, max_components, seed, models)
    analysis.paper_pads, analysis.paper_note = paper_comparability(
        study.specimen_names, study.pads, conditions, study.reference_specimen)
    jobs = [(pad, condition, cv) for pad in study.pads for condition in conditions for cv in cv_schemes]
    iterator = progress(jobs, total=len(jobs), description="cross-validating") if progress else jobs
    control_jobs = _fit_every_condition(analysis, iterator, features, study, combined_forces, n_permutations)
    analysis.controls = _controls.run_controls(control_jobs, n_jobs=n_jobs, progress=progress)
    # The shufflings are default_rng(seed)'s: rerun with it to get them back. "model" stays the last column.
    analysis.controls.insert(len(_controls.CONTROL_COLUMNS), "seed", int(seed))
    analysis.held_out, analysis.presses = _stricter(analysis, control_jobs) if stricter else (pd.DataFrame(),) * 2
    analysis.tests = signed_rank_tests(analysis, conditions)
    analysis.paper_predictive = paper_predictive()
    analysis.claims = evaluate_claims(analysis)
    return analysis


def _stricter(analysis: StudyAnalysis, control_jobs: list[tuple]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A period and a shape left out (held_out.py), and presses per surface (presses.py), from the LOSO fits."""
    return held_out_analysis(analysis, control_jobs), presses_analysis(analysis, control_jobs)


def _check_models(models: Sequence[str]) -> tuple[str, ...]:
    """The requested families by name (case-insensitive), each once; one line naming the choices otherwise."""
    if isinstance(models, str):
        models = (models,)
    checked = tuple(dict.fromkeys(check_model_name(m, option="models") for m in models))
    if not checked:
        raise ConfigError(f"models must name at least one of {', '.join(MODEL_FAMILIES)}")
    return checked


def _perceived_by_enough_people(study: Study) -> pd.DataFrame:
    """The study's targets, refused where a specimen has fewer than the 2 raters that its SD and OVL need."""
    if study.ratings is None:
        raise InputError("the study has no ratings.csv; the analysis needs participants' ratings", path=study.root)
    perceived = dataset.perceived_roughness(study)
    rated = perceived[perceived["specimen"] != study.reference_specimen]
    lonely = rated[rated["n_participants"] < 2]
    if not lonely.empty:
        raise InputError(
            f"specimen {lonely['specimen'].iloc[0]} is rated by only {int(lonely['n_participants'].iloc[0])} participant; "
            "the analysis compares predictions with the spread across participants (SD, OVL), so every specimen "
            "needs ratings from at least 2", path=study.root / RATINGS_CSV)
    return perceived


def _check_repetitions(features: pd.DataFrame, study: Study) -> None:
    """Cross-validation needs at least 2 images of each specimen on each pad at each force."""
    counts = features.groupby(["pad", "specimen", "condition"]).size()
    if counts.min() < 2:
        (pad, specimen, condition) = counts.idxmin()
        raise InputError(
            f"too few repetitions for cross-validation: {specimen} on the {pad} pad at {condition} has {counts.min()}",
            path=study.root / MANIFEST_CSV,
        )


def _empty_analysis(study: Study, perceived: pd.DataFrame, features: pd.DataFrame, max_components: int,
                    seed: int, models: tuple[str, ...]) -> StudyAnalysis:
    """The analysis's record of the study (targets, shapes, mean spectra) before any model is fitted."""
    freq_columns = dataset.frequency_columns(features)
    mean_spectra = dataset.plain_names(
        features.groupby(["pad", "specimen", "condition"], sort=False)[freq_columns].mean().reset_index())
    return StudyAnalysis(
        study_name=study.name,
        reference_specimen=study.reference_specimen,
        perceived=perceived,
        shapes=dict(zip(study.specimens["specimen"], study.specimens["shape"])),
        freq_per_mm=dataset.column_frequencies(freq_columns),
        mean_spectra=mean_spectra,
        max_components=max_components,
        simulation=study.simulation,
        synthetic=study.synthetic,
        seed=int(seed),
        models=models,
        wavelengths=dict(zip(study.specimens["specimen"], pd.to_numeric(study.specimens.get(
            "wavelength_mm", pd.Series(np.nan, index=study.specimens.index)), errors="coerce"))),
    )


def _fit_every_condition(analysis: StudyAnalysis, jobs, features: pd.DataFrame, study: Study,
                         combined_forces: Sequence[str] | None, n_permutations: int) -> list[tuple]:
    """Cross-validate each (pad, condition, cv) and model into ``analysis.fits``; returns the controls' jobs.

    X, y and the shufflings are built once per pad and condition and shared by both CV schemes, every model and
    the controls (so every model faces the same shuffled targets). Jobs come back grouped by model, as the tables.
    """
    matrices: dict[tuple[str, str], tuple] = {}
    control_jobs: list[tuple] = []
    for pad, condition, cv in jobs:
        if (pad, condition) not in matrices:
            X, meta = dataset.condition_matrix(features, pad, condition, combined_forces=combined_forces)
            y = dataset.targets(meta, analysis.perceived, path=study.root / RATINGS_CSV)
            specimens = meta["specimen"].astype(str).to_numpy()
            permutations = _controls.specimen_permutations(len(pd.unique(specimens)), n_permutations, analysis.seed)
            law = law_settings(X, analysis.freq_per_mm, study.pad_ridge_period_mm.get(pad), specimens)
            matrices[(pad, condition)] = (X, y, meta, specimens, permutations, law)
        X, y, meta, specimens, permutations, law = matrices[(pad, condition)]
        for fit in fit_all(analysis.models, X, y, meta, analysis.perceived, pad, condition, cv, law,
                           max_components=analysis.max_components, seed=analysis.seed):
            analysis.fits.append(fit)
            control_jobs.append((fit, X, y, specimens, permutations, law))
    return sorted(control_jobs, key=lambda job: analysis.models.index(job[0].model))
