"""The peak law's prediction held to its domain (model/readout_domain.py), and its refusal of negative spectra."""
from __future__ import annotations

import numpy as np

from ..peak_search import PeakLawInputError, held_features


def predict_law(features: np.ndarray, intercept: float, coef: np.ndarray, low: np.ndarray, high: np.ndarray
                ) -> np.ndarray:
    """exp(intercept + clip(features) . coef): the law's prediction, features held to [low, high] (the law's
    domain, :func:`~roughsense.model.readout_domain.domain_margins`)."""
    return np.exp(intercept + held_features(features, low, high) @ np.asarray(coef, dtype=np.float64))


def _check_positive(X: np.ndarray) -> None:
    if np.any(X < 0):
        raise PeakLawInputError("Negative values in data passed to PeakPowerLaw: spectra are amplitudes")
