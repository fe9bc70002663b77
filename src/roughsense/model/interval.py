"""90 % prediction intervals from a model's own leave-one-specimen-out residuals (the plain jackknife, in logs).

Perceived roughness is a positive ratio to the reference, and its errors grow with it, so residuals are taken in
logs (log perceived - log predicted) and an interval is ``prediction x exp(-h) .. prediction x exp(+h)``: always
positive, wider in absolute terms for rougher surfaces. ``h`` is the ceil((n + 1) level)-th smallest absolute
residual of the out-of-fold predictions under leave-one-specimen-out, put around the *full* model's prediction.
That is the jackknife, not split-conformal: the residuals come from other models than the one deployed, so the
split-conformal guarantee does not hold (model/jackknife_plus.py gives a surface interval that has one, and the
study's nested check). Two are kept:

- per trial (one press, or one combined trial): over every trial's residual;
- per surface (the mean prediction of a surface's presses): over every specimen's, so n is the number of specimens.

Trials of one specimen share its target, so their residuals are not independent: the per-trial quantile is honest
about the spread of presses, and the per-surface one about the spread between surfaces; the study checks both on
held-out specimens (analysis/unseen.py) rather than trusting a theorem.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .schema import integer, number, strict

#: The interval's nominal coverage.
INTERVAL_LEVEL = 0.9
#: Largest log half-width a model file may hold (a factor e^50 either way; real ones are below 1).
MAX_LOG_HALFWIDTH = 50.0
_RESIDUALS = "log(perceived) - log(predicted), leave-one-specimen-out"
_METHOD = "jackknife: no coverage guarantee (the study checks the jackknife+ over specimens)"
_WIDTH = number(0.0, MAX_LOG_HALFWIDTH, null=True)
#: The model file's ``training.interval`` (:meth:`PredictionInterval.to_dict`), checked by model/schema.py.
SCHEMA = strict({
    "level": {"const": INTERVAL_LEVEL, "description": f"{INTERVAL_LEVEL} (the level roughsense writes and labels "
                                                      "pi90)"},
    "trial_log_halfwidth": _WIDTH, "surface_log_halfwidth": _WIDTH, "alone_log_halfwidth": _WIDTH,
    "n_trials": integer(0, None), "n_surfaces": integer(0, None),
    "residuals": {"const": _RESIDUALS}, "method": {"const": _METHOD},
}, required=("level", "trial_log_halfwidth", "surface_log_halfwidth"))


def conformal_halfwidth(absolute_residuals, level: float = INTERVAL_LEVEL) -> float:
    """The ceil((n + 1) level)-th smallest |residual| (inf when n is too small for the level)."""
    values = np.sort(np.asarray(absolute_residuals, dtype=np.float64).ravel())
    rank = math.ceil((values.size + 1) * level)
    return float(values[rank - 1]) if 1 <= rank <= values.size else float("inf")


def positive(predictions, floor) -> np.ndarray:
    """Predictions held at ``floor`` (a number, or one per row) or above (PLS can predict <= 0; a log residual
    needs a positive value)."""
    return np.maximum(np.asarray(predictions, dtype=np.float64), floor)


def held_out_floors(targets, surfaces) -> np.ndarray:
    """Per row, the floor a model fitted without the row's surface holds its predictions at: half the smallest
    target of the *other* surfaces (a loaded PLS file's floor), so a held-out rating never raises its own prediction."""
    targets = np.asarray(targets, dtype=np.float64)
    codes, _ = pd.factorize(pd.Series(np.asarray(surfaces)), sort=False)
    smallest = pd.Series(targets).groupby(codes).min().to_numpy()
    order = np.argsort(smallest)
    first, second = smallest[order[0]], smallest[order[1]] if smallest.size > 1 else np.inf
    others = np.where(codes == order[0], second, first)
    return 0.5 * others


def log_residuals(predictions, targets, surfaces, floor) -> tuple[np.ndarray, np.ndarray]:
    """Per-trial and per-surface residuals log(target) - log(prediction); a surface's prediction is its trials'
    mean, as :meth:`PredictionInterval.surface_bounds` predicts one."""
    predicted = positive(predictions, floor)
    targets = np.asarray(targets, dtype=np.float64)
    trial = np.log(targets) - np.log(predicted)
    frame = pd.DataFrame({"surface": np.asarray(surfaces), "prediction": predicted, "target": targets})
    means = frame.groupby("surface", sort=False).mean()
    return trial, np.log(means["target"].to_numpy()) - np.log(means["prediction"].to_numpy())


@dataclass(frozen=True)
class PredictionInterval:
    """Half-widths (log units) of the interval around a trial's and a surface's prediction."""

    trial_log_halfwidth: float
    surface_log_halfwidth: float
    level: float = INTERVAL_LEVEL
    n_trials: int = 0
    n_surfaces: int = 0
    #: A press read alone (no other press of its surface given): the peak law reads it less surely than with its
    #: surface's other presses, so its interval is calibrated on LOSO predictions made that way. NaN: the same.
    alone_log_halfwidth: float = float("nan")

    @classmethod
    def from_cv(cls, predictions, targets, surfaces, *, floor=None, level: float = INTERVAL_LEVEL,
                alone_predictions=None) -> PredictionInterval:
        """From out-of-fold (LOSO) predictions of the training trials, their targets and specimens.

        ``floor``: what predictions are held at (default: each held-out specimen's deployed floor,
        :func:`held_out_floors`); ``alone_predictions``: the same trials each read alone, if that differs.
        """
        floor = held_out_floors(targets, surfaces) if floor is None else floor
        trial, surface = log_residuals(predictions, targets, surfaces, floor)
        alone = float("nan")
        if alone_predictions is not None:
            alone = conformal_halfwidth(np.abs(log_residuals(alone_predictions, targets, surfaces, floor)[0]), level)
        return cls(conformal_halfwidth(np.abs(trial), level), conformal_halfwidth(np.abs(surface), level), level,
                   int(trial.size), int(surface.size), alone)

    def press_halfwidth(self, read_alone: bool) -> float:
        """The half-width of a trial's interval: read alone, or with its surface's other presses."""
        return self.alone_log_halfwidth if read_alone and math.isfinite(self.alone_log_halfwidth) \
            else self.trial_log_halfwidth

    @property
    def finite(self) -> bool:
        return math.isfinite(self.trial_log_halfwidth) and math.isfinite(self.surface_log_halfwidth)

    def trial_bounds(self, predictions, *, read_alone: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) around each trial's prediction (:meth:`press_halfwidth`; 0 and inf when it is not known)."""
        predicted = np.asarray(predictions, dtype=np.float64)
        width = self.press_halfwidth(read_alone)
        return predicted * math.exp(-width), predicted * math.exp(width)

    def surface_bounds(self, predictions) -> tuple[np.ndarray, np.ndarray]:
        predicted = np.asarray(predictions, dtype=np.float64)
        return predicted * math.exp(-self.surface_log_halfwidth), predicted * math.exp(self.surface_log_halfwidth)

    def to_dict(self) -> dict:
        """The model file's ``interval`` entry; a half-width too few residuals cannot give is null."""
        def finite(value: float) -> float | None:
            return value if math.isfinite(value) else None

        return {"level": self.level, "trial_log_halfwidth": finite(self.trial_log_halfwidth),
                "surface_log_halfwidth": finite(self.surface_log_halfwidth),
                "alone_log_halfwidth": finite(self.alone_log_halfwidth), "n_trials": self.n_trials,
                "n_surfaces": self.n_surfaces, "residuals": _RESIDUALS, "method": _METHOD}


def check_record(record: dict, document: dict, fail) -> None:
    """A stored interval's counts: those of the training record, and enough residuals for each width it gives
    (:func:`conformal_halfwidth` is infinite, stored null, below ``ceil((n + 1) level)`` residuals)."""
    training = document.get("training", {})
    for name, counted, what in (("n_trials", training.get("n_samples"), "training.n_samples"),
                                ("n_surfaces", len(training.get("specimens", [])) or None, "training.specimens")):
        if name in record and counted is not None and record[name] != counted:
            fail(name, f"is {record[name]}, but {what} gives {counted}")
    for width, name in (("trial_log_halfwidth", "n_trials"), ("surface_log_halfwidth", "n_surfaces"),
                        ("alone_log_halfwidth", "n_trials")):
        if name not in record:
            continue
        enough = 1 <= math.ceil((record[name] + 1) * INTERVAL_LEVEL) <= record[name]
        if record.get(width) is not None and not enough:
            fail(width, f"is {record[width]}, but {record[name]} residuals give no {INTERVAL_LEVEL:g} interval")
        if record.get(width, 0.0) is None and enough and width != "alone_log_halfwidth":
            fail(width, f"is null, but {record[name]} residuals give a {INTERVAL_LEVEL:g} interval")


def held_out_coverage(predictions, targets, surfaces, *, floor=None, level: float = INTERVAL_LEVEL
                      ) -> tuple[float, float]:
    """Empirical coverage of the intervals on held-out specimens: each specimen's interval is built from the
    other specimens' residuals only, then asked whether it holds the specimen's perceived roughness.

    Returns (share of trials covered, share of specimens whose surface interval covers them). ``floor`` as in
    :meth:`PredictionInterval.from_cv`.
    """
    floor = held_out_floors(targets, surfaces) if floor is None else floor
    trial, surface = log_residuals(predictions, targets, surfaces, floor)
    codes, _ = pd.factorize(pd.Series(np.asarray(surfaces)), sort=False)
    covered_trials = 0
    for code in range(surface.size):
        mine = codes == code
        covered_trials += int(np.sum(np.abs(trial[mine]) <= conformal_halfwidth(np.abs(trial[~mine]), level)))
    covered_surfaces = np.abs(surface) <= held_out_halfwidths(surface, level)
    return covered_trials / trial.size, float(np.mean(covered_surfaces))


def held_out_halfwidths(surface_residuals, level: float = INTERVAL_LEVEL) -> np.ndarray:
    """Per surface, the half-width of its interval built from the *other* surfaces' residuals only."""
    residuals = np.abs(np.asarray(surface_residuals, dtype=np.float64))
    return np.array([conformal_halfwidth(np.delete(residuals, i), level) for i in range(residuals.size)])
