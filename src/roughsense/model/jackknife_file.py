"""The jackknife+ a model file carries, so ``predict`` gives a new surface an interval with a stated guarantee.

model/jackknife_plus.py defines the interval: every leave-one-specimen-out model's log prediction of the new
surface, widened by that model's log residual on the specimen it left out. A model file therefore keeps, besides the
model fitted on every specimen, the smallest exact form of each fold model (the peak law: intercept, slopes and kept
training range, 10 numbers; PLS: coefficient vector, intercept and floor) and each specimen's held-out log residual.

Presses per surface. A surface read from fewer presses is predicted less surely (on the fingerprint pad much less:
analysis/presses.py), and the jackknife+ is exchangeable only between like readings: a new surface read from k
presses is compared with training specimens read from k presses by the models that left them out. So the residuals
are kept for k = 1, 3, 5, 10 (those at most the fewest presses a specimen has, and that number itself); each
specimen's k presses are one seeded draw of its presses (all of them when it has k), and a surface read from m
presses takes the residuals of the largest stored k <= m. One draw keeps the exchangeability argument exact; it makes
the width at small k depend on the draw (``fit --seed``).

The guarantee (Barber et al. 2021, Theorem 1): coverage of at least 1 - 2 alpha for a new surface exchangeable with
the training specimens; in practice close to 1 - alpha. With 14 specimens at 90 % the bounds are the extremes over
the 14 folds: the worst held-out specimen sets the width (docs/peak_law.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .._util.checks import Real, short_repr
from ..errors import ModelFileError
from .interval import INTERVAL_LEVEL, held_out_floors
from .jackknife_plus import jackknife_plus, ranks, surface_means
from .schema import integer, number, strict

#: The model file's ``training`` key, and the method it names (in predict's CSV too).
KEY = "jackknife_plus"
METHOD = "jackknife+ over specimens"
#: Presses per surface whose residuals a model file keeps (as analysis/presses.py reports them).
PRESS_COUNTS = (1, 3, 5, 10)
#: Largest |log residual| and |fold coefficient| a file may hold (a factor e^50; slopes of real fits are a few units).
MAX_LOG_RESIDUAL = 50.0
MAX_FOLD_VALUE = 1e6
_RESIDUALS = "log(perceived) - log(predicted) of each specimen by the model fitted without it"
_FOLD_ARRAY = {"type": "array", "minItems": 1}
#: The model file's ``training.jackknife_plus`` (:meth:`DeployedJackknife.to_dict`), checked by model/schema.py;
#: the shapes, and that the folds bracket the model they travel with, by :func:`deployed_jackknife` on loading.
SCHEMA = strict({
    "method": {"const": METHOD},
    "level": {"const": INTERVAL_LEVEL, "description": f"{INTERVAL_LEVEL} (the level predict labels pi90)"},
    "specimens": {"type": "array", "items": {"type": "string"}, "minItems": 1, "uniqueItems": True},
    "presses": {"type": "array", "items": integer(1, 10_000), "minItems": 1, "uniqueItems": True},
    "log_residuals": {"type": "array", "items": {"type": "array", "items": number(-MAX_LOG_RESIDUAL,
                                                                                    MAX_LOG_RESIDUAL)}},
    "residuals": {"const": _RESIDUALS},
    "folds": strict({"kind": {"enum": ["peak-power-law", "pls1-simpls"]}, "intercept": _FOLD_ARRAY,
                     "coefficients": _FOLD_ARRAY, "feature_min": _FOLD_ARRAY, "feature_max": _FOLD_ARRAY,
                     "intercepts": _FOLD_ARRAY, "floors": _FOLD_ARRAY}, required=("kind",)),
}, required=("method", "level", "specimens", "presses", "log_residuals", "folds"))


def press_counts(presses_per_specimen) -> tuple[int, ...]:
    """The counts kept: :data:`PRESS_COUNTS` below the fewest presses a specimen has, and that number."""
    smallest = int(np.min(presses_per_specimen))
    return tuple(sorted({k for k in PRESS_COUNTS if k < smallest} | {smallest}))


def press_subsets(codes: np.ndarray, counts, seed: int) -> list[np.ndarray]:
    """Per count k, the rows read: each specimen's k presses (all of them when it has k), one draw seeded by ``seed``."""
    rng = np.random.default_rng(seed)
    members = [np.flatnonzero(codes == s) for s in range(int(codes.max()) + 1)]
    return [np.concatenate([rows if rows.size == k else np.sort(rng.choice(rows, size=k, replace=False))
                            for rows in members]) for k in counts]


