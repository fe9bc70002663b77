"""The peak readout's domain, beneath both families: the training rows a Huber fit of the readout's terms kept and
their range, the margins a feature may lie beyond it and still count as inside, and every way a row lies outside it
said in a user's words (period, peak strength, contact pattern, an unclear peak, presses that disagree).

The peak law is applied in this domain and held at its edge; a PLS model keeps the same readout of its training
surfaces (model/pls/applicability.py) and flags a spectrum outside it in the same words. :func:`fit_readout` is that
fit, the one both take.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sensor.band import RIDGE_EXCLUSION_PER_MM
from ..sensor.shape import duty_cycle
from .huber_batch import HUBER_EPSILON
from .peak_search import (
    AMPLITUDE,
    FREQUENCY,
    HARMONIC,
    PeakLawInputError,
    PeakReadout,
    check_grid,
    check_settings,
    fit_terms,
    peak_readout,
    press_deviations,
    shape_read,
    surface_codes,
)
from .press_spread import PressScatter, robust_spread, trained_presses

#: A training row counts as kept by the Huber fit when its final weight is at least this (|residual| <= 2 epsilon
#: scale): its features bound the range the law is applied in (:func:`kept_rows`).
KEPT_WEIGHT = 0.5
#: Slack (log units, a factor 1.65) on the peak's strength and a surface's clarity before a row counts as outside
#: what was trained: held-out gratings like the trained ones lay up to 0.43 beyond the others on seeds 0-2 (a
#: 2.5 mm press's strength; a 4 mm surface's clarity on the fingerprint pad by 0.3), where the flagged 0.5 and 1 mm
#: gratings' surfaces stood 0.6-1.9 below.
LOG_MARGIN = 0.5
#: Presses of one surface that peak elsewhere than the surface: below this share, there is no one period to read.
MIN_AGREEMENT = 1 / 3
#: Features more than this (in log units) outside the training range count as extrapolation (rounding aside).
_RANGE_TOL = 1e-9


def kept_rows(features: np.ndarray, log_y: np.ndarray, beta: np.ndarray, scale: float, epsilon: float,
              surfaces=None) -> np.ndarray:
    """The rows the Huber fit kept: final weight at least :data:`KEPT_WEIGHT` (|residual| <= 2 epsilon scale).

    A misread peak is down-weighted, not dropped, so the raw training range would include it: a law trained on a
    1N fingerprint study with one press read at 0.13 mm^-1 would then call an 8 mm grating "inside". The range of
    the kept rows is the range the law was actually fitted on. With ``surfaces``, a surface most of whose presses
    are down-weighted keeps them all: its *rating* is what the law misses, and its features are real.
    """
    residual = log_y - beta[0] - np.nan_to_num(features) @ beta[1:]  # a NaN feature is no term: coefficient 0
    return _kept(np.abs(residual)[None, None], np.array([[scale]]), epsilon, np.ones((1, len(log_y)), bool),
                 surfaces)[0, 0]


def _kept(absolute: np.ndarray, scale: np.ndarray, epsilon: float, train: np.ndarray, surfaces) -> np.ndarray:
    """(F, B, n) kept training rows from absolute residuals (F, B, n), scales (F, B) and training masks (F, n)."""
    kept = (absolute <= epsilon * scale[:, :, None] / KEPT_WEIGHT * (1 + 1e-12)) & train[:, None, :]
    if surfaces is not None:
        codes = surface_codes(surfaces, absolute.shape[-1])
        members = np.zeros((codes.size, int(codes.max()) + 1))
        members[np.arange(codes.size), codes] = 1.0
        trained = train.astype(float) @ members  # (F, S) training presses of each surface
        share = (kept.astype(float) @ members) / np.maximum(trained, 1.0)[:, None, :]
        kept |= (share < 0.5)[:, :, codes] & train[:, None, :]
    return np.where(kept.any(axis=2, keepdims=True), kept, train[:, None, :])


def outside_each(features: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """(n, p) booleans: which of a row's features lies outside the range (rounding aside; NaN is not outside)."""
    return (features < low - _RANGE_TOL) | (features > high + _RANGE_TOL)


