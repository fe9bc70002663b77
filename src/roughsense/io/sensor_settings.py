"""What study.toml's ``[sensor]`` table means: the camera scale, the region of interest and the pixel limit.

Part of the folder contract (not of ``sensor/``), so the rig can check its frames without the analysis.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .. import defaults
from .._util.checks import POSITIVE, check, is_number
from ..errors import ConfigError
from .images import MAX_PIXELS_LIMIT
from .numbers import NumberError, parse_number

#: A study that does not say takes the paper's camera scale (349 px/cm, section 2.1) and roi="center":
#: ``defaults.CENTER_CROP_PX`` (width, height) centred on the frame, the paper's crop of its 1920 x 1080 camera.
#: Part of the study contract, so the rig can check frames without the sensor code.
Roi = str | tuple[int, int, int, int]


@dataclass(frozen=True)
class SensorSettings:
    """How images of this study are turned into lines: camera scale and where the contact band is."""

    px_per_mm: float = defaults.PX_PER_MM
    roi: Roi = defaults.ROI
    max_pixels: int = defaults.MAX_PIXELS

    def __post_init__(self) -> None:
        check(self.px_per_mm, POSITIVE, name="px_per_mm", must="a positive number")
        try:  # then its stated range (numbers.BOUNDS): a scale of 1e-300 px/mm is no camera
            parse_number(self.px_per_mm, quantity="px_per_mm")
        except NumberError as exc:
            raise ConfigError(f"px_per_mm {exc.message}") from None
        object.__setattr__(self, "roi", parse_roi(self.roi))
        object.__setattr__(self, "max_pixels", check_max_pixels(self.max_pixels))


def check_max_pixels(value: object, *, option: str = "max_pixels") -> int:
    """A pixel limit: a whole number of pixels from 1 to :data:`~.images.MAX_PIXELS_LIMIT` (default
    :data:`roughsense.defaults.MAX_PIXELS`)."""
    if not (is_number(value) and math.isfinite(value) and value == int(value) and 1 <= value <= MAX_PIXELS_LIMIT):
        raise ConfigError(f"{option} must be a whole number of pixels from 1 to {MAX_PIXELS_LIMIT} (OpenCV decodes "
                          f"no larger image), got {value!r}")
    return int(value)


def parse_roi(value: object) -> Roi:
    """Accept "center", "auto", "X,Y,W,H" or a 4-sequence of non-negative ints (W, H positive)."""
    if isinstance(value, str):
        text = value.strip().lower()
        if text in ("center", "centre"):
            return "center"
        if text == "auto":
            return "auto"
        parts = [p.strip() for p in text.split(",")]
    elif isinstance(value, Sequence):
        parts = list(value)
        if any(isinstance(p, (bool, np.bool_)) for p in parts):
            raise ConfigError(f"ROI values must be whole pixels, not true/false, got {_roi_text(value)}")
    else:
        raise ConfigError(f"ROI must be 'center', 'auto' or X,Y,W,H, got {_roi_text(value)}")
    if len(parts) != 4:
        raise ConfigError(f"ROI must be 'center', 'auto' or X,Y,W,H, got {_roi_text(value)}")
    try:  # the one number parser: '1_0' and non-ASCII digits are not pixels here either
        numbers = [float(parse_number(p)) for p in parts]
    except NumberError:
        raise ConfigError(f"ROI must be 'center', 'auto' or X,Y,W,H with whole numbers, got {_roi_text(value)}") from None
    if not all(math.isfinite(n) for n in numbers):
        raise ConfigError(f"ROI values must be finite whole pixels, got {_roi_text(value)}")
    if any(n != int(n) for n in numbers):
        raise ConfigError(f"ROI values must be whole pixels, got {_roi_text(value)}")
    x, y, w, h = (int(n) for n in numbers)
    if x < 0 or y < 0 or w <= 0 or h <= 0:
        raise ConfigError(f"ROI needs X,Y >= 0 and W,H > 0, got {_roi_text(value)}")
    return (x, y, w, h)


def _roi_text(value: object) -> str:
    """The ROI as the user gave it (a sequence of numpy numbers must not print as np.int64(...))."""
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, Sequence):
        return ",".join(str(v) for v in value)
    return repr(value)


def roi_misfit(roi: Roi, width_px: int, height_px: int) -> str | None:
    """Why a ``width_px`` x ``height_px`` frame cannot yield this ROI's crop, or None if it can.

    The one size rule: :func:`roughsense.sensor.line.resolve_roi` refuses a crop with it, and a source
    checks its frames with it before recording a session the analysis would refuse.
    """
    roi = parse_roi(roi)
    if roi == "center":
        crop_w, crop_h = defaults.CENTER_CROP_PX
        if width_px < crop_w or height_px < crop_h:
            return f"smaller than the {crop_w}x{crop_h} px centre crop of roi 'center'"
        return None
    if roi == "auto":
        if width_px < 2 or height_px < 1:
            return "too small to find the contact band (roi 'auto')"
        return None
    x, y, w, h = roi
    if x + w > width_px or y + h > height_px:
        return f"ROI {x},{y},{w},{h} reaches outside it"
    return None
