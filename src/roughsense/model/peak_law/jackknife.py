"""The peak law's jackknife+ folds (model/jackknife_file.py): the law fitted without each specimen, kept in a model
file as intercept, slopes and kept training range (10 numbers a fold), read with the deployed law's settings.

Fitted in one batch (model/peak_law/folds.py), as the study fits them; checked on loading as the deployed law's own
section is (each fold's peak on the grid, its exponent finite over its domain), and against the law they travel with:
over the law's trained feature box (its centre and corners, where a linear law's extremes are) the folds' log
predictions must lie around the law's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import ModelFileError
from ..jackknife_file import KEY, deploy, fold_numbers
from .file import KIND

#: The folds' fields in a model file (``kind`` aside), as JSON Schema properties (the shapes are checked on loading).
FOLD_SCHEMA = {name: {"type": "array", "minItems": 1}
               for name in ("intercept", "coefficients", "feature_min", "feature_max")}


@dataclass(frozen=True)
class LawFolds:
    """The peak law fitted without each specimen: intercept and slopes (S, p + 1) and kept range (S, p), read with
    the deployed law's settings (grid, blocks, pad ridges), which the model file holds once."""

    beta: np.ndarray
    low: np.ndarray
    high: np.ndarray
    settings: dict

    kind = KIND

    def log_predict(self, X, surfaces=None) -> np.ndarray:
        """(S, n) each fold's log prediction of each row (rows of one surface share where its peak is read)."""
        from ...sensor.grid import grid_step
        from ..peak_search import peak_features
        from .folds import fold_log_predictions

        freq = np.asarray(self.settings["freq_per_mm"], dtype=np.float64)
        features = peak_features(X, freq, surfaces=surfaces, **{k: v for k, v in self.settings.items()
                                                              if k in ("n_blocks", "pad_ridge_period_mm",
                                                                       "exclusion_per_mm")})
        return fold_log_predictions(features, self.beta, self.low, self.high, grid_step(freq))

    def to_dict(self) -> dict:
        def bound(values):
            return [[float(v) if math.isfinite(v) else None for v in row] for row in values]

        return {"kind": self.kind, "intercept": self.beta[:, 0].tolist(), "coefficients": self.beta[:, 1:].tolist(),
                "feature_min": bound(self.low), "feature_max": bound(self.high)}

    def bracket(self, loaded) -> tuple[np.ndarray, np.ndarray, str]:
        """The folds' and the law's log roughness over the law's trained feature box (its centre and corners, over
        the features with a term), and where that is, as a refusal names it."""
        used = np.flatnonzero(np.asarray(loaded.coef_) != 0)  # their ranges are finite (checked on loading)
        low, high = np.asarray(loaded.feature_min_), np.asarray(loaded.feature_max_)
        centre = np.where(np.isfinite(low) & np.isfinite(high), 0.5 * (low + high), 0.0)
        points = [centre]
        for corner in _corners(centre.size, used):
            point = centre.copy()
            point[used] = np.where(corner[used], high[used], low[used])
            points.append(point)
        points = np.array(points)
        around = self.beta[:, :1] + self.beta[:, 1:] @ points.T  # (S, points): log roughness
        model = loaded.intercept_ + points @ np.asarray(loaded.coef_)
        return around, model, "over the trained feature box (log roughness at its centre and corners)"


def _corners(width: int, used: np.ndarray) -> list[np.ndarray]:
    """Every combination of low (False) and high (True) ends over the ``used`` features (``width`` in all)."""
    corners = []
    for code in range(2 ** used.size):
        corner = np.zeros(width, dtype=bool)
        corner[used] = [(code >> i) & 1 == 1 for i in range(used.size)]
        corners.append(corner)
    return corners


def law_jackknife(X, y, specimens, law: dict, seed: int):
    """The peak law's: its leave-one-specimen-out fits in one batch (model/peak_law/folds.py), as the study's."""
    from .folds import law_fold_models

    codes, _ = pd.factorize(pd.Series(np.asarray(specimens).astype(str)), sort=False)
    held = codes[None, :] == np.arange(int(codes.max()) + 1)[:, None]
    settings = {k: v for k, v in law.items() if k != "surfaces"}
    beta, low, high, _ = law_fold_models(X, y, ~held, surfaces=specimens, **settings)
    return deploy(LawFolds(beta, low, high, settings), X, y, specimens, seed)


def load_law_folds(stored: dict, loaded, names: list, path: Path | None) -> LawFolds:
    """The file's law folds, each as checked as the deployed law's section (its peak on the grid, its exponent
    finite over its widened domain)."""
    from ...sensor.grid import grid_step
    from ..readout_domain import domain_margins
    from ..readout_file import check_log_frequencies
    from .file import _check_finite_predictions

    p, n = loaded.coef_.size, len(names)
    intercept = fold_numbers(stored.get("intercept"), (n,), "folds.intercept", path)
    coefficients = fold_numbers(stored.get("coefficients"), (n, p), "folds.coefficients", path)
    low = fold_numbers(stored.get("feature_min"), (n, p), "folds.feature_min", path, nulls=True)
    high = fold_numbers(stored.get("feature_max"), (n, p), "folds.feature_max", path, nulls=True)
    low, high = np.where(np.isnan(low), -np.inf, low), np.where(np.isnan(high), np.inf, high)
    if np.any(low > high):
        raise ModelFileError(f"training.{KEY}.folds.feature_min exceeds feature_max: an empty training range", path=path)
    step = grid_step(loaded.freq_per_mm)
    for i in range(n):  # each fold's peak read on the grid, and its exponent finite over its domain, as the law's
        check_log_frequencies([low[i, 0], high[i, 0]], loaded.freq_per_mm,
                               f"training.{KEY}.folds.feature_min[{i}][0] and feature_max[{i}][0]", path)
        wide_low, wide_high = domain_margins(step, low[i], high[i])
        try:
            _check_finite_predictions(float(intercept[i]), {"coefficients": coefficients[i], "feature_min": wide_low,
                                                            "feature_max": wide_high}, path)
        except ModelFileError as exc:
            raise ModelFileError(f"training.{KEY}.folds, fold {i + 1} ({names[i]}): {exc.message}", path=path) from None
    settings = {"freq_per_mm": loaded.freq_per_mm, "n_blocks": loaded.n_blocks,
                "pad_ridge_period_mm": loaded.pad_ridge_period_mm, "exclusion_per_mm": loaded.exclusion_per_mm}
    return LawFolds(np.column_stack([intercept, coefficients]), low, high, settings)
