"""PLS's jackknife+ folds (model/jackknife_file.py): PLS refitted without each specimen at the component count its
nested leave-one-specimen-out chose, kept in a model file as coefficient vector, intercept and floor per fold.

Checked on loading for shape, finiteness and a positive floor, and against the model they travel with: at the
training centroid (``model.x_mean``), where the model predicts ``model.y_mean``, the folds' predictions must lie
around the model's.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import ModelFileError
from ..interval import held_out_floors
from ..jackknife_file import KEY, deploy, fold_numbers
from .file import KIND

#: The folds' fields in a model file (``kind`` aside), as JSON Schema properties (the shapes are checked on loading).
FOLD_SCHEMA = {name: {"type": "array", "minItems": 1} for name in ("coefficients", "intercepts", "floors")}


@dataclass(frozen=True)
class LinearFolds:
    """PLS fitted without each specimen (its nested component count): coefficients (S, p), intercepts and floors
    (S,): half the smallest rating that fold trained on, as a loaded PLS file holds its predictions."""

    coefficients: np.ndarray
    intercepts: np.ndarray
    floors: np.ndarray

    kind = KIND

    def log_predict(self, X, surfaces=None) -> np.ndarray:
        linear = np.asarray(X, dtype=np.float64) @ self.coefficients.T + self.intercepts
        return np.log(np.maximum(linear, self.floors)).T

    def to_dict(self) -> dict:
        return {"kind": self.kind, "coefficients": self.coefficients.tolist(), "intercepts": self.intercepts.tolist(),
                "floors": self.floors.tolist()}

    def bracket(self, loaded) -> tuple[np.ndarray, np.ndarray, str]:
        """The folds' and the model's predictions at the training centroid, and where that is, as a refusal says."""
        x_mean = np.asarray(loaded.x_mean_, dtype=np.float64)
        around, model = self.coefficients @ x_mean + self.intercepts, float(loaded.y_mean_)
        return around, model, "at the training centroid (model.x_mean), where the model predicts model.y_mean"


def pls_jackknife(X, y, specimens, n_components: dict, seed: int):
    """PLS's: each specimen's fold refitted with the component count its nested LOSO chose (0: the training mean)."""
    from .simpls import SIMPLS

    specimens = np.asarray(specimens).astype(str)
    X, y = np.asarray(X, dtype=np.float64), np.asarray(y, dtype=np.float64)
    names = pd.unique(pd.Series(specimens))
    coefficients, intercepts = np.zeros((names.size, X.shape[1])), np.empty(names.size)
    for i, name in enumerate(names):
        train = specimens != name
        count = int(n_components.get(str(name), 0))
        if count < 1:
            intercepts[i] = float(y[train].mean())
            continue
        fitted = SIMPLS(n_components=count).fit(X[train], y[train])
        coefficients[i], intercepts[i] = fitted.coef_, fitted.intercept_
    floors = pd.Series(held_out_floors(y, specimens)).groupby(pd.factorize(pd.Series(specimens))[0]).first()
    return deploy(LinearFolds(coefficients, intercepts, floors.to_numpy()), X, y, specimens, seed)


def load_linear_folds(stored: dict, loaded, names: list, path: Path | None) -> LinearFolds:
    """The file's PLS folds: one coefficient vector of the model's width, one intercept and one positive floor each."""
    n = len(names)
    coefficients = fold_numbers(stored.get("coefficients"), (n, loaded.n_features), "folds.coefficients", path)
    intercepts = fold_numbers(stored.get("intercepts"), (n,), "folds.intercepts", path)
    floors = fold_numbers(stored.get("floors"), (n,), "folds.floors", path)
    if np.any(floors <= 0):
        raise ModelFileError(f"training.{KEY}.folds.floors must be positive (a floor on roughness)", path=path)
    return LinearFolds(coefficients, intercepts, floors)
