"""The paper's analysis of a study folder: every pad x predictor set, cross-validated, tabulated and tested.

For each pad and condition (1N, 2N, 3N, combined) it chooses the number of PLS components by
cross-validation (LOO as in the paper, and leave-one-specimen-out as the honest estimate for a
specimen never seen in training), keeps the out-of-fold predictions at that count, and judges them
per specimen by RMSE against the perceived geometric mean and by the overlap coefficient.

Beside the paper's PLS, every requested model family (``models``; roughsense.model.registry) is
cross-validated under the same folds and judged the same way: the peak power law
(roughsense.model.peak_law.law), built for surfaces never seen in training, has nothing to choose from the
targets, so its out-of-fold predictions are its fit on each training fold.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import pandas as pd

from .. import defaults, paper
from ..errors import ConfigError, InputError
from ..io.study import RATINGS_CSV, Study
from ..model.registry import MODEL_FAMILIES, check_model_name
from . import controls as _controls
from . import dataset
from .claims import evaluate_claims
from .family_fits import FamilyFit, fit_all, law_settings
from .held_out import stricter_schemes
from .results import (
    CV_SCHEMES,
    Controls,
    CrossValidation,
    PaperComparisons,
    RunSettings,
    StricterSchemes,
    StudyFacts,
    StudyResults,
)
from .signed_rank_tests import signed_rank_tests
from .spread import paper_predictive
from .unseen import unseen_surfaces


def analyse_study(study: Study, *, features: pd.DataFrame | None = None, max_components: int = defaults.MAX_COMPONENTS,
                  conditions: Sequence[str] = paper.PAPER_CONDITIONS, cv_schemes: Sequence[str] = CV_SCHEMES,
                  n_jobs: int = 1, progress: Callable | None = None, n_permutations: int = defaults.PERMUTATIONS,
                  seed: int = defaults.SEED, combined_forces: Sequence[str] | None = None,
                  models: Sequence[str] = MODEL_FAMILIES, stricter: bool = True) -> StudyResults:
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
        folds and controls (names in roughsense.model.registry; claims and signed-rank tests are the paper's).
    n_jobs, progress : int, callable
        Threads computing the features; a wrapper of long loops (e.g. a progress bar).

    Returns
    -------
    StudyResults
        Frozen, assembled once from the stages' records (roughsense.analysis.results), every table computed once:
        ``results("loo"|"loso")``, ``controls``, ``claims``, ``held_out``, ``presses``, ``unseen``,
        ``headline_condition`` and ``provenance``: what the report renders.

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
    (['pad', 'specimen', 'condition', 'pred_mean', 'pred_sd', 'ovl'], ['groove', 'peak-law', 'pls'])
    >>> list(analysis.controls[["cv", "model"]].itertuples(index=False, name=None))  # doctest: +NORMALIZE_WHITESPACE
    [('loo', 'pls'), ('loso', 'pls'), ('loo', 'peak-law'), ('loso', 'peak-law'), ('loo', 'groove'),
     ('loso', 'groove')]
    """
    _check_arguments(study, n_jobs, progress)
    models = _check_models(models)
    _controls.check_permutations(n_permutations)  # before the features: the shufflings are held in memory at once
    perceived = _perceived_by_enough_people(study)
    if features is None:
        features = dataset.study_features(study, n_jobs=n_jobs, progress=progress)
    dataset.check_repetitions(features, study)
    run = RunSettings(tuple(conditions), tuple(cv_schemes), max_components, int(seed), n_permutations)
    facts = StudyFacts.of(study, perceived, features, run.conditions)
    cross_validation, jobs = _fit_every_condition(facts, run, models, features, study, combined_forces, progress)
    controls = _controls_table(jobs, run.seed, n_jobs, progress)
    schemes = stricter_schemes(facts, run, controls, jobs) if stricter else StricterSchemes.skipped()
    comparisons = PaperComparisons(signed_rank_tests(cross_validation, run.conditions),
                                   evaluate_claims(facts, cross_validation, controls.controls), paper_predictive())
    unseen = unseen_surfaces(facts, run, cross_validation, controls)
    return StudyResults.assemble(facts, run, cross_validation, controls, schemes, comparisons, unseen)


def _controls_table(jobs: list[tuple], seed: int, n_jobs: int, progress: Callable | None) -> Controls:
    """controls.csv: every fit against the training mean and the shuffled targets (controls.py)."""
    controls = _controls.run_controls(jobs, n_jobs=n_jobs, progress=progress)
    # The shufflings are default_rng(seed)'s: rerun with it to get them back. "model" stays the last column.
    controls.insert(len(_controls.CONTROL_COLUMNS), "seed", int(seed))
    return Controls(controls)


def _check_arguments(study, n_jobs, progress) -> None:
    """The public call's arguments refused at the edge, each named (``_util/arguments.py``)."""
    from .._util.arguments import callable_argument, jobs_argument

    if not hasattr(study, "manifest"):
        raise ConfigError(f"study must be what read_study returned, got {type(study).__name__}")
    jobs_argument(n_jobs)
    callable_argument(progress)


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


def _fit_every_condition(facts: StudyFacts, run: RunSettings, models: tuple[str, ...], features: pd.DataFrame,
                         study: Study, combined_forces: Sequence[str] | None,
                         progress: Callable | None) -> tuple[CrossValidation, list[tuple]]:
    """Cross-validate each (pad, condition, cv) and model: the fits, and the controls' jobs.

    X, y and the shufflings are built once per pad and condition and shared by both CV schemes, every model and
    the controls (so every model faces the same shuffled targets). Jobs come back grouped by model, as the tables.
    """
    jobs = [(pad, condition, cv) for pad in study.pads for condition in run.conditions for cv in run.cv_schemes]
    if progress:
        jobs = progress(jobs, total=len(jobs), description="cross-validating")
    matrices: dict[tuple[str, str], tuple] = {}
    fits: list[FamilyFit] = []
    control_jobs: list[tuple] = []
    for pad, condition, cv in jobs:
        if (pad, condition) not in matrices:
            X, meta = dataset.condition_matrix(features, pad, condition, combined_forces=combined_forces)
            y = dataset.targets(meta, facts.perceived, path=study.root / RATINGS_CSV)
            specimens = meta["specimen"].astype(str).to_numpy()
            permutations = _controls.specimen_permutations(len(pd.unique(specimens)), run.n_permutations, run.seed)
            contact = dataset.condition_contact(features, meta, condition, combined_forces)
            law = law_settings(X, facts.freq_per_mm, study.pad_ridge_period_mm.get(pad), specimens, *contact)
            matrices[(pad, condition)] = (X, y, meta, specimens, permutations, law)
        X, y, meta, specimens, permutations, law = matrices[(pad, condition)]
        for fit in fit_all(models, X, y, meta, facts.perceived, pad, condition, cv, law,
                           max_components=run.max_components, seed=run.seed):
            fits.append(fit)
            control_jobs.append((fit, X, y, specimens, permutations, law))
    return CrossValidation(models, tuple(fits)), sorted(control_jobs, key=lambda job: models.index(job[0].model))