@dataclass(frozen=True)
class LawFolds:
    """The peak law fitted without each specimen: intercept and slopes (S, p + 1) and kept range (S, p), read with
    the deployed law's settings (grid, blocks, pad ridges), which the model file holds once."""

    beta: np.ndarray
    low: np.ndarray
    high: np.ndarray
    settings: dict

    kind = "peak-power-law"

    def log_predict(self, X, surfaces=None) -> np.ndarray:
        """(S, n) each fold's log prediction of each row (rows of one surface share where its peak is read)."""
        from ..sensor.grid import grid_step
        from .peak_law.folds import fold_log_predictions
        from .peak_search import peak_features

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


@dataclass(frozen=True)
class LinearFolds:
    """PLS fitted without each specimen (its nested component count): coefficients (S, p), intercepts and floors
    (S,): half the smallest rating that fold trained on, as a loaded PLS file holds its predictions."""

    coefficients: np.ndarray
    intercepts: np.ndarray
    floors: np.ndarray

    kind = "pls1-simpls"

    def log_predict(self, X, surfaces=None) -> np.ndarray:
        linear = np.asarray(X, dtype=np.float64) @ self.coefficients.T + self.intercepts
        return np.log(np.maximum(linear, self.floors)).T

    def to_dict(self) -> dict:
        return {"kind": self.kind, "coefficients": self.coefficients.tolist(), "intercepts": self.intercepts.tolist(),
                "floors": self.floors.tolist()}


@dataclass(frozen=True)
class DeployedJackknife:
    """Fold models and residuals by presses: the jackknife+ interval of any new surface (:meth:`intervals`)."""

    folds: LawFolds | LinearFolds
    specimens: tuple[str, ...]
    counts: tuple[int, ...]
    log_residuals: np.ndarray  # (K, S): log(perceived) - log(fold prediction), a specimen read from counts[k] presses
    level: float = INTERVAL_LEVEL

    def count_for(self, presses: int) -> int:
        """The largest kept count at most ``presses`` (the smallest kept one for fewer)."""
        fitting = [k for k in self.counts if k <= presses]
        return fitting[-1] if fitting else self.counts[0]

    @property
    def name(self) -> str:
        return f"{METHOD} ({len(self.specimens)})"

    def label(self, presses: int) -> str:
        """The method as predict's CSV names it: which presses' residuals set the width."""
        return f"{self.name}, residuals of {self.count_for(presses)}-press surfaces"

    def intervals(self, X, surfaces=None) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """Per row, its surface's 90 % jackknife+ bounds (low, high) and the method's label; rows of one surface
        (``surfaces``) are read together and predicted as their mean; None: each row is a surface of one press."""
        n = np.asarray(X).shape[0]
        labels = np.arange(n) if surfaces is None else np.asarray(surfaces)
        codes, _ = pd.factorize(pd.Series(labels), sort=False)
        presses = np.bincount(codes)
        rows = np.exp(self.folds.log_predict(X, None if surfaces is None else labels))
        centres = np.log(surface_means(rows, codes, presses.size)).T  # (m, S)
        low, high = np.empty(presses.size), np.empty(presses.size)
        for count in np.unique(presses):
            which = presses == count
            k = self.counts.index(self.count_for(int(count)))
            low[which], high[which] = jackknife_plus(centres[which], self.log_residuals[k], self.level)
        bounded = np.isfinite(low) & np.isfinite(high)  # too few specimens for the level: no interval (NaN)
        low, high = np.where(bounded, np.exp(low), np.nan), np.where(bounded, np.exp(high), np.nan)
        return low[codes], high[codes], [self.label(int(presses[c])) for c in codes]

    @property
    def bounded(self) -> bool:
        """Whether the specimens are enough for a finite interval at the level (:attr:`fewest_specimens`)."""
        return len(self.specimens) >= self.fewest_specimens

    @property
    def fewest_specimens(self) -> int:
        """The fewest specimens whose jackknife+ is finite at the level: 9 at 90 % (:func:`ranks`)."""
        return next(n for n in range(1, 10_000) if ranks(n, self.level)[0] >= 1 and ranks(n, self.level)[1] <= n)

    def to_dict(self) -> dict:
        """The model file's ``training.jackknife_plus`` entry."""
        return {"method": METHOD, "level": self.level, "specimens": list(self.specimens),
                "presses": list(self.counts), "log_residuals": self.log_residuals.tolist(),
                "residuals": _RESIDUALS, "folds": self.folds.to_dict()}


def deploy(folds: LawFolds | LinearFolds, X, y, specimens, seed: int) -> DeployedJackknife:
    """Each specimen's residual under the model that left it out, read from each kept count of presses."""
    codes, names = pd.factorize(pd.Series(np.asarray(specimens).astype(str)), sort=False)
    log_targets = np.log(pd.Series(np.asarray(y, dtype=np.float64)).groupby(codes).first().to_numpy())
    counts = press_counts(np.bincount(codes))
    X = np.asarray(X, dtype=np.float64)
    residuals = []
    for rows in press_subsets(codes, counts, seed):
        owner = codes[rows]
        own = np.exp(folds.log_predict(X[rows], owner)[owner, np.arange(rows.size)])  # each row by its own fold
        residuals.append(log_targets - np.log(np.bincount(owner, weights=own) / np.bincount(owner)))
    return DeployedJackknife(folds, tuple(map(str, names)), counts, np.array(residuals))


