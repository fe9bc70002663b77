"""Controls for a cross-validated model: does it beat shuffled targets, and the training mean?

Leave-one-out keeps the other repetitions of the held-out specimen in training, so a model can score well
by recognising the specimen rather than by reading its roughness from the spectrum. The control for that is
a specimen-level permutation test: the perceived values are shuffled across specimens (every repetition of
a specimen keeps one shared, wrong value), the whole cross-validation (including the choice of the number of
components, and for leave-one-specimen-out its nested choice) is rerun on the shuffled targets, and the
p-value is the share of shufflings whose CV RMSE is at least as good as the real one's. The null model
predicts each training fold's mean; its RMSE under the same CV is the floor any useful model must beat.

Every family faces the same test with the same shufflings, each through its engine's ``permuted_rmse``
(roughsense.model.family): PLS advances all of them as one batch over one rotation of X
(:func:`roughsense.model.pls.cv.pls_cv_many`) through the same nested-selection code as the real targets; the peak
power law fits every fold and shuffled target in one batched IRLS, and chooses nothing, so that fit is the whole of
what is rerun.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pandas as pd

from .. import defaults
from .._util.checks import Integer, check
from .._util.workers import thread_map
from ..model.family import FoldSettings, cv_rmse
from ..model.pls.simpls import single_threaded_blas
from ..model.registry import engine
from .metrics import ALPHA, specimen_table  # a model passes the permutation control when p < ALPHA

CONTROL_COLUMNS = ["pad", "condition", "cv", "rmse", "null_rmse", "permutation_p", "n_permutations",
                   "n_components", "permuted_rmse_median", "permuted_rmse_min", "beats_null",
                   "beats_permutation", "passes"]  # then analyse_study's "seed", then MODEL_COLUMN
#: The model family of a row (roughsense.model.registry); the last column of controls.csv.
MODEL_COLUMN = "model"


def check_permutations(n_permutations: int) -> int:
    """The number of shufflings, refused unless a whole number from 0 to ``defaults.MAX_PERMUTATIONS``."""
    return check(n_permutations, Integer(0, defaults.MAX_PERMUTATIONS), name="permutations",
                 must=f"a whole number from 0 to {defaults.MAX_PERMUTATIONS}")


def specimen_permutations(n_specimens: int, n_permutations: int, seed: int) -> np.ndarray:
    """(n_permutations, n_specimens) shufflings of specimen indices, drawn from ``default_rng(seed)``.

    Every pad x condition x CV scheme with the same number of specimens gets the same shufflings
    (common random numbers), whatever order the models are analysed in.
    """
    rng = np.random.default_rng(seed)
    return np.array([rng.permutation(n_specimens) for _ in range(n_permutations)], dtype=np.intp).reshape(
        n_permutations, n_specimens)


def permuted_targets(y: np.ndarray, specimens: Sequence, permutations: np.ndarray) -> np.ndarray:
    """Targets (n, B): specimen j's trials get the perceived value of specimen ``permutations[b, j]``.

    Specimens are indexed in order of first appearance in ``specimens``; ``y`` must be constant per specimen.
    """
    codes, names = pd.factorize(pd.Series(np.asarray(specimens)), sort=False)
    values = np.empty(len(names))
    values[codes] = y
    if not np.allclose(values[codes], y):
        raise ValueError("permuted_targets: y differs within a specimen")
    return values[permutations][:, codes].T


def fold_mean_predictions(y: np.ndarray, folds: Sequence) -> np.ndarray:
    """The null model's out-of-fold predictions under any folds: each trial gets the mean target of its training
    fold (every trial whose fold label differs from its own). The one home of the training-mean model."""
    y = np.asarray(y, dtype=float)
    codes, _ = pd.factorize(pd.Series(np.asarray(folds)), sort=False)
    sums, counts = np.bincount(codes, weights=y), np.bincount(codes)
    return (y.sum() - sums[codes]) / (y.size - counts[codes])


def training_mean_predictions(y: np.ndarray, specimens: Sequence, cv: str) -> np.ndarray:
    """The null model's out-of-fold predictions: each trial gets the mean target of its training fold.

    LOO leaves out the trial alone; LOSO leaves out every trial of its specimen. The same model as ``pls_cv``'s
    0-component column (``predictions[:, 0]``), so a claim can be checked against it trial by trial.
    """
    return fold_mean_predictions(y, np.arange(len(y)) if cv == "loo" else specimens)


def training_mean_results(perceived: pd.DataFrame, fits: Sequence, cv: str) -> pd.DataFrame:
    """The per-specimen table (pad, condition, specimen, gmean, sd, pred_mean, pred_sd, ovl, rmse) of the model
    that predicts each training fold's mean, on the same trials and folds as the ``fits`` (FamilyFit) of ``cv``.

    A claim the training mean also meets cannot tell a model from no model.
    """
    frames = []
    gmean = perceived.set_index("specimen")["gmean"]
    for fit in fits:
        if fit.cv != cv:
            continue
        trials = fit.predictions[["specimen"]].copy()
        y = trials["specimen"].map(gmean).to_numpy(dtype=float)
        trials["prediction"] = training_mean_predictions(y, trials["specimen"].astype(str).to_numpy(), cv)
        # Every trial of a specimen gets the same prediction, so the SD is 0 under either ddof.
        table = specimen_table(trials, perceived, pred_sd_ddof=0)
        table.insert(0, "pad", fit.pad)
        table.insert(1, "condition", fit.condition)
        frames.append(table)
    columns = ["pad", "condition", "specimen", "gmean", "sd", "pred_mean", "pred_sd", "ovl", "rmse", "n_predictions"]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=columns)


def permutation_p(rmse: float, permuted: np.ndarray) -> float:
    """(1 + shufflings at least as good) / (1 + shufflings); ``rmse`` computed as the shuffled ones, so ties count."""
    return float((1 + np.sum(permuted <= rmse * (1 + 1e-12))) / (1 + permuted.size))


def control_row(fit, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, permutations: np.ndarray,
                law: dict | None = None) -> dict:
    """One row of controls.csv for a fitted pad x condition x CV scheme (a ``FamilyFit``) of any family.

    ``law``: the pad x condition's settings (:class:`roughsense.model.family.FoldSettings` or its keyword dict),
    for a family whose folds read them (the peak law's).
    """
    specimens = np.asarray(specimens).astype(str)
    predictions = fit.predictions["prediction"].to_numpy(dtype=float)
    rmse = float(cv_rmse(predictions, y))  # the pooled RMSE, as every family's permuted_rmse computes it
    # curve[0] is the training-fold mean under the same folds: the null model (LOSO: nothing to choose).
    null_rmse = float(fit.curve[0])
    n_permutations = int(permutations.shape[0])
    if n_permutations:
        Y = permuted_targets(y, specimens, permutations)
        permuted = engine(fit.model).permuted_rmse(X, Y, specimens, fit.cv, FoldSettings.of(law),
                                                   int(fit.curve.size - 1))
        p = permutation_p(rmse, permuted)
        median, low = float(np.median(permuted)), float(permuted.min())
    else:
        p = median = low = float("nan")
    beats_null = bool(rmse < null_rmse)
    # Without shufflings the permutation control is not run: left empty, and judged on the null model alone.
    beats_permutation = bool(p < ALPHA) if n_permutations else None
    return {
        "pad": fit.pad, "condition": fit.condition, "cv": fit.cv, "rmse": rmse, "null_rmse": null_rmse,
        "permutation_p": p, "n_permutations": n_permutations, "n_components": int(fit.best),
        "permuted_rmse_median": median, "permuted_rmse_min": low, "beats_null": beats_null,
        "beats_permutation": beats_permutation, "passes": beats_null and beats_permutation is not False,
        MODEL_COLUMN: fit.model,
    }


def controls_table(rows: list[dict]) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=[*CONTROL_COLUMNS, MODEL_COLUMN])


def run_controls(jobs: Sequence[tuple], *, n_jobs: int = 1, progress: Callable | None = None) -> pd.DataFrame:
    """controls.csv for many models: each job is the arguments of :func:`control_row`.

    The models are independent array work that releases the GIL, so ``n_jobs`` threads share them; BLAS is held
    to one thread for the whole run (its own threads would only contend with ours, and one thread keeps every
    product's rounding the same), and rows come back in job order: the table is identical for any ``n_jobs``.
    """
    jobs = list(jobs)
    shufflings = {int(job[4].shape[0]) for job in jobs}
    # The count a log shows when the stage starts: models, and each one's shufflings (the work is their product).
    description = f"controls, {shufflings.pop()} shufflings per model" if len(shufflings) == 1 else "controls"

    def one(job: tuple) -> dict:
        return control_row(*job)

    with single_threaded_blas():
        rows = thread_map(one, jobs, min(n_jobs, max(len(jobs), 1)))
        rows = list(progress(rows, total=len(jobs), description=description) if progress else rows)
    return controls_table(rows)
