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

from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
import pandas as pd

from .._util.checks import Real, short_repr
from ..errors import ModelFileError
from .interval import INTERVAL_LEVEL
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
#: The model file's ``training.jackknife_plus`` (:meth:`DeployedJackknife.to_dict`), checked by model/schema.py with
#: the families' folds (:func:`jackknife_schema`); the shapes, and that the folds bracket the model they travel with,
#: by :func:`deployed_jackknife` on loading.
SCHEMA = strict({
    "method": {"const": METHOD},
    "level": {"const": INTERVAL_LEVEL, "description": f"{INTERVAL_LEVEL} (the level predict labels pi90)"},
    "specimens": {"type": "array", "items": {"type": "string"}, "minItems": 1, "uniqueItems": True},
    "presses": {"type": "array", "items": integer(1, 10_000), "minItems": 1, "uniqueItems": True},
    "log_residuals": {"type": "array", "items": {"type": "array", "items": number(-MAX_LOG_RESIDUAL,
                                                                                    MAX_LOG_RESIDUAL)}},
    "residuals": {"const": _RESIDUALS},
    "folds": {"type": "object"},
}, required=("method", "level", "specimens", "presses", "log_residuals", "folds"))


def jackknife_schema(families) -> dict:
    """:data:`SCHEMA` with ``folds`` of any registered family's kind, holding only the fields the families' folds
    have (each family's ``fold_schema``; their shapes are its loader's to check)."""
    fields = {"kind": {"enum": sorted(family.kind for family in families)}}
    for family in families:
        fields.update(family.fold_schema)
    return {**SCHEMA, "properties": {**SCHEMA["properties"], "folds": strict(fields, required=("kind",))}}


class Folds(Protocol):
    """A family's fold models (its ``jackknife``, its ``load_folds``): each specimen's model fitted without it."""

    kind: str

    def log_predict(self, X, surfaces=None) -> np.ndarray:
        """(S, n) each fold's log prediction of each row (rows of one surface read together)."""
        ...

    def to_dict(self) -> dict:
        """The model file's ``folds`` entry (``{"kind": its family's kind, ...}``)."""
        ...

    def bracket(self, loaded) -> tuple[np.ndarray, np.ndarray | float, str]:
        """Where the folds must lie around the model they travel with: the folds' values (S, points), the model's
        (points,) there, and where that is, as a refusal names it."""
        ...


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
class DeployedJackknife:
    """Fold models and residuals by presses: the jackknife+ interval of any new surface (:meth:`intervals`)."""

    folds: Folds
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

    def intervals(self, X, surfaces=None, contact=None) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """Per row, its surface's 90 % jackknife+ bounds (low, high) and the method's label; rows of one surface
        (``surfaces``) are read together and predicted as their mean; None: each row is a surface of one press.
        ``contact``: each row's contact measures, for folds of a family that reads them (``reads_contact``)."""
        n = np.asarray(X).shape[0]
        labels = np.arange(n) if surfaces is None else np.asarray(surfaces)
        codes, _ = pd.factorize(pd.Series(labels), sort=False)
        presses = np.bincount(codes)
        rows = np.exp(self.folds.log_predict(X, None if surfaces is None else labels, **_contact(contact)))
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


def _contact(contact) -> dict:
    """The keyword a contact-reading family's folds take, only where there are contact measures (the others' folds
    take no such keyword)."""
    return {} if contact is None else {"contact": contact}


def deploy(folds: Folds, X, y, specimens, seed: int, contact=None) -> DeployedJackknife:
    """Each specimen's residual under the model that left it out, read from each kept count of presses
    (``contact``: each row's contact measures, for a family that reads them)."""
    codes, names = pd.factorize(pd.Series(np.asarray(specimens).astype(str)), sort=False)
    log_targets = np.log(pd.Series(np.asarray(y, dtype=np.float64)).groupby(codes).first().to_numpy())
    counts = press_counts(np.bincount(codes))
    X = np.asarray(X, dtype=np.float64)
    residuals = []
    for rows in press_subsets(codes, counts, seed):
        owner = codes[rows]
        mine = _contact(None if contact is None else np.asarray(contact)[rows])
        own = np.exp(folds.log_predict(X[rows], owner, **mine)[owner, np.arange(rows.size)])  # each row by its own fold
        residuals.append(log_targets - np.log(np.bincount(owner, weights=own) / np.bincount(owner)))
    return DeployedJackknife(folds, tuple(map(str, names)), counts, np.array(residuals))


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
    residuals = fold_numbers(stored.get("log_residuals"), (len(counts), len(names)), "log_residuals", path)
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


def _check_bracket(folds: Folds, loaded, path: Path | None) -> None:
    """The folds bracket the model they travel with: each is the model refitted without one specimen, so where the
    model is anchored (its family's ``bracket``: PLS's training centroid, where it predicts the mean rating; the law's
    centre and corners of its trained feature box) their predictions lie around the model's. Their spread, on either
    side, allows for folds whose nested CV chose another component count; folds that all agree (spread 0) must agree
    with the model. A file whose folds do not is refused: its interval could exclude its own prediction."""
    around, model, where = folds.bracket(loaded)
    low, high = np.min(around, axis=0), np.max(around, axis=0)
    slack = (high - low) + 1e-9 * (1.0 + np.abs(model))
    if np.any(model < low - slack) or np.any(model > high + slack):
        raise ModelFileError(f"training.{KEY}.folds do not bracket the model they travel with {where}: the folds "
                             f"give {float(np.min(low)):.4g} to {float(np.max(high)):.4g}, the model "
                             f"{float(np.min(model)):.4g}" + (f" to {float(np.max(model)):.4g}" if np.size(model) > 1
                                                              else ""), path=path)


def fold_numbers(value, shape: tuple[int, ...], field: str, path: Path | None, *, nulls: bool = False) -> np.ndarray:
    """A fold entry's ``field``: a nested list of numbers of ``shape`` (nulls read as NaN where allowed), finite,
    within MAX_FOLD_VALUE; refused in one line naming ``training.jackknife_plus.<field>``."""
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


def _folds(stored, loaded, names: list, path: Path | None) -> Folds:
    """The fold models, of the loaded model's own kind and size, each as checked as the deployed model's section
    (by its family: model/registry.py)."""
    from .registry import engine

    family = engine(loaded.family)
    if not isinstance(stored, dict) or stored.get("kind") != family.kind:
        raise ModelFileError(f"training.{KEY}.folds must be an object of kind {family.kind!r} (the model's own)",
                             path=path)
    folds = family.load_folds(stored, loaded, names, path)
    if folds is None:
        raise ModelFileError(f"training.{KEY}: the {loaded.family} family keeps no jackknife+ folds", path=path)
    return folds