def law_jackknife(X, y, specimens, law: dict, seed: int) -> DeployedJackknife:
    """The peak law's: its leave-one-specimen-out fits in one batch (model/peak_law/folds.py), as the study's."""
    from .peak_law.folds import law_fold_models

    codes, _ = pd.factorize(pd.Series(np.asarray(specimens).astype(str)), sort=False)
    held = codes[None, :] == np.arange(int(codes.max()) + 1)[:, None]
    settings = {k: v for k, v in law.items() if k != "surfaces"}
    beta, low, high, _ = law_fold_models(X, y, ~held, surfaces=specimens, **settings)
    return deploy(LawFolds(beta, low, high, settings), X, y, specimens, seed)


def pls_jackknife(X, y, specimens, n_components: dict, seed: int) -> DeployedJackknife:
    """PLS's: each specimen's fold refitted with the component count its nested LOSO chose (0: the training mean)."""
    from .pls.simpls import SIMPLS

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


# --------------------------------------------------------------------------- reading a model file's entry


def deployed_jackknife(loaded) -> DeployedJackknife | None:
    """The model file's jackknife+, or None (a file written before it). A malformed entry is refused in one line
    naming the field: the checksum is unkeyed, so these checks are what keep an edited file from a false interval."""
    training = loaded.training if isinstance(loaded.training, dict) else {}
    stored = training.get(KEY)
    if stored is None:
        return None
    path = loaded.path

    def fail(field: str, must: str, value) -> None:
        raise ModelFileError(f"training.{KEY}.{field} must be {must}, got {short_repr(value)}", path=path)

    if not isinstance(stored, dict):
        raise ModelFileError(f"training.{KEY} must be an object, got {short_repr(stored)}", path=path)
    if stored.get("level") != INTERVAL_LEVEL or not Real().accepts(stored.get("level")):
        fail("level", f"{INTERVAL_LEVEL} (the level predict labels pi90)", stored.get("level"))
    names = stored.get("specimens")
    if not (isinstance(names, list) and names and all(isinstance(v, str) for v in names)):
        fail("specimens", "a list of specimen names", names)
    counts = stored.get("presses")
    if not (isinstance(counts, list) and counts and all(type(k) is int and k >= 1 for k in counts)
            and counts == sorted(set(counts))):
        fail("presses", "increasing whole numbers of presses", counts)
    residuals = _numbers(stored.get("log_residuals"), (len(counts), len(names)), "log_residuals", path)
    if np.abs(residuals).max() > MAX_LOG_RESIDUAL:
        fail("log_residuals", f"log residuals within +-{MAX_LOG_RESIDUAL:g}", float(np.abs(residuals).max()))
    trained = training.get("specimens")
    if trained is not None and sorted(names) != sorted(trained):
        raise ModelFileError(f"training.{KEY}.specimens are not the specimens trained on (training.specimens)",
                             path=path)
    with np.errstate(all="ignore"):  # a forged fold is refused in one line, never with a warning before it
        folds = _folds(stored.get("folds"), loaded, names, path)
        _check_bracket(folds, loaded, path)
    return DeployedJackknife(folds, tuple(names), tuple(counts), residuals, float(stored["level"]))


def _check_bracket(folds: LawFolds | LinearFolds, loaded, path: Path | None) -> None:
    """The folds bracket the model they travel with: each is the model refitted without one specimen, so where the
    model is anchored (PLS: its training centroid, where it predicts the mean rating; the law: the centre and
    corners of its trained feature box) their predictions lie around the model's. Their spread, on either side,
    allows for folds whose nested CV chose another component count; folds that all agree (spread 0) must agree
    with the model. A file whose folds do not is refused: its interval could exclude its own prediction."""
    if isinstance(folds, LinearFolds):
        x_mean = np.asarray(loaded.x_mean_, dtype=np.float64)
        around, model = folds.coefficients @ x_mean + folds.intercepts, float(loaded.y_mean_)
        where = "at the training centroid (model.x_mean), where the model predicts model.y_mean"
    else:
        used = np.flatnonzero(np.asarray(loaded.coef_) != 0)  # their ranges are finite (checked on loading)
        low, high = np.asarray(loaded.feature_min_), np.asarray(loaded.feature_max_)
        centre = np.where(np.isfinite(low) & np.isfinite(high), 0.5 * (low + high), 0.0)
        points = [centre]
        for corner in _corners(centre.size, used):
            point = centre.copy()
            point[used] = np.where(corner[used], high[used], low[used])
            points.append(point)
        points = np.array(points)
        around = folds.beta[:, :1] + folds.beta[:, 1:] @ points.T  # (S, points): log roughness
        model = loaded.intercept_ + points @ np.asarray(loaded.coef_)
        where = "over the trained feature box (log roughness at its centre and corners)"
    low, high = np.min(around, axis=0), np.max(around, axis=0)
    slack = (high - low) + 1e-9 * (1.0 + np.abs(model))
    if np.any(model < low - slack) or np.any(model > high + slack):
        raise ModelFileError(f"training.{KEY}.folds do not bracket the model they travel with {where}: the folds "
                             f"give {float(np.min(low)):.4g} to {float(np.max(high)):.4g}, the model "
                             f"{float(np.min(model)):.4g}" + (f" to {float(np.max(model)):.4g}" if np.size(model) > 1
                                                              else ""), path=path)


