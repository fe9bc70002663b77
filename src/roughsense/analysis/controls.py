"""Controls for a cross-validated model: does it beat shuffled targets, and the training mean?

Leave-one-out keeps the other repetitions of the held-out specimen in training, so a model can score well
by recognising the specimen rather than by reading its roughness from the spectrum. The control for that is
a specimen-level permutation test: the perceived values are shuffled across specimens (every repetition of
a specimen keeps one shared, wrong value), the whole cross-validation (including the choice of the number of
components, and for leave-one-specimen-out its nested choice) is rerun on the shuffled targets, and the
p-value is the share of shufflings whose CV RMSE is at least as good as the real one's. The null model
predicts each training fold's mean; its RMSE under the same CV is the floor any useful model must beat.

Every shuffling's cross-validation runs through :func:`roughsense.model.pls_cv.pls_cv_many`, which advances all of
them as one batch over one rotation of X, and through the same nested-selection code as the real targets.

The peak power law (model family ``peak-law``) faces the same test with the same shufflings: all of them go through
one :func:`roughsense.model.peak_law.peak_law_cv` call (every fold and shuffled target in one batched fit). It
chooses nothing from the targets, so its fit on each training fold is the whole of what is rerun.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd

from .._util.checks import Integer, check
from ..model.families import PEAK_LAW, PLS
from ..model.peak_law import peak_law_cv
from ..model.pls import single_threaded_blas
from ..model.pls_cv import nested_group_predictions, pls_cv_many
from .metrics import ALPHA  # a model passes the permutation control when p < ALPHA (claims.py reads it here)

#: At least 199 shufflings (p-values in steps of 1/200; the smallest is 0.005).
DEFAULT_PERMUTATIONS = 199
#: At most this many (p-values to 1e-4): the shufflings' targets are held at once, one column per shuffling, and
#: 10^9 of them ran out of memory after half a minute; more is refused before any work.
MAX_PERMUTATIONS = 10_000
#: The peak law's shufflings run in chunks of about this many cells (folds fitted x shufflings x presses) a working
#: array: 4 MiB of float64 (the built-in study's 199 shufflings in one chunk), whatever the number of presses. Its IRLS
#: and kept ranges take one fold per specimen (peak_law_cv), so what is left at this size is the kept ranges' arrays:
#: 2^21 cells held the two control threads ~40 MiB higher at the same CPU, 2^17 cost 13 % more CPU
#: (benchmarks/bench_issue37.py --chunks).
LAW_CHUNK_CELLS = 1 << 19
CONTROL_COLUMNS = ["pad", "condition", "cv", "rmse", "null_rmse", "permutation_p", "n_permutations",
                   "n_components", "permuted_rmse_median", "permuted_rmse_min", "beats_null",
                   "beats_permutation", "passes"]  # then analyse_study's "seed", then MODEL_COLUMN
#: The model family of a row (roughsense.model.families); the last column of controls.csv.
MODEL_COLUMN = "model"


def check_permutations(n_permutations: int) -> int:
    """The number of shufflings, refused unless a whole number from 0 to :data:`MAX_PERMUTATIONS`."""
    return check(n_permutations, Integer(0, MAX_PERMUTATIONS), name="permutations",
                 must=f"a whole number from 0 to {MAX_PERMUTATIONS}")


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


def _cv_rmse(prediction: np.ndarray, target: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean((prediction - target) ** 2, axis=-1))


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


def permuted_cv_rmse(X: np.ndarray, Y: np.ndarray, specimens: np.ndarray, cv: str, max_components: int) -> np.ndarray:
    """CV RMSE of each target column of Y after the same selection the study applies to the real target.

    LOO: the argmin over 1..max_components of the LOO RMSE. LOSO: nested leave-one-specimen-out (each
    held-out specimen's count chosen by LOSO over the others), pooled over all trials.
    """
    if cv == "loo":
        batch = pls_cv_many(X, Y, max_components=max_components, cv="loo", cap=True)
        return batch.rmse[:, 1:].min(axis=1)
    outer = pls_cv_many(X, Y, max_components=max_components, groups=specimens, cap=True)
    nested, _ = nested_group_predictions(X, Y, specimens, outer.predictions)
    return _cv_rmse(nested, Y.T)


def permuted_law_rmse(X: np.ndarray, Y: np.ndarray, specimens: np.ndarray, cv: str, law: dict) -> np.ndarray:
    """CV RMSE of the peak power law on each target column of Y, pooled over all trials (LOO or LOSO).

    ``law``: peak_law_cv's keywords for this pad and condition (grid, spectra per row, the pad's ridge period).
    Shufflings go through in chunks of about :data:`LAW_CHUNK_CELLS` folds x shufflings x presses, so the memory
    stays flat in the number of presses (leave-one-out has as many folds as presses); each shuffling's fit is its own.
    """
    groups = np.asarray(specimens) if cv == "loso" else None
    n = Y.shape[0]
    # Leave-one-out's folds of one specimen's presses pose one problem (its targets are the specimen's one value):
    # peak_law_cv fits each once, so both schemes fit as many folds as there are specimens.
    size = max(1, LAW_CHUNK_CELLS // (n * len(pd.unique(np.asarray(specimens)))))
    predictions = np.vstack([peak_law_cv(X, Y[:, start:start + size], groups=groups, **law)
                             for start in range(0, Y.shape[1], size)])
    return _cv_rmse(predictions, Y.T)


def permutation_p(rmse: float, permuted: np.ndarray) -> float:
    """(1 + shufflings at least as good) / (1 + shufflings); ``rmse`` computed as the shuffled ones, so ties count."""
    return float((1 + np.sum(permuted <= rmse * (1 + 1e-12))) / (1 + permuted.size))


def control_row(fit, X: np.ndarray, y: np.ndarray, specimens: np.ndarray, permutations: np.ndarray,
                law: dict | None = None) -> dict:
    """One row of controls.csv for a fitted pad x condition x CV scheme (a ``ConditionFit``) of either family.

    ``law``: the peak law's settings (:func:`permuted_law_rmse`); needed for a peak-law fit only.
    """
    specimens = np.asarray(specimens).astype(str)
    predictions = fit.predictions["prediction"].to_numpy(dtype=float)
    rmse = float(_cv_rmse(predictions, y))
    # cv_rmse[0] is the training-fold mean under the same folds: the null model (LOSO: nothing to choose).
    null_rmse = float(fit.cv_rmse[0])
    model = getattr(fit, "model", PLS)
    n_permutations = int(permutations.shape[0])
    if n_permutations:
        Y = permuted_targets(y, specimens, permutations)
        if model == PEAK_LAW:
            permuted = permuted_law_rmse(X, Y, specimens, fit.cv, law)
        else:
            permuted = permuted_cv_rmse(X, Y, specimens, fit.cv, int(fit.cv_rmse.size - 1))
        p = permutation_p(rmse, permuted)
        median, low = float(np.median(permuted)), float(permuted.min())
    else:
        p = median = low = float("nan")
    beats_null = bool(rmse < null_rmse)
    # Without shufflings the permutation control is not run: left empty, and judged on the null model alone.
    beats_permutation = bool(p < ALPHA) if n_permutations else None
    return {
        "pad": fit.pad, "condition": fit.condition, "cv": fit.cv, "rmse": rmse, "null_rmse": null_rmse,
        "permutation_p": p, "n_permutations": n_permutations, "n_components": int(fit.best_n_components),
        "permuted_rmse_median": median, "permuted_rmse_min": low, "beats_null": beats_null,
        "beats_permutation": beats_permutation, "passes": beats_null and beats_permutation is not False,
        MODEL_COLUMN: model,
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
        if n_jobs > 1 and len(jobs) > 1:
            with ThreadPoolExecutor(max_workers=n_jobs, thread_name_prefix="roughsense-controls") as pool:
                rows = pool.map(one, jobs)
                rows = list(progress(rows, total=len(jobs), description=description) if progress else rows)
        else:
            rows = [one(job) for job in (progress(jobs, total=len(jobs), description=description) if progress else jobs)]
    return controls_table(rows)
