"""Fitting and validating the simulated finger (:mod:`roughsense.sim.finger`) against given ratings.

Not part of the package: the fitted constants are committed in ``finger.py``, so only ``fit_finger_to_paper.py`` beside this
file (which passes the paper's values and prints those constants) and the tests use it. The functions take the
targets as arguments and read no table.

Free parameters: the receptor depth (searched over the SA1 range 0.5-1.0 mm), the saturation strain (searched on
a log grid over 3-30 %) and the psychophysical exponent (least squares in logs, through R3 = 1, in closed form).
The contact does not depend on any of them, so it is solved once per specimen and the grid search is cheap.

The yardstick is :func:`geometric_leave_one_out`, a two-parameter law with no mechanics at all: on the paper's
gratings the finger has to beat it to show that its mechanics add anything (docs/simulator.md: it does not).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls
from scipy.stats import spearmanr, wilcoxon

from roughsense.paper import REFERENCE_SPECIMEN
from roughsense.sim.finger import FINGER, Finger, _median_variance, contact_pressures, sa1_rate, subsurface_strain
from roughsense.sim.specimens import PRESETS, Specimen

DEPTHS_MM = tuple(round(0.5 + 0.05 * i, 2) for i in range(11))  # SA1 (Merkel) depth range, 0.5-1.0 mm
# SA1 rate-intensity functions are near linear over everyday indentations (docs/simulator.md): a saturation below a
# few percent strain would saturate every receptor under a 1 N touch, so the search starts at 3 %.
SATURATIONS = tuple(float(v) for v in np.geomspace(0.03, 0.3, 11))
SESSION_SHARE = 0.3  # of a person's non-exponent log-variance, as in sim.panel (not identifiable from the SDs)


@dataclass(frozen=True)
class Fit:
    receptor_depth_mm: float
    saturation_strain: float
    exponent: float
    rms_log_error: float


@dataclass(frozen=True)
class Validation:
    """Leave-one-specimen-out: each specimen predicted by a fit on the others."""

    names: tuple[str, ...]
    predicted: np.ndarray  # magnitude estimates (R3 = 1)
    observed: np.ndarray
    folds: tuple  # the fit of each fold: a Fit for the finger, (b, c) for the geometric law

    @property
    def abs_log_errors(self) -> np.ndarray:
        return np.abs(np.log(self.predicted / self.observed))

    @property
    def median_abs_log_error(self) -> float:
        return float(np.median(self.abs_log_errors))

    @property
    def spearman(self) -> float:
        return float(spearmanr(self.predicted, self.observed)[0])


class _Table:
    """log(S / S_R3) for every specimen at every (depth, saturation) of the grid."""

    def __init__(self, specimens: Sequence[Specimen], finger: Finger):
        everyone = [PRESETS[REFERENCE_SPECIMEN], *specimens]
        solved = [contact_pressures(s, finger) for s in everyone]
        table = np.empty((len(DEPTHS_MM), len(SATURATIONS), len(everyone)))
        for i, depth in enumerate(DEPTHS_MM):
            strains = [subsurface_strain(p, length, depth, finger.young_pa, finger.poisson) for length, p in solved]
            for j, saturation in enumerate(SATURATIONS):
                table[i, j] = [sa1_rate(e, saturation).std(axis=1).mean() for e in strains]
        self.log_ratio = np.log(table[:, :, 1:] / table[:, :, :1])  # (depth, saturation, specimen)

    def fit(self, y: np.ndarray, use: np.ndarray) -> Fit:
        x = self.log_ratio[:, :, use]
        exponent = (x * y[use]).sum(axis=2) / np.maximum((x * x).sum(axis=2), 1e-300)
        rss = ((exponent[:, :, None] * x - y[use]) ** 2).sum(axis=2)
        i, j = np.unravel_index(int(np.argmin(rss)), rss.shape)
        return Fit(DEPTHS_MM[i], SATURATIONS[j], float(exponent[i, j]), float(math.sqrt(rss[i, j] / use.sum())))

    def predict(self, fit: Fit, k: int) -> float:
        i, j = DEPTHS_MM.index(fit.receptor_depth_mm), SATURATIONS.index(fit.saturation_strain)
        return float(math.exp(fit.exponent * self.log_ratio[i, j, k]))


def _targets(specimens: Sequence[Specimen], ratings: Sequence[float]) -> np.ndarray:
    if len(specimens) != len(ratings) or len(specimens) < 3:
        raise ValueError("give at least three specimens and one rating (R3 = 1) per specimen")
    if any(s.name == REFERENCE_SPECIMEN for s in specimens):
        raise ValueError(f"{REFERENCE_SPECIMEN} is the reference (1 by definition), not a rated specimen")
    return np.log(np.asarray(ratings, dtype=float))


def fit_readout(specimens: Sequence[Specimen], ratings: Sequence[float], *, finger: Finger = FINGER) -> Fit:
    """Depth, saturation and exponent minimising the squared log error of the magnitude estimates."""
    y = _targets(specimens, ratings)
    return _Table(specimens, finger).fit(y, np.ones(len(y), dtype=bool))


def leave_one_out(specimens: Sequence[Specimen], ratings: Sequence[float], *, finger: Finger = FINGER) -> Validation:
    """Refit without each specimen in turn and predict it."""
    y = _targets(specimens, ratings)
    table = _Table(specimens, finger)
    predicted, folds = np.empty(len(y)), []
    for k in range(len(y)):
        use = np.arange(len(y)) != k
        fold = table.fit(y, use)
        folds.append(fold)
        predicted[k] = table.predict(fold, k)
    return Validation(tuple(s.name for s in specimens), predicted, np.exp(y), tuple(folds))


def fit_spread(log_ratios: Sequence[float], sd_over_gmean: Sequence[float], exponent: float, *,
               sessions: int = 3) -> tuple[float, float, float]:
    """(scale_sd, exponent_sd, session_sd) so that the log-SD across people's medians is as observed.

    The SD of log medians is sqrt(scale_sd^2 + (exponent * exponent_sd * L)^2 + m * session_sd^2) for a specimen at
    log ratio L (m: variance of a median of ``sessions`` normals), so the observed log-variances are regressed on
    [1, L^2] with non-negative coefficients. The intercept is split between person and session in the panel's
    fixed proportion (``SESSION_SHARE``): the SDs of medians alone cannot tell them apart.
    """
    L = np.asarray(log_ratios, dtype=float)
    cv = np.asarray(sd_over_gmean, dtype=float)
    log_var = np.log1p(cv**2)  # lognormal: SD/mean -> variance of the logs
    (c0, c1), _ = nnls(np.column_stack([np.ones_like(L), L**2]), log_var)
    per_rating = c0 / ((1 - SESSION_SHARE) + SESSION_SHARE * _median_variance(sessions))
    return (math.sqrt((1 - SESSION_SHARE) * per_rating), math.sqrt(c1) / exponent,
            math.sqrt(SESSION_SHARE * per_rating))


def geometric_features(specimens: Sequence[Specimen]) -> np.ndarray:
    """[log(period / 3 mm), 1 if circular]: the geometric law's inputs, both 0 for the reference R3."""
    period = PRESETS[REFERENCE_SPECIMEN].wavelength_mm
    return np.column_stack([np.log([s.wavelength_mm / period for s in specimens]),
                            [float(s.shape == "circular") for s in specimens]])


def geometric_leave_one_out(specimens: Sequence[Specimen], ratings: Sequence[float]) -> Validation:
    """The finger's yardstick: log rating = b log(period / 3 mm) + c [circular], refitted without each specimen.

    Two parameters, least squares in logs, through R3 = 1 like the finger's exponent; it knows a grating's period
    and family and nothing of skin, depth or force.
    """
    y = _targets(specimens, ratings)
    x = geometric_features(specimens)
    predicted, folds = np.empty(len(y)), []
    for k in range(len(y)):
        use = np.arange(len(y)) != k
        coef = np.linalg.lstsq(x[use], y[use], rcond=None)[0]
        folds.append((float(coef[0]), float(coef[1])))
        predicted[k] = math.exp(float(x[k] @ coef))
    return Validation(tuple(s.name for s in specimens), predicted, np.exp(y), tuple(folds))


def paired_p(a: Validation, b: Validation) -> float:
    """Two-sided exact Wilcoxon signed-rank p of the paired |log errors| of two validations of the same specimens."""
    if a.names != b.names:
        raise ValueError("the two validations must hold the same specimens in the same order")
    return float(wilcoxon(a.abs_log_errors, b.abs_log_errors, method="exact").pvalue)
