"""Why a trial lies outside what its model was trained on, the ``outside`` column's words: the spectrum's band
(``sensor/band.py``), the family's own domain, and the images' scale against known structure in them
(``model/scale_check.py``).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .modelfile import FittedModel


def trial_reasons(loaded: FittedModel, spectrum, lines: list, X: np.ndarray, surfaces, reference, *,
                  ridge_period_mm: float | None, contact: dict | None = None):
    """Each kept trial's ``outside`` words and the images' scale check: the domain's reasons (:func:`domain_reasons`),
    then ``scale: ...`` on every trial when the images' scale is off (:func:`images_scale_check`)."""
    reasons = domain_reasons(loaded, spectrum, lines, X, surfaces, ridge_period_mm=ridge_period_mm, contact=contact)
    scale = images_scale_check(spectrum, lines, len(loaded.conditions), ridge_period_mm, reference)
    if scale.off:
        reasons = [f"{r}; {scale.reason()}" if r else scale.reason() for r in reasons]
    return reasons, scale


def domain_reasons(loaded: FittedModel, spectrum, lines: list, X: np.ndarray, surfaces=None, *,
                   ridge_period_mm: float | None, contact: dict | None = None) -> list[str]:
    """Why each trial lies outside the model's domain ('' where it lies inside): the band's reason first, then the
    family's own, named by the band when the structure outside it is at least as strong as the band's own peak.
    Shared by predict's trials and live mode's frames, so a frame says what its image would say. ``contact``: the
    keyword a family that reads the contact takes (``scoring.contact_inputs``)."""
    from ..sensor.band import NAMING_DOMINANCE

    k = len(loaded.conditions)
    band = trial_band_reasons(spectrum, lines, k, ridge_period_mm, surfaces)
    named = trial_band_reasons(spectrum, lines, k, ridge_period_mm, surfaces, dominance=NAMING_DOMINANCE)
    family = loaded.applicability(X, surfaces=surfaces, **(contact or {}))
    return [b or (n if f else "") or f for b, n, f in zip(band, named, family)]


def trial_band_reasons(spectrum, lines: list, k: int, ridge_period_mm: float | None, surfaces=None, *,
                       dominance: float | None = None) -> list[str]:
    """Per trial (of ``k`` images), why its structure lies outside the spectrum's band ('' where it lies inside): the
    one band test (``sensor/band.py``) every family's predictions pass, a trial read from the medians of its
    images."""
    from ..sensor.band import DOMINANCE, band_reading, band_reasons, median_reading

    freq = spectrum.freq_per_mm_
    f_min, f_max = float(freq[0]), float(freq[-1])
    readings = [band_reading(line, float(spectrum.px_per_mm), f_min, f_max, ridge_period_mm=ridge_period_mm)
                for line in lines]
    trials = [median_reading(readings[i:i + k]) for i in range(0, len(readings), k)]
    return band_reasons(trials, f_min, f_max, surfaces, dominance=DOMINANCE if dominance is None else dominance)


def images_scale_check(spectrum, lines: list, k: int, ridge: float | None, reference=None):
    """The images' scale (trials of ``k`` images) against the pad's ridges (every image) and the stated periods of
    ``reference``'s trials, at the scale the spectrum read them (``model/scale_check.py``)."""
    from .scale_check import check_study_lines

    groups = []
    mounts = [i // k for i in range(len(lines))]  # a trial's images are one mount of the surface
    if ridge is not None:
        groups.append((f"the pad's {ridge:g} mm ridges", ridge, lines, mounts))
    if reference is not None:
        what, periods = reference
        for period_mm in dict.fromkeys(p for p in periods if np.isfinite(p)):
            chosen = [i for i in range(len(lines)) if periods[i // k] == period_mm]
            groups.append((what, float(period_mm), [lines[i] for i in chosen], [mounts[i] for i in chosen]))
    return check_study_lines(groups, float(spectrum.px_per_mm))
