"""Presses per surface: how a held-out surface's error falls with the number of presses it is read from.

A surface is scored as the mean of its presses' predictions, and the law reads where its peak is, and its shape, on
their mean spectrum; one fingerprint press can show no grating at all. So the study asks, per pad and condition:
with the law fitted as the study fits it (every press of the other specimens, leave-one-specimen-out), how far is
a held-out specimen's score from its perceived roughness when it is read from 1, 3, 5 or 10 of its presses? Each
count draws :data:`DRAWS` random subsets of each specimen's presses (seeded from the study's seed); a specimen's
RMSE is over its draws, and the curve is the mean over specimens beside the training mean's (which reads no press).
``presses_needed`` is the fewest presses that gain at least half of what the most presses gain over the training
mean. Of every family that reads a surface from its presses together (its engine's ``surface_reader``: the peak
law, whose leave-one-specimen-out fits are one batch); PLS reads each press alone, so the mean is all it has.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from ..model.family import FoldSettings
from ..model.jackknife_file import PRESS_COUNTS  # the counts reported, as a model file keeps its residuals
from ..model.peak_law.folds import specimen_codes
from ..model.registry import engine, engines
from .controls import fold_mean_predictions

#: Random subsets of a specimen's presses per count.
DRAWS = 20
PRESS_COLUMNS = ["model", "pad", "condition", "n_presses", "rmse", "null_rmse"]


def presses_curve(X: np.ndarray, y: np.ndarray, specimens: np.ndarray, law, seed: int,
                  counts=PRESS_COUNTS, draws: int = DRAWS, *, model: str | None = None) -> pd.DataFrame | None:
    """Mean per-specimen RMSE of a held-out surface read from k of its presses, per k (columns n_presses, rmse,
    null_rmse), by family ``model`` (default: the first registered one that reads surfaces); None for a family
    that reads each press alone."""
    specimens = np.asarray(specimens).astype(str)
    chosen = engine(model) if model is not None else next(e for e in engines() if e.reads_surfaces)
    read = chosen.surface_reader(X, y, specimens, FoldSettings.of(law))
    if read is None:
        return None
    codes, names = specimen_codes(specimens)
    target = pd.Series(y).groupby(codes).first().to_numpy()
    null = pd.Series(np.abs(fold_mean_predictions(y, specimens) - y)).groupby(codes).first().to_numpy()
    rng = np.random.default_rng(seed)
    smallest = int(np.bincount(codes).min())
    rows = []
    for k in (c for c in counts if c <= smallest):
        picks = [np.concatenate([rng.choice(np.flatnonzero(codes == s), size=k, replace=False)
                                 for s in range(names.size)]) for _ in range(draws)]
        rows_of = np.concatenate(picks)
        labels = np.repeat(np.arange(draws * names.size), k)  # one surface per specimen and draw
        predicted = read(rows_of, labels)
        surface = pd.Series(predicted).groupby(labels).mean().to_numpy().reshape(draws, names.size)
        per_specimen = np.sqrt(np.mean((surface - target[None, :]) ** 2, axis=0))
        rows.append({"n_presses": k, "rmse": float(per_specimen.mean()), "null_rmse": float(null.mean())})
    return pd.DataFrame(rows, columns=["n_presses", "rmse", "null_rmse"])


#: A count of presses is enough when it gains at least this share of what reading the most presses gains over the
#: training mean: "below the mean" alone would accept one fingerprint press at 0.352 against a mean of 0.354.
NEEDED_SHARE = 0.5


def presses_needed(curve: pd.DataFrame) -> int | None:
    """The fewest presses per surface that gain at least :data:`NEEDED_SHARE` of the most presses' gain over the
    training mean (None: even the most presses do not beat it)."""
    if curve.empty:
        return None
    null = float(curve["null_rmse"].iloc[0])
    best = float(curve.loc[curve["n_presses"].idxmax(), "rmse"])
    if not best < null:
        return None
    good = curve[curve["rmse"] <= null - NEEDED_SHARE * (null - best)]
    return int(good["n_presses"].min())


def presses_analysis(jobs, seed: int) -> pd.DataFrame:
    """The study's table (PRESS_COLUMNS) over the LOSO fits among the controls' jobs of every family that reads a
    surface from its presses together, each count's subsets drawn from ``seed``."""
    frames = []
    for fit, X, y, specimens, _, law in jobs:
        curve = presses_curve(X, y, specimens, law, seed, model=fit.model) if fit.cv == "loso" else None
        if curve is None:
            continue
        curve.insert(0, "model", fit.model)
        curve.insert(1, "pad", fit.pad)
        curve.insert(2, "condition", fit.condition)
        frames.append(curve)
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=PRESS_COLUMNS)


def presses_needed_by_curve(presses: pd.DataFrame) -> dict[tuple[str, str, str], int | None]:
    """:func:`presses_needed` of every (model, pad, condition) curve of presses.csv, computed once for the report."""
    if presses.empty:
        return {}
    return {(str(model), str(pad), str(condition)): presses_needed(curve)
            for (model, pad, condition), curve in presses.groupby(["model", "pad", "condition"], sort=False)}
