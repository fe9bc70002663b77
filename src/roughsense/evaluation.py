"""The paper's analysis of a study folder: every pad x predictor set, cross-validated, tabulated and tested.

For each pad and condition (1N, 2N, 3N, combined) it chooses the number of PLS components by
cross-validation (LOO as in the paper, and leave-one-specimen-out as the honest estimate for a
specimen never seen in training), keeps the out-of-fold predictions at that count, and judges them
per specimen by RMSE against the perceived geometric mean and by the overlap coefficient.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from . import dataset
from .errors import InputError
from .metrics import compare_conditions, shape_summary, signed_rank, specimen_table
from .perception import aggregate_ratings
from .pls import pls_cv
from .study import Study

CONDITIONS = ("1N", "2N", "3N", "combined")
CV_SCHEMES = ("loo", "loso")
PRED_SD_DDOF = 0
RESULT_COLUMNS = ["pad", "specimen", "condition", "pred_mean", "pred_sd", "ovl", "rmse"]


@dataclass
class ConditionFit:
    """One pad x condition x CV scheme: the CV curve, the chosen count and the per-specimen table.

    ``predictions`` holds one out-of-fold prediction per trial (specimen, repetition, image, prediction).
    For LOSO they are nested: each held-out specimen's component count is chosen by LOSO over the other
    specimens only (``nested_n_components``), so no choice ever sees the specimen it predicts.
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
    max_components: int = 20

    def fit(self, pad: str, condition: str, cv: str = "loo") -> ConditionFit:
        for item in self.fits:
            if (item.pad, item.condition, item.cv) == (pad, condition, cv):
                return item
        raise KeyError((pad, condition, cv))

    @property
    def pads(self) -> list[str]:
        return list(dict.fromkeys(f.pad for f in self.fits))

    def results(self, cv: str = "loo") -> pd.DataFrame:
        """Per-specimen results in the schema of the paper's tables (paper_results.csv)."""
        frames = []
        for item in self.fits:
            if item.cv != cv:
                continue
            table = item.table.copy()
            table.insert(0, "pad", item.pad)
            table.insert(2, "condition", item.condition)
            frames.append(table[RESULT_COLUMNS])
        return pd.concat(frames, ignore_index=True)

    def predictions(self) -> pd.DataFrame:
        """Every out-of-fold prediction: one row per trial (image, or the three images of a combined trial)."""
        frames = []
        for item in self.fits:
            frame = item.predictions.copy()
            frame.insert(0, "pad", item.pad)
            frame.insert(1, "condition", item.condition)
            frame.insert(2, "cv", item.cv)
            frame["n_components"] = [item.nested_n_components.get(str(s), item.best_n_components)
                                     for s in frame["specimen"]]
            frames.append(frame)
        return pd.concat(frames, ignore_index=True)

    def cv_table(self) -> pd.DataFrame:
        rows = []
        for item in self.fits:
            for n_components, rmse in enumerate(item.cv_rmse):
                rows.append({"pad": item.pad, "condition": item.condition, "cv": item.cv,
                             "n_components": n_components, "rmse": float(rmse)})
        return pd.DataFrame(rows, columns=["pad", "condition", "cv", "n_components", "rmse"])

    def chosen_components(self) -> pd.DataFrame:
        return pd.DataFrame([
            {"pad": f.pad, "condition": f.condition, "cv": f.cv, "best_n_components": f.best_n_components,
             "one_se_n_components": f.one_se_n_components, "cv_rmse": float(f.cv_rmse[f.best_n_components])}
            for f in self.fits
        ])

    def summary(self, cv: str, column: str) -> pd.DataFrame:
        """Mean ± SD of ``column`` over rectangular, circular and all specimens, per pad x condition."""
        results = self.results(cv)
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
    prediction for specimen s is the outer one at the count an inner LOSO over the other specimens picks.
    """
    predictions = np.empty(len(y))
    chosen: dict[str, int] = {}
    for specimen in pd.unique(specimens):
        held = specimens == specimen
        rest = specimens[~held]
        largest_inner_fold = int(pd.Series(rest).value_counts().max())
        usable = _usable_components(len(rest) - largest_inner_fold, X.shape[1], max_components)
        inner = pls_cv(X[~held], y[~held], max_components=usable, groups=rest, cap=True)
        k = int(inner.best_n_components)
        chosen[str(specimen)] = k
        predictions[held] = outer.predictions[held, k]
    return predictions, chosen


def _condition_fit(
    X: np.ndarray, y: np.ndarray, meta: pd.DataFrame, perceived: pd.DataFrame,
    pad: str, condition: str, cv: str, max_components: int,
) -> ConditionFit:
    specimens = meta["specimen"].astype(str).to_numpy()
    held_out = int(pd.Series(specimens).value_counts().max()) if cv == "loso" else 1
    usable = _usable_components(len(y) - held_out, X.shape[1], max_components)
    if usable < 1:
        raise InputError(f"{pad} {condition}: too few samples for {cv.upper()} cross-validation ({len(y)} trials)")
    nested: dict[str, int] = {}
    if cv == "loo":
        result = pls_cv(X, y, max_components=usable, cv="loo", cap=True)
        out_of_fold = result.predictions[:, result.best_n_components]
    else:
        if len(np.unique(specimens)) < 4:
            raise InputError(f"{pad} {condition}: leave-one-specimen-out needs at least 4 specimens "
                             "(3 to choose the components of each held-out one)")
        result = pls_cv(X, y, max_components=usable, groups=specimens, cap=True)
        out_of_fold, nested = _loso_nested(X, y, specimens, result, result.max_components)
    image_columns = [c for c in meta.columns if c.startswith("image")]
    predictions = meta[["specimen", "repetition"]].copy()
    predictions["image"] = meta[image_columns].astype(str).agg(";".join, axis=1)
    predictions["prediction"] = out_of_fold
    # The paper's Tables 1-6 are consistent with the population SD of the predictions (RMSE^2 = bias^2 + SD^2
    # holds for all 112 rows with ddof=0, 107 with ddof=1; docs/perception.md), so we report the same.
    table = specimen_table(predictions, perceived, pred_sd_ddof=PRED_SD_DDOF)
    return ConditionFit(pad, condition, cv, np.asarray(result.rmse, float), int(result.best_n_components),
                        int(result.one_se_n_components), predictions, table, nested)


def _signed_rank_tests(analysis: StudyAnalysis, conditions: Sequence[str]) -> pd.DataFrame:
    """Combined vs each single force per pad (Bonferroni x3), and smooth vs fingerprint on the combined condition."""
    frames = []
    for cv in CV_SCHEMES:
        if not any(f.cv == cv for f in analysis.fits):
            continue
        results = analysis.results(cv)
        singles = [c for c in conditions if c != "combined"]
        for pad in analysis.pads:
            if "combined" not in conditions or not singles:
                break
            by_condition = {
                c: results[(results.pad == pad) & (results.condition == c)].set_index("specimen")["rmse"]
                for c in conditions
            }
            table = compare_conditions(by_condition, "combined", singles, bonferroni=len(singles))
            table["comparison"] = f"{pad}: " + table["comparison"].astype(str)
            table["cv"] = cv
            frames.append(table)
        pads = analysis.pads
        if len(pads) == 2:
            first, second = sorted(pads, key=lambda p: (p != "smooth", p))
            rows = []
            # The paper compares the pads on the combined condition only (Section 4); so do we.
            for condition in [c for c in conditions if c == "combined"] or list(conditions[-1:]):
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


def analyse_study(
    study: Study,
    *,
    features: pd.DataFrame | None = None,
    max_components: int = 20,
    conditions: Sequence[str] = CONDITIONS,
    cv_schemes: Sequence[str] = CV_SCHEMES,
    n_jobs: int = 1,
    progress: Callable | None = None,
    combined_forces: Sequence[str] | None = None,
) -> StudyAnalysis:
    """Run the paper's whole analysis on a validated study; ``features`` may come from a cache.

    ``combined_forces`` (condition labels) are the forces the "combined" condition concatenates; default 1N, 2N, 3N.
    """
    if study.ratings is None:
        raise InputError("the study has no ratings.csv; the analysis needs participants' ratings", path=study.root)
    perceived = aggregate_ratings(study.ratings, study.reference_specimen, path=study.root / "ratings.csv")
    if features is None:
        features = dataset.study_features(study, n_jobs=n_jobs, progress=progress)
    counts = features.groupby(["pad", "specimen", "condition"]).size()
    if counts.min() < 2:
        (pad, specimen, condition) = counts.idxmin()
        raise InputError(
            f"too few repetitions for cross-validation: {specimen} on the {pad} pad at {condition} has {counts.min()}",
            path=study.root / "manifest.csv",
        )
    freq_columns = dataset.frequency_columns(features)
    freq_per_mm = np.array([float(c) for c in freq_columns])
    mean_spectra = features.groupby(["pad", "specimen", "condition"], sort=False)[freq_columns].mean().reset_index()
    analysis = StudyAnalysis(
        study_name=study.name,
        reference_specimen=study.reference_specimen,
        perceived=perceived,
        shapes=dict(zip(study.specimens["specimen"], study.specimens["shape"])),
        freq_per_mm=freq_per_mm,
        mean_spectra=mean_spectra,
        max_components=max_components,
    )
    jobs = [(pad, condition, cv) for pad in study.pads for condition in conditions for cv in cv_schemes]
    iterator = progress(jobs, total=len(jobs), description="cross-validating") if progress else jobs
    matrices: dict[tuple[str, str], tuple[np.ndarray, np.ndarray, pd.DataFrame]] = {}
    for pad, condition, cv in iterator:
        if (pad, condition) not in matrices:
            X, meta = dataset.condition_matrix(features, pad, condition, combined_forces=combined_forces)
            y = dataset.targets(meta, perceived, path=study.root / "ratings.csv")
            matrices[(pad, condition)] = (X, y, meta)
        X, y, meta = matrices[(pad, condition)]
        analysis.fits.append(_condition_fit(X, y, meta, perceived, pad, condition, cv, max_components))
    analysis.tests = _signed_rank_tests(analysis, conditions)
    return analysis
