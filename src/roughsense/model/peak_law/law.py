"""Peak power law: perceived roughness as a power law of where the contact spectrum peaks, and of the contact's shape.

Why a second model. PLS is linear in the 45 amplitudes, and each grating puts its fundamental into bins that no other
training grating excites, so for a surface it never saw it has nothing to go on (under leave-one-specimen-out the
paper's PLS sits at the training mean's error). Roughness that people perceive by spatial coding grows with the
spacing of the contact pattern, and the spacing *moves* the spectrum's peak: a law in where the peak is (and in the
contact's shape) extrapolates to a period between, or just beside, the trained ones. The peak's height is no term.

The law, in logs, with 2 or 3 parameters::

    log(roughness) = b0 + b1 * log(peak frequency, mm^-1) [+ b3 * log(A(2 f0) / A(f0))]

- *Peak frequency*: the highest local maximum of the spectrum (averaged over a trial's forces), refined below the
  grid spacing by a parabola through the log amplitudes of the peak bin and its two neighbours (exact for a Gaussian
  lobe, which a Hann-windowed line's main lobe nearly is). The band's two end bins are never peaks (no neighbour on
  one side), and a fingerprint pad's own ridge frequency, 1 / ``pad_ridge_period_mm``, is excluded with
  ``exclusion_per_mm`` on either side: its relief is a pattern of the pad, not of the surface.
- *Peak amplitude*: the log amplitude at the refined peak. It earned no term under leave-one-specimen-out (its
  coefficient is 0) and bounds the domain only.
- *Shape*: the second harmonic's log ratio to the fundamental (sensor/shape.py: a square grating's is far below 0, a
  narrow contact's near 0), read on the surface's mean spectrum. A term only where every training surface shows it
  and they span more than one shape (:func:`law_terms`); it bounds the domain wherever it is read.
- *Fit*: Huber's M-estimator (epsilon 1.345, scale by the median absolute residual, iteratively reweighted least
  squares), because an image whose peak was misread (a fingerprint pad's lobe or a low-frequency shading hump) is an
  outlier that least squares would follow.
- *Surfaces*: rows labelled as presses of one surface share where its peak is (read from their mean spectrum);
  each keeps its own peak amplitude there (:func:`peak_features`).
- *Prediction*: features are clipped to the range of the training rows the fit kept (a power law is not carried
  past its data), and :meth:`PeakPowerLaw.applicability` says, in a user's words, what lies outside what the law
  was fitted on (period, peak strength, contact pattern, a spectrum with no clear peak, presses that disagree).

Nothing is chosen from the targets: the features, the rule for the terms (spectra only) and epsilon are fixed, so
cross-validating the fit is
all the nesting there is (docs/peak_law.md says how they were chosen, and on which data). Every fold of a
cross-validation, and every shuffled target of the permutation control, is fitted in one batched IRLS
(:func:`peak_law_cv`), the same arithmetic as a refit of :class:`PeakPowerLaw` on that fold.
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from ... import defaults
from ...sensor.band import RIDGE_EXCLUSION_PER_MM
from ...sensor.grid import grid_step
from ..huber_batch import HUBER_EPSILON
from ..loaded import FromModelFile
from ..peak_search import (
    PeakLawInputError,
    PeakReadout,
    check_settings,
    peak_readout,
)
from ..readout_domain import domain_margins, domain_reasons, fit_readout, readout_grid
from ..registry import PEAK_LAW as NAME  # the family's name, beside its class
from .domain import _check_positive, predict_law

#: The paper's band when a caller gives no grid: n evenly spaced frequencies over 0.1-1.0 mm^-1.
_DEFAULT_BAND_PER_MM = (defaults.F_MIN_PER_MM, defaults.F_MAX_PER_MM)


class PeakPowerLaw(FromModelFile, RegressorMixin, BaseEstimator):
    """scikit-learn regressor: spectra (n, n_blocks x K) -> perceived roughness, by a power law of the spectrum's peak.

    roughness = exp(intercept + coef . (log peak frequency, log peak amplitude, log second-harmonic ratio)), fitted by
    Huber regression in logs on its terms (:func:`law_terms`; a feature that is no term has coefficient 0).

    ``freq_per_mm``: the spectra's grid (K frequencies; default K evenly spaced over 0.1-1.0 mm^-1);
    ``n_blocks``: spectra per row (3 for a combined-force trial); ``pad_ridge_period_mm``: the pad's ridge period
    (a fingerprint pad's), whose frequency is left out of the peak search; ``epsilon``: Huber's constant.
    ``fit``, ``predict`` and ``applicability`` take ``surfaces`` (one label per row; rows of one surface share
    where its peak is, read on their mean spectrum).
    Fitted: ``coef_`` (3,), ``intercept_``, ``scale_`` (robust residual SD, log units), ``feature_min_`` and
    ``feature_max_`` (the range of the rows the Huber fit kept, weight >= 0.5, used to clip and to flag),
    ``press_scatter_`` (the training presses' robust scatter about their surfaces, which widens the flag for a
    surface read from fewer presses than the trained ones, model/press_spread.py; None without ``surfaces``),
    ``freq_per_mm_``.

    Parameters
    ----------
    freq_per_mm : array-like, optional
        (K,) the spectra's frequencies in mm^-1; default K evenly spaced over 0.1-1.0.
    n_blocks : int
        Spectra side by side in a row (3 for a combined-force trial).
    pad_ridge_period_mm : float, optional
        A fingerprint pad's ridge period (mm): its frequency is no surface's peak.
    exclusion_per_mm : float
        How far either side of the pad's ridge frequency is left out (mm^-1).
    epsilon : float
        Huber's constant: residuals beyond ``epsilon`` robust SDs are down-weighted.

    Examples
    --------
    Spectra peaking at 1/period, from gratings of 2-5 mm, two presses each:

    >>> import numpy as np
    >>> import roughsense as rs
    >>> f = rs.frequency_grid()
    >>> periods = np.repeat([2.0, 3.0, 4.0, 5.0], 2)
    >>> X = np.exp(-((f - 1 / periods[:, None]) / 0.05) ** 2) + 0.01
    >>> y = (periods / 3) ** 0.9  # perceived roughness grows with the period
    >>> law = rs.PeakPowerLaw().fit(X, y)
    >>> law.predict(X[::2]).round(2)
    array([0.69, 1.  , 1.3 , 1.58])
    >>> unseen = np.exp(-((f - 1 / np.array([[2.5], [8.0]])) / 0.05) ** 2) + 0.01
    >>> law.predict(unseen).round(2)  # 8 mm lies beyond the law's domain: held at its edge
    array([0.85, 1.66])
    >>> law.applicability(unseen)
    ['', 'period 8.00 mm outside the trained 2.00-5.00 mm']
    """

    family: ClassVar[str] = NAME

    def __init__(self, freq_per_mm=None, n_blocks: int = 1, pad_ridge_period_mm: float | None = None,
                 exclusion_per_mm: float = RIDGE_EXCLUSION_PER_MM, epsilon: float = HUBER_EPSILON) -> None:
        self.freq_per_mm = freq_per_mm
        self.n_blocks = n_blocks
        self.pad_ridge_period_mm = pad_ridge_period_mm
        self.exclusion_per_mm = exclusion_per_mm
        self.epsilon = epsilon

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.positive_only = True  # amplitude spectra
        tags.target_tags.positive_only = True  # magnitude estimates
        tags.regressor_tags.poor_score = True  # a 3-parameter law scores poorly on arbitrary data, by design
        return tags

    def _grid(self, n_features: int) -> np.ndarray:
        return readout_grid(n_features, self.freq_per_mm, self.n_blocks, _DEFAULT_BAND_PER_MM)

    def _check_params(self) -> None:
        check_settings(pad_ridge_period_mm=self.pad_ridge_period_mm, exclusion_per_mm=self.exclusion_per_mm,
                       epsilon=self.epsilon)

    def features(self, X, surfaces=None) -> np.ndarray:
        """The peak readout of each row (log peak frequency, log peak amplitude, log second-harmonic ratio).

        Parameters
        ----------
        X : array-like
            (n_samples, n_blocks x K) spectra.
        surfaces : array-like, optional
            (n_samples,) labels: rows of one surface share where its peak is read.

        Returns
        -------
        numpy.ndarray
            (n_samples, 3) as :data:`FEATURE_NAMES` (the ratio NaN where it cannot be read).
        """
        check_is_fitted(self)
        X = validate_data(self, self._file_inputs(X), reset=False, ensure_min_samples=1)
        _check_positive(X)
        return self._features(X, surfaces)

    def _file_inputs(self, X):
        X = super()._file_inputs(X)
        if hasattr(self, "model_file_") and (not np.all(np.isfinite(X)) or np.any(X < 0)):
            raise PeakLawInputError("a spectrum holds a negative or non-finite amplitude; the peak law reads "
                                    "amplitudes")
        return X

    def _features(self, X: np.ndarray, surfaces=None) -> np.ndarray:
        return self._readout(X, surfaces).features

    def _reading(self) -> dict:
        return {"freq_per_mm": self.freq_per_mm_, "n_blocks": int(self.n_blocks),
                "pad_ridge_period_mm": self.pad_ridge_period_mm, "exclusion_per_mm": float(self.exclusion_per_mm)}

    def _readout(self, X: np.ndarray, surfaces=None) -> PeakReadout:
        return peak_readout(X, **self._reading(), surfaces=surfaces)

    def fit(self, X, y, surfaces=None):
        """Fit the law by Huber's M-estimator and record the range of the rows it kept.

        Parameters
        ----------
        X : array-like
            (n_samples, n_blocks x K) spectra (non-negative amplitudes).
        y : array-like
            (n_samples,) perceived roughness, positive (the law is fitted in logs).
        surfaces : array-like, optional
            (n_samples,) labels: rows of one surface share where its peak is read.

        Returns
        -------
        PeakPowerLaw
            This estimator, fitted.
        """
        self._check_params()
        X, y = validate_data(self, X, y, y_numeric=True, ensure_min_samples=2)
        _check_positive(X)
        self.freq_per_mm_ = self._grid(X.shape[1])
        fit = fit_readout(X, y, **self._reading(), epsilon=float(self.epsilon), surfaces=surfaces)
        self.intercept_, self.coef_, self.scale_ = fit.intercept, fit.coef, fit.scale
        self.feature_min_, self.feature_max_ = fit.feature_min, fit.feature_max
        self.clarity_limit_, self.press_scatter_ = fit.clarity_limit, fit.press_scatter
        return self

    def predict(self, X, surfaces=None) -> np.ndarray:
        """Perceived roughness by the law, each feature held to the law's domain.

        Parameters
        ----------
        X : array-like
            (n_samples, n_blocks x K) spectra.
        surfaces : array-like, optional
            (n_samples,) labels: rows of one surface share where its peak is read.

        Returns
        -------
        numpy.ndarray
            (n_samples,) predictions (positive).
        """
        return predict_law(self.features(X, surfaces), self.intercept_, self.coef_,
                           *domain_margins(grid_step(self.freq_per_mm_), self.feature_min_, self.feature_max_))

    def applicability(self, X, surfaces=None) -> list[str]:
        """Per row, what lies outside what the law was fitted on, in a user's words ('' where nothing does).

        Parameters
        ----------
        X, surfaces
            As :meth:`predict`.

        Returns
        -------
        list of str
            One reason per row: period or peak strength beyond the trained range, no clear peak, presses that
            disagree; '' where the row is inside.
        """
        check_is_fitted(self)
        X = validate_data(self, self._file_inputs(X), reset=False, ensure_min_samples=1)
        _check_positive(X)
        return domain_reasons(self._readout(X, surfaces), self.feature_min_, self.feature_max_, self.clarity_limit_,
                              grid_step(self.freq_per_mm_), self.press_scatter_)