def domain_margins(freq_step_per_mm: float, low: np.ndarray, high: np.ndarray, extra=None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The law's domain: the kept training range (``low``, ``high``: (..., 2)) widened by what a feature may lie
    beyond it and still count as inside. The law is applied unclipped inside and held at the domain's edge outside,
    so a prediction is held exactly when it is flagged (for a surface read from fewer presses than the trained ones,
    only beyond its presses' scatter, ``extra``, is it flagged).

    The period is read to about half a grid bin, so two gratings of one period can read 1-2 % apart: half a bin
    either side of the trained frequencies. The peak strength varies from press to press by more than that:
    :data:`LOG_MARGIN` either side. ``extra`` (n, p): a surface of few presses' excess scatter
    (model/press_spread.py), added in quadrature: (n, p) margins, for the flags only.
    """
    step = float(freq_step_per_mm)
    low, high = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    below, above = np.full(low.shape, LOG_MARGIN), np.full(high.shape, LOG_MARGIN)
    below[..., 0] = np.log1p(0.5 * step / np.exp(low[..., 0]))
    above[..., 0] = np.log1p(0.5 * step / np.exp(high[..., 0]))
    if extra is not None:
        below, above = np.hypot(below, extra), np.hypot(above, extra)
    return low - below, high + above


def range_reasons(features: np.ndarray, low: np.ndarray, high: np.ndarray, *, shown=None, tolerated=None
                  ) -> list[str]:
    """Per row, what lies outside the range [low, high] (margins included), in a user's words ('' where nothing).

    The frequency is said as a period (what a user designs), the amplitude as the peak's strength; ``shown``: the
    range the message quotes (the trained one, without the margins), default [low, high].
    """
    outside = outside_each(features, low, high)
    # The law reads the contact's shape where its range is bounded; a row whose shape cannot be read is then unsure.
    unread = np.isnan(features) & np.isfinite(low) & np.isfinite(high)
    if tolerated is not None:  # a shape unread only because the period's scatter put its harmonic past the band
        unread[:, HARMONIC:] &= ~np.asarray(tolerated, dtype=bool)[:, None]
    low, high = (low, high) if shown is None else shown
    reasons = []
    for row, out, blind in zip(features, outside, unread):
        parts = []
        if out[FREQUENCY]:
            parts.append(f"period {np.exp(-row[0]):.2f} mm outside the trained {np.exp(-high[0]):.2f}-"
                         f"{np.exp(-low[0]):.2f} mm")
        if out[AMPLITUDE]:
            side = "weaker" if row[1] < low[1] else "stronger"
            parts.append(f"peak strength {np.exp(row[1]):.3g} {side} than any trained ({np.exp(low[1]):.3g}-"
                         f"{np.exp(high[1]):.3g})")
        if len(row) > HARMONIC and (out[HARMONIC] or blind[HARMONIC]):
            parts.append(_shape_words(row[HARMONIC], low[HARMONIC], high[HARMONIC]))
        reasons.append("; ".join(parts))
    return reasons


def _shape_words(ratio: float, low: float, high: float) -> str:
    """The contact's shape against the trained ones, as the pulse train's duty cycle (sensor/shape.py)."""
    trained = f"trained surfaces {duty_cycle(high):.2f}-{duty_cycle(low):.2f} of the period in contact"
    if np.isnan(ratio):
        return f"contact pattern not readable (its second harmonic lies on the pad's ridges or past the band); {trained}"
    kind = "narrower ridges" if ratio > high else "wider lands"
    return (f"contact pattern unlike any trained surface: {kind} (about {duty_cycle(ratio):.2f} of the period in "
            f"contact; {trained})")


def domain_reasons(readout: PeakReadout, low: np.ndarray, high: np.ndarray, clarity_limit: float | None,
                   freq_step_per_mm: float, scatter: PressScatter | None = None) -> list[str]:
    """Per row, every way it lies outside the law's domain ('' where none): period and peak strength outside the
    kept training range (:func:`domain_margins`), a spectrum with no clear peak, presses that disagree on where the
    peak is. ``clarity_limit`` None: a model file written before the clarity was kept (not checked).
    ``scatter``: the training presses' scatter about their surfaces (model/press_spread.py); a row read from fewer
    presses than the trained surfaces is flagged only beyond it too. None: the surface margins alone."""
    slack, tolerated, extra = np.zeros(len(readout.clarity)), None, None
    if scatter is not None and readout.presses is not None:
        extra = scatter.excess(readout.presses)  # (n, 4)
        slack = np.hypot(LOG_MARGIN, extra[:, 3]) - LOG_MARGIN
        if readout.overshoot is not None:
            tolerated = (readout.overshoot > 0) & (readout.overshoot <= extra[:, FREQUENCY])
    low_m, high_m = domain_margins(freq_step_per_mm, low, high, None if extra is None else extra[:, :3])
    reasons = range_reasons(readout.features, low_m, high_m, shown=(low, high), tolerated=tolerated)
    for i, clarity in enumerate(readout.clarity):
        parts = [reasons[i]] if reasons[i] else []
        if clarity_limit is not None and clarity < clarity_limit - slack[i]:
            parts.append(f"spectrum shape: no clear peak (it stands {clarity:.2f} log units above the band's median, "
                         f"every trained surface at least {clarity_limit - slack[i]:.2f})")
        if readout.agreement[i] < MIN_AGREEMENT:
            parts.append(f"only {readout.agreement[i]:.0%} of the surface's presses peak at its period")
        reasons[i] = "; ".join(parts)
    return reasons


def kept_range(features: np.ndarray, kept: np.ndarray, read: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F, B, p) low and high of each feature over the kept rows (F, B, n). The second-harmonic ratio bounds the
    domain only where the shape is read (``read`` (F,), :func:`shape_read`); elsewhere its range is unbounded, so
    nothing is flagged for it."""
    columns = range(features.shape[1])
    low = np.stack([np.where(kept, features[:, j], np.inf).min(axis=2) for j in columns], axis=-1)
    high = np.stack([np.where(kept, features[:, j], -np.inf).max(axis=2) for j in columns], axis=-1)
    if features.shape[1] > HARMONIC:
        unused = ~read[:, None]
        low[..., HARMONIC] = np.where(unused, -np.inf, low[..., HARMONIC])
        high[..., HARMONIC] = np.where(unused, np.inf, high[..., HARMONIC])
    return low, high


#: The settings a peak readout is fitted with, as the peak law's estimator names them (its parameters).
READOUT_SETTINGS = ("freq_per_mm", "n_blocks", "pad_ridge_period_mm", "exclusion_per_mm", "epsilon")


@dataclass(frozen=True)
class ReadoutSettings:
    """:data:`READOUT_SETTINGS` for a family that reads peaks without being the law, with the law's defaults."""

    freq_per_mm: np.ndarray
    n_blocks: int = 1
    pad_ridge_period_mm: float | None = None
    exclusion_per_mm: float = RIDGE_EXCLUSION_PER_MM
    epsilon: float = HUBER_EPSILON


@dataclass(frozen=True)
class ReadoutFit:
    """The Huber fit of log y on a readout's terms (intercept, coefficients, robust scale) and the domain of the
    rows it kept: each feature's range, the least clear kept peak less :data:`LOG_MARGIN`, and (surfaces given) the
    training presses' scatter about their surfaces. ``freq_per_mm``: the checked grid it was read on."""

    freq_per_mm: np.ndarray
    intercept: float
    coef: np.ndarray
    scale: float
    feature_min: np.ndarray
    feature_max: np.ndarray
    clarity_limit: float
    press_scatter: PressScatter | None


def readout_grid(n_features: int, freq_per_mm, n_blocks: int, default_band_per_mm=None) -> np.ndarray:
    """The grid of each of a row's ``n_blocks`` spectra, checked against the row's width (``freq_per_mm`` None: K
    evenly spaced frequencies over ``default_band_per_mm``)."""
    blocks = check_settings(n_blocks=n_blocks)["n_blocks"]
    if n_features % blocks:
        raise PeakLawInputError(f"{n_features} feature(s) cannot be split into {blocks} equal spectra")
    k_bins = n_features // blocks
    if freq_per_mm is None:
        return np.linspace(*default_band_per_mm, k_bins)
    freq = check_grid(freq_per_mm)
    if freq.size != k_bins:
        raise PeakLawInputError(
            f"{n_features} feature(s) in {blocks} block(s) do not match the {freq.size}-frequency grid")
    return freq


def fit_readout(X: np.ndarray, y: np.ndarray, *, freq_per_mm, n_blocks: int, pad_ridge_period_mm: float | None,
                exclusion_per_mm: float, epsilon: float, surfaces=None) -> ReadoutFit:
    """Read each row's peak (rows of one surface share where it is read), fit log ``y`` on its terms by Huber's
    M-estimator and keep the domain of the rows the fit kept. ``X``: non-negative spectra; ``y``: positive;
    ``freq_per_mm``: the grid of each of a row's spectra, as :func:`readout_grid` checks it."""
    check_settings(pad_ridge_period_mm=pad_ridge_period_mm, exclusion_per_mm=exclusion_per_mm, epsilon=epsilon)
    y = np.asarray(y, dtype=np.float64)
    if np.any(y <= 0):
        raise PeakLawInputError("perceived roughness must be positive (magnitude estimates); the law is fitted in logs")
    reading = {"freq_per_mm": freq_per_mm, "n_blocks": int(n_blocks),
               "pad_ridge_period_mm": pad_ridge_period_mm, "exclusion_per_mm": float(exclusion_per_mm)}
    readout = peak_readout(X, **reading, surfaces=surfaces)
    features = readout.features
    beta, scale = fit_terms(features, np.log(y)[None, :], np.ones((1, len(y)), dtype=bool),
                            epsilon=float(epsilon), grouped=surfaces is not None)
    kept = kept_rows(features, np.log(y), beta[0, 0], float(scale[0, 0]), float(epsilon), surfaces)
    low, high = kept_range(features, kept[None, None],
                           shape_read(features, np.ones((1, len(y)), dtype=bool), surfaces is not None))
    everything = np.ones((1, len(y)), dtype=bool)
    press_scatter = None if surfaces is None else PressScatter(
        robust_spread(press_deviations(X, readout, **reading), everything)[0],
        float(trained_presses(surface_codes(surfaces, len(y)), everything)[0]))
    return ReadoutFit(reading["freq_per_mm"], float(beta[0, 0, 0]), beta[0, 0, 1:].copy(), float(scale[0, 0]),
                      low[0, 0], high[0, 0], float(readout.clarity[kept].min()) - LOG_MARGIN, press_scatter)
