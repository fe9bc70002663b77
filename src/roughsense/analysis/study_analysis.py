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
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .. import paper
from ..errors import ConfigError, InputError
from ..io.study import MANIFEST_CSV, RATINGS_CSV, Study
from ..model.applicability import held_out_flags as pls_flags
from ..model.families import MODEL_FAMILIES, PEAK_LAW, PLS, check_model_name
from ..model.jackknife_plus import nested_check
from ..model.peak_law import PeakPowerLaw, peak_law_cv
from ..model.peak_law import held_out_flags as peak_law_flags
from ..model.peak_law_folds import law_nested_press_check, law_pair_log_predictions, law_pair_models, specimen_codes
from ..model.pls_cv import DEFAULT_MAX_COMPONENTS, nested_group_predictions, pls_cv
from . import controls as _controls
from . import dataset
from .claims import evaluate_claims
from .held_out import held_out_analysis
from .metrics import compare_conditions, shape_summary, signed_rank, specimen_table
from .presses import presses_analysis
from .spread import paper_predictive, predictive_ovl
from .unseen import unseen_summary

CV_SCHEMES = ("loo", "loso")
PRED_SD_DDOF = 0
#: The paper's schema first (paper_results.csv), then our additions; columns are only ever added.
RESULT_COLUMNS = ["pad", "specimen", "condition", "pred_mean", "pred_sd", "ovl", "rmse", "predictive_sd",
                  "ovl_predictive", "model"]


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


