"""PLS's applicability domain: is a new spectrum like the ones the model was trained on?

PLS is linear everywhere, so it never "extrapolates" by construction; it silently predicts from any spectrum. The
chemometric answer (Hotelling T^2 on the scores, and Q, the squared residual of the spectrum off the score plane)
says when a spectrum lies outside the training data: T^2 measures how unusual it is *within* the model's plane, Q
how much of it the plane does not describe at all (a peak where no training spectrum had one). Their limits are
cross-validated: the 95th percentile of T^2 and Q of held-out rows under leave-one-specimen-out, each scored by a
model that never saw its specimen, so a new surface like the trained ones is flagged about 5 % of the time.

T^2 and Q alone miss what matters most here: a spectrum normalised to unit area with no grating in the band (a
0.5 mm grating) is close to the mean of the trained spectra, and a peak at 0.125 mm^-1 (an 8 mm grating) is a small
share of Q. So a PLS model also keeps the peak law's readout of its training surfaces (:class:`PeakDomain`): the
trained periods, contact shapes and the least clear peak, and flags a spectrum whose period or shape lies outside
them or that shows no clear peak, in the same words as the law.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...sensor.band import RIDGE_EXCLUSION_PER_MM
from ...sensor.grid import grid_step
from ..peak_search import HARMONIC, PeakReadout, peak_readout
from ..press_spread import PressScatter
from ..readout_domain import READOUT_SETTINGS, ReadoutFit, domain_reasons, fit_readout, readout_grid
from .simpls import SIMPLS

#: Share of held-out training rows inside the limits (the cross-validated percentile).
DOMAIN_LEVEL = 0.95


@dataclass(frozen=True)
class PeakDomain:
    """Where the training surfaces' spectra peak (log mm^-1, the kept range) and the least clear peak accepted."""

    freq_per_mm: np.ndarray
    log_frequency_range: tuple[float, float]
    clarity_limit: float
    pad_ridge_period_mm: float | None = None
    exclusion_per_mm: float = RIDGE_EXCLUSION_PER_MM
    #: The trained surfaces' second-harmonic log ratios (the contact's shape, sensor/shape.py); unbounded where
    #: the law could not read it on every training surface.
    harmonic_range: tuple[float, float] = (-np.inf, np.inf)
    #: The training presses' scatter about their surfaces (model/press_spread.py); None: surface margins alone.
    press_scatter: PressScatter | None = None

    @classmethod
    def of(cls, fit: ReadoutFit, pad_ridge_period_mm: float | None, exclusion_per_mm: float) -> PeakDomain:
        return cls(np.asarray(fit.freq_per_mm, float), (float(fit.feature_min[0]), float(fit.feature_max[0])),
                   float(fit.clarity_limit), pad_ridge_period_mm, float(exclusion_per_mm),
                   (float(fit.feature_min[HARMONIC]), float(fit.feature_max[HARMONIC])), fit.press_scatter)

    def reasons(self, X, n_blocks: int, surfaces=None) -> list[str]:
        readout = peak_readout(X, self.freq_per_mm, n_blocks=n_blocks, pad_ridge_period_mm=self.pad_ridge_period_mm,
                               exclusion_per_mm=self.exclusion_per_mm, surfaces=surfaces)
        unbounded = PeakReadout(np.column_stack([readout.features[:, 0], np.zeros(len(readout.clarity)),
                                                 readout.features[:, HARMONIC]]),
                                readout.clarity, readout.agreement, readout.presses,
                                readout.overshoot)  # no peak-strength range
        low = np.array([self.log_frequency_range[0], -np.inf, self.harmonic_range[0]])
        high = np.array([self.log_frequency_range[1], np.inf, self.harmonic_range[1]])
        step = grid_step(self.freq_per_mm)
        return domain_reasons(unbounded, low, high, self.clarity_limit, step, self.press_scatter)

    def to_dict(self) -> dict:
        return {"log_frequency_range": list(self.log_frequency_range), "clarity_limit": self.clarity_limit,
                "pad_ridge_period_mm": self.pad_ridge_period_mm, "exclusion_per_mm": self.exclusion_per_mm,
                "harmonic_range": [v if np.isfinite(v) else None for v in self.harmonic_range],
                **({} if self.press_scatter is None else {"press_scatter": self.press_scatter.to_dict()})}