def _corners(width: int, used: np.ndarray) -> list[np.ndarray]:
    """Every combination of low (False) and high (True) ends over the ``used`` features (``width`` in all)."""
    corners = []
    for code in range(2 ** used.size):
        corner = np.zeros(width, dtype=bool)
        corner[used] = [(code >> i) & 1 == 1 for i in range(used.size)]
        corners.append(corner)
    return corners


def _numbers(value, shape: tuple[int, ...], field: str, path: Path | None, *, nulls: bool = False) -> np.ndarray:
    """A nested list of numbers of ``shape`` (nulls read as NaN where allowed), finite, within MAX_FOLD_VALUE."""
    def number(v) -> bool:
        return type(v) in (int, float) or (nulls and v is None)

    rows = value if len(shape) == 2 else [value]
    if not (isinstance(value, list) and all(isinstance(r, list) and all(number(v) for v in r) for r in rows)):
        raise ModelFileError(f"training.{KEY}.{field} must be an array of numbers", path=path)
    width = shape[-1]
    if len(rows) != (shape[0] if len(shape) == 2 else 1) or any(len(r) != width for r in rows):
        found = (len(rows), *sorted({len(r) for r in rows})) if len(shape) == 2 else (len(value),)
        raise ModelFileError(f"training.{KEY}.{field} has shape {found}, expected {shape}", path=path)
    array = np.array([[np.nan if v is None else v for v in r] for r in rows], dtype=np.float64)
    array = array if len(shape) == 2 else array[0]
    if array.shape != shape:
        raise ModelFileError(f"training.{KEY}.{field} has shape {array.shape}, expected {shape}", path=path)
    if np.any(np.abs(array[~np.isnan(array)]) > MAX_FOLD_VALUE) or (not nulls and np.isnan(array).any()):
        raise ModelFileError(f"training.{KEY}.{field} holds a value that is not a finite number within "
                             f"{MAX_FOLD_VALUE:g}", path=path)
    return array


def _folds(stored, loaded, names: list, path: Path | None) -> LawFolds | LinearFolds:
    """The fold models, of the loaded model's own kind and size, each as checked as the deployed model's section."""
    from .families import family
    from .pls.file import KIND as PLS_KIND

    kind = family(loaded.family).kind  # the model's own section kind
    if not isinstance(stored, dict) or stored.get("kind") != kind:
        raise ModelFileError(f"training.{KEY}.folds must be an object of kind {kind!r} (the model's own)", path=path)
    n = len(names)
    if kind == PLS_KIND:
        coefficients = _numbers(stored.get("coefficients"), (n, loaded.n_features), "folds.coefficients", path)
        intercepts = _numbers(stored.get("intercepts"), (n,), "folds.intercepts", path)
        floors = _numbers(stored.get("floors"), (n,), "folds.floors", path)
        if np.any(floors <= 0):
            raise ModelFileError(f"training.{KEY}.folds.floors must be positive (a floor on roughness)", path=path)
        return LinearFolds(coefficients, intercepts, floors)
    return _law_folds(stored, loaded, names, path)


def _law_folds(stored: dict, loaded, names: list, path: Path | None) -> LawFolds:
    from ..sensor.grid import grid_step
    from .peak_law.file import _check_finite_predictions
    from .readout_domain import domain_margins
    from .readout_file import check_log_frequencies

    p, n = loaded.coef_.size, len(names)
    intercept = _numbers(stored.get("intercept"), (n,), "folds.intercept", path)
    coefficients = _numbers(stored.get("coefficients"), (n, p), "folds.coefficients", path)
    low = _numbers(stored.get("feature_min"), (n, p), "folds.feature_min", path, nulls=True)
    high = _numbers(stored.get("feature_max"), (n, p), "folds.feature_max", path, nulls=True)
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