@dataclass
class StudyAnalysis:
    study_name: str
    reference_specimen: str
    perceived: pd.DataFrame
    shapes: dict[str, str]
    freq_per_mm: np.ndarray
    mean_spectra: pd.DataFrame
    fits: list[ConditionFit] = field(default_factory=list)
    tests: pd.DataFrame = field(default_factory=pd.DataFrame)
    max_components: int = DEFAULT_MAX_COMPONENTS
    #: One row per pad x condition x CV scheme (controls.CONTROL_COLUMNS): permutation test and null model.
    controls: pd.DataFrame = field(default_factory=pd.DataFrame)
    #: The paper's claims, each with our statistic, p and verdict (claims.CLAIM_COLUMNS).
    claims: pd.DataFrame = field(default_factory=pd.DataFrame)
    #: The paper's published predictions with the predictive OVL of a spread model (spread.paper_predictive).
    paper_predictive: pd.DataFrame = field(default_factory=pd.DataFrame)
    #: The study's [simulation] table (seed and settings) when a simulator wrote it; None for real data.
    simulation: dict | None = None
    #: study.toml's ``[study] synthetic``: where a folder's synthetic images came from (not measurements); None else.
    synthetic: str | None = None
    #: Whether the paper's per-specimen values describe this study, per pad, and why not where they do not.
    paper_pads: tuple[str, ...] = ()
    paper_note: str = ""
    seed: int = 0
    wavelengths: dict[str, float] = field(default_factory=dict)
    #: The model families fitted, in the order of every table (the paper's PLS first).
    models: tuple[str, ...] = (PLS,)
    #: Every LOSO fit again with a period, and a shape, held out (analysis/held_out.py; HELD_OUT_COLUMNS).
    held_out: pd.DataFrame = field(default_factory=pd.DataFrame)
    #: A held-out surface's error against the presses it is read from (analysis/presses.py; PRESS_COLUMNS).
    presses: pd.DataFrame = field(default_factory=pd.DataFrame)

    def condition_fit(self, pad: str, condition: str, cv: str = "loo", model: str = PLS) -> ConditionFit:
        """The cross-validated model of one pad, condition, CV scheme and family (a lookup: all fitted already)."""
        for item in self.fits:
            if (item.pad, item.condition, item.cv, item.model) == (pad, condition, cv, model):
                return item
        fitted = ", ".join(f"{f.model} {f.pad} {f.condition} {f.cv}" for f in self.fits) or "none"
        raise KeyError(f"no model for {model} {pad} {condition} {cv}; fitted: {fitted}")

    def ordered_fits(self) -> list[ConditionFit]:
        """The fits grouped by model family (PLS's rows first, as they were before any other family existed)."""
        return [f for model in self.models for f in self.fits if f.model == model]

    @property
    def pads(self) -> list[str]:
        return list(dict.fromkeys(f.pad for f in self.fits))

    def results(self, cv: str = "loo") -> pd.DataFrame:
        """Per-specimen results in the schema of the paper's tables (paper_results.csv)."""
        frames = []
        for item in self.ordered_fits():
            if item.cv != cv:
                continue
            table = item.table.copy()
            table.insert(0, "pad", item.pad)
            table.insert(2, "condition", item.condition)
            table["model"] = item.model
            frames.append(table[RESULT_COLUMNS])
        return pd.concat(frames, ignore_index=True)

    def predictions(self) -> pd.DataFrame:
        """Every out-of-fold prediction: one row per trial (image, or the three images of a combined trial)."""
        frames = []
        for item in self.ordered_fits():
            frame = item.predictions.copy()
            frame.insert(0, "pad", item.pad)
            frame.insert(1, "condition", item.condition)
            frame.insert(2, "cv", item.cv)
            frame["n_components"] = [item.nested_n_components.get(str(s), item.best_n_components)
                                     for s in frame["specimen"]]
            frame["model"] = item.model
            frames.append(frame)
        return pd.concat(frames, ignore_index=True)

    def cv_table(self) -> pd.DataFrame:
        """The CV curves (n_components 0 is the training mean; a peak-law fit's 1 is the law)."""
        rows = []
        for item in self.ordered_fits():
            for n_components, rmse in enumerate(item.cv_rmse):
                rows.append({"pad": item.pad, "condition": item.condition, "cv": item.cv,
                             "n_components": n_components, "rmse": float(rmse), "model": item.model})
        return pd.DataFrame(rows, columns=["pad", "condition", "cv", "n_components", "rmse", "model"])

    def chosen_components(self) -> pd.DataFrame:
        return pd.DataFrame([
            {"pad": f.pad, "condition": f.condition, "cv": f.cv, "best_n_components": f.best_n_components,
             "one_se_n_components": f.one_se_n_components, "cv_rmse": float(f.cv_rmse[f.best_n_components]),
             "model": f.model}
            for f in self.ordered_fits()
        ])

    def unseen_summary(self) -> pd.DataFrame:
        """How well each model predicts a surface it never saw: nested LOSO per model x pad x condition (unseen.py)."""
        return unseen_summary(self)

    @property
    def simulated(self) -> bool:
        return self.simulation is not None

    def summary(self, cv: str, column: str, model: str = PLS, results: pd.DataFrame | None = None) -> pd.DataFrame:
        """Mean ± SD of ``column`` over rectangular, circular and all specimens, per pad x condition, of one model.

        ``results``: ``self.results(cv)`` if the caller holds it already (a report summarises it a dozen times)."""
        results = self.results(cv) if results is None else results
        results = results[results["model"] == model]
        frames = []
        for (pad, condition), table in results.groupby(["pad", "condition"], sort=False):
            summary = shape_summary(table, self.shapes, column)
            summary.insert(0, "pad", pad)
            summary.insert(1, "condition", condition)
            frames.append(summary)
        return pd.concat(frames, ignore_index=True)


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


def _model_fits(analysis: StudyAnalysis, X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, pad: str,
                condition: str, cv: str, law: dict) -> list[ConditionFit]:
    """Every requested family on one pad x condition x CV scheme, under the same folds."""
    fits = [family_fit(model, X, y, meta, analysis.perceived, pad, condition, cv, law=law,
                       max_components=analysis.max_components) for model in analysis.models]
    return sorted(fits, key=lambda f: analysis.models.index(f.model))


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


