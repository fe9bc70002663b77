"""How a model file reads an image: its spectrum rebuilt from the file (and checked against it), read where and at
the scale a :class:`SensorOverride` says, and its pad's ridge period (what the readings set aside).

Every path from a model to pixels starts here: predict's batches and live frames (``model/scoring.py``) and the
gate's presses (``model/press_gate.py``, ``capture --model``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..errors import ConfigError
from .modelfile import FittedModel, check_features, feature_definition_for

if TYPE_CHECKING:
    from ..io.sensor_settings import Roi


@dataclass(frozen=True)
class SensorOverride:
    """Where the line is read (``roi``) and the images' scale (``px_per_mm``), given at scoring time in place of
    the model's.

    Both only change how an image becomes a line in mm: the spectrum itself (band and grid in mm^-1, window, rows,
    normalisation) stays the model's, so the features mean what they meant in training. A scale is refused where
    the model's band cannot be measured (f_max at or above Nyquist here; a line shorter than 1/f_min, per image).
    """

    roi: Roi | None = None
    px_per_mm: float | None = None

    @classmethod
    def parse(cls, roi: str | None = None, px_per_mm: float | None = None) -> SensorOverride | None:
        """From ``--roi`` and ``--px-per-mm`` as given (None when neither was): each refused in one line naming it."""
        from .._util.checks import POSITIVE, check
        from ..io.sensor_settings import parse_roi

        if roi is None and px_per_mm is None:
            return None
        if roi is not None:
            try:
                roi = parse_roi(roi)
            except ConfigError as exc:
                raise ConfigError(f"--roi: {exc.message}") from None
        if px_per_mm is not None:
            px_per_mm = check(px_per_mm, POSITIVE, name="--px-per-mm", must="a positive number (px/mm)")
        return cls(roi, px_per_mm)

    def fields(self) -> dict:
        """The feature-definition fields this override replaces (JSON values, as a model file stores them)."""
        given = {}
        if self.roi is not None:
            given["roi"] = self.roi if isinstance(self.roi, str) else list(self.roi)
        if self.px_per_mm is not None:
            given["px_per_mm"] = float(self.px_per_mm)
        return given


def model_spectrum(loaded: FittedModel, *, n_jobs: int = 1, override: SensorOverride | None = None):
    """The SpatialSpectrum the model was trained with, rebuilt from its file (and checked against it).

    With ``override``, the checked definition is then read where and at the scale the override says.
    """
    from ..sensor.spectrum import SpatialSpectrum

    stored = loaded.model_file_.features["spectrum"]
    spectrum = SpatialSpectrum.from_definition(stored, n_jobs=n_jobs).fit()
    check_features(loaded, feature_definition_for(spectrum, loaded.conditions))
    if override is None:
        return spectrum
    f_max = float(spectrum.freq_per_mm_[-1])
    if override.px_per_mm is not None and f_max >= override.px_per_mm / 2:
        raise ConfigError(f"--px-per-mm {override.px_per_mm:g}: the model's band reaches {f_max:g} mm^-1, not below "
                          f"the Nyquist frequency {override.px_per_mm / 2:g} mm^-1 of images at that scale",
                          path=loaded.path)
    return SpatialSpectrum.from_definition({**stored, **override.fields()}, n_jobs=n_jobs).fit()


def model_ridge_period_mm(loaded: FittedModel) -> float | None:
    """The ridge period (mm) of the model's pad, or None for a smooth pad (or a file that does not say)."""
    training = loaded.training if isinstance(loaded.training, dict) else {}
    stated = training.get("pad_ridge_period_mm", getattr(loaded, "pad_ridge_period_mm", None))
    domain = getattr(loaded, "domain_", None)
    if stated is None and domain is not None and domain.peak is not None:
        stated = domain.peak.pad_ridge_period_mm
    return float(stated) if isinstance(stated, (int, float)) and stated > 0 else None