@dataclass(frozen=True)
class SpectrumDomain:
    """Scores and residuals of spectra against one PLS model, and the cross-validated limits they are judged by."""

    x_mean: np.ndarray  # (p,)
    rotations: np.ndarray  # (p, A): scores = (X - x_mean) @ rotations
    loadings: np.ndarray  # (p, A): X - x_mean ~ scores @ loadings.T
    score_var: np.ndarray  # (A,) training variance of each score
    t2_limit: float
    q_limit: float
    peak: PeakDomain | None = None
    n_blocks: int = 1

    @classmethod
    def of(cls, model: SIMPLS, t2_limit: float = np.inf, q_limit: float = np.inf, peak: PeakDomain | None = None,
           n_blocks: int = 1) -> SpectrumDomain:
        scores = model.x_scores_
        return cls(np.asarray(model.x_mean_, float), np.asarray(model.x_weights_, float),
                   np.asarray(model.x_loadings_, float), np.var(scores, axis=0, ddof=1), float(t2_limit),
                   float(q_limit), peak, int(n_blocks))

    def statistics(self, X) -> tuple[np.ndarray, np.ndarray]:
        """Hotelling T^2 and Q (squared residual) of each row."""
        centred = np.asarray(X, dtype=np.float64) - self.x_mean
        scores = centred @ self.rotations
        t2 = np.sum(scores**2 / np.maximum(self.score_var, np.finfo(float).tiny), axis=1)
        q = np.sum((centred - scores @ self.loadings.T) ** 2, axis=1)
        return t2, q

    def reasons(self, X, surfaces=None) -> list[str]:
        """Per row, how its spectrum lies outside the training spectra ('' where it does not)."""
        t2, q = self.statistics(X)
        readable = self.peak is not None and np.all(np.asarray(X) >= 0)  # amplitude spectra: a peak to read
        peak = self.peak.reasons(X, self.n_blocks, surfaces) if readable else [""] * len(t2)
        reasons = []
        for t2_row, q_row, why in zip(t2, q, peak):
            parts = [why] if why else []
            if q_row > self.q_limit:
                parts.append(f"spectrum shape unlike any trained: residual Q {q_row:.3g} > limit {self.q_limit:.3g}")
            if t2_row > self.t2_limit:
                parts.append(f"spectrum unusual within the model: Hotelling T2 {t2_row:.3g} > limit "
                             f"{self.t2_limit:.3g}")
            reasons.append("; ".join(parts))
        return reasons

    def to_dict(self) -> dict:
        """The model file's ``applicability`` section (floats as JSON numbers)."""
        section = {"rotations": self.rotations.T.tolist(), "loadings": self.loadings.T.tolist(),
                   "score_var": self.score_var.tolist(), "t2_limit": self.t2_limit, "q_limit": self.q_limit,
                   "level": DOMAIN_LEVEL}
        if self.peak is not None:
            section["peak"] = self.peak.to_dict()
        return section


def cross_validated_limits(X: np.ndarray, y: np.ndarray, n_components: int, groups) -> tuple[float, float]:
    """The :data:`DOMAIN_LEVEL` percentiles of T^2 and Q of every row, scored by a model fitted without its group."""
    X = np.asarray(X, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    groups = np.asarray(groups)
    t2_all, q_all = np.empty(len(y)), np.empty(len(y))
    for name in np.unique(groups):
        held = groups == name
        model = SIMPLS(n_components=n_components).fit(X[~held], y[~held])
        t2_all[held], q_all[held] = SpectrumDomain.of(model).statistics(X[held])
    return float(np.quantile(t2_all, DOMAIN_LEVEL)), float(np.quantile(q_all, DOMAIN_LEVEL))


def fit_domain(model: SIMPLS, X: np.ndarray, y: np.ndarray, groups, law=None) -> SpectrumDomain:
    """The domain of a PLS model fitted on (X, y), with limits cross-validated over ``groups`` (specimens), and
    the peak readout (model/readout_domain.py) fitted here on the same trials, surfaces = ``groups``, with the
    settings ``law`` names (:data:`READOUT_SETTINGS`: a :class:`ReadoutSettings`, or an unfitted peak law's).

    Each limit is the larger of the cross-validated and the in-sample percentile: with few specimens a held-out one
    lies *between* the others, so its T^2 is smaller than the training rows' own (which average the component
    count by construction), and a limit below them would flag the training data itself.
    """
    t2_limit, q_limit = cross_validated_limits(X, y, int(model.x_weights_.shape[1]), groups)
    in_sample = SpectrumDomain.of(model)
    t2_own, q_own = in_sample.statistics(X)
    peak, n_blocks = None, 1
    if law is not None and np.all(np.asarray(X) >= 0):  # a peak is read from amplitude spectra only
        settings = {key: getattr(law, key) for key in READOUT_SETTINGS}
        X = np.asarray(X, dtype=np.float64)
        settings["freq_per_mm"] = readout_grid(X.shape[1], settings["freq_per_mm"], settings["n_blocks"])
        fit = fit_readout(X, y, **settings, surfaces=np.asarray(groups))
        peak = PeakDomain.of(fit, settings["pad_ridge_period_mm"], settings["exclusion_per_mm"])
        n_blocks = int(law.n_blocks)
    return SpectrumDomain.of(model, max(t2_limit, float(np.quantile(t2_own, DOMAIN_LEVEL))),
                             max(q_limit, float(np.quantile(q_own, DOMAIN_LEVEL))), peak, n_blocks)


def nested_domain_flags(X: np.ndarray, y: np.ndarray, groups, n_components: dict, law=None) -> np.ndarray:
    """Whether each row falls outside the domain of the model fitted without its group (its specimen): the
    applicability flag a user would have seen for a surface the model never saw.

    ``n_components``: each group's component count (the nested choice of leave-one-specimen-out); the held-out
    model's limits are cross-validated over the other groups only, as :func:`fit_domain` would compute them.
    """
    X = np.asarray(X, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    groups = np.asarray(groups).astype(str)
    flags = np.zeros(len(y), dtype=bool)
    for name in np.unique(groups):
        held = groups == name
        model = SIMPLS(n_components=int(n_components[name])).fit(X[~held], y[~held])
        domain = fit_domain(model, X[~held], y[~held], groups[~held], law)
        flags[held] = [bool(reason) for reason in domain.reasons(X[held], groups[held])]
    return flags