def _signed_rank_tests(analysis: StudyAnalysis, conditions: Sequence[str]) -> pd.DataFrame:
    """Combined vs each single force per pad (Bonferroni x3), and smooth vs fingerprint on the combined condition.

    Of the paper's PLS only (tests.csv has no model column): these are the paper's own comparisons.
    """
    frames = []
    for cv in CV_SCHEMES:
        if not any(f.cv == cv and f.model == PLS for f in analysis.fits):
            continue
        results = analysis.results(cv)
        results = results[results["model"] == PLS].drop(columns="model")  # the paper's model, as the paper tested
        singles = [c for c in conditions if c != paper.COMBINED]
        for pad in analysis.pads:
            if paper.COMBINED not in conditions or not singles:
                break
            by_condition = {
                c: results[(results.pad == pad) & (results.condition == c)].set_index("specimen")["rmse"]
                for c in conditions
            }
            table = compare_conditions(by_condition, paper.COMBINED, singles, bonferroni=len(singles))
            table["comparison"] = f"{pad}: " + table["comparison"].astype(str)
            table["cv"] = cv
            frames.append(table)
        pads = analysis.pads
        if len(pads) == 2:
            first, second = sorted(pads, key=lambda p: (p != paper.SMOOTH_PAD, p))
            rows = []
            # The paper compares the pads on the combined condition only (Section 4); so do we.
            for condition in [c for c in conditions if c == paper.COMBINED] or list(conditions[-1:]):
                a = results[(results.pad == first) & (results.condition == condition)].set_index("specimen")["rmse"]
                b = results[(results.pad == second) & (results.condition == condition)].set_index("specimen")["rmse"]
                common = a.index.intersection(b.index)
                test = signed_rank(a.loc[common].to_numpy(), b.loc[common].to_numpy())
                rows.append({"comparison": f"{condition}: {first} vs {second}", "statistic": test.statistic,
                             "p": test.p, "p_adjusted": test.p, "cv": cv, "n": test.n, "method": test.method})
            frames.append(pd.DataFrame(rows))
    if not frames:
        return pd.DataFrame(columns=["comparison", "statistic", "p", "p_adjusted", "cv"])
    tests = pd.concat(frames, ignore_index=True)
    front = ["comparison", "statistic", "p", "p_adjusted", "cv"]
    return tests[front + [c for c in tests.columns if c not in front]]


def paper_comparability(specimens: Sequence[str], pads: Sequence[str], conditions: Sequence[str],
                        reference_specimen: str) -> tuple[tuple[str, ...], str]:
    """The pads whose results may stand beside the paper's, and one note on why the others may not.

    The paper's numbers describe its 14 specimens, its two pads, its three forces and their combination,
    with R3 as the reference; beside any other design they would read as a comparison that is not one.
    """
    paper_specimens = list(paper.PAPER_SPECIMENS)
    problems = []
    if set(specimens) != set(paper_specimens):
        problems.append(f"its specimens ({', '.join(map(str, specimens))}) are not the paper's "
                        f"{len(paper_specimens)} ({', '.join(paper_specimens)})")
    if list(conditions) != list(paper.PAPER_CONDITIONS):
        problems.append(f"its conditions ({', '.join(conditions)}) are not the paper's {', '.join(paper.PAPER_CONDITIONS)}")
    if reference_specimen != paper.REFERENCE_SPECIMEN:
        problems.append(f"its reference is {reference_specimen}, the paper's {paper.REFERENCE_SPECIMEN}")
    if problems:
        return (), "The paper's values are not shown: " + "; ".join(problems) + "."
    matching = tuple(p for p in pads if p in paper.PAPER_PADS)
    others = [p for p in pads if p not in paper.PAPER_PADS]
    note = ""
    if others:
        note = (f"The paper's values are not shown for the {', '.join(others)} pad(s): the paper tested only the "
                f"{' and '.join(paper.PAPER_PADS)} pads.")
    return matching, note


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
    analysis.tests = _signed_rank_tests(analysis, conditions)
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
        for fit in _model_fits(analysis, X, y, meta, pad, condition, cv, law):
            if cv == "loso":
                fit.held_out_flags = held_out_flags(fit, X, y, specimens, law)
                fit.interval_check = interval_check(fit, X, y, specimens, law, analysis.seed)
            analysis.fits.append(fit)
            control_jobs.append((fit, X, y, specimens, permutations, law))
    return sorted(control_jobs, key=lambda job: analysis.models.index(job[0].model))
