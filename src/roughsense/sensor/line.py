"""One contact image -> its gray line -> its spectrum: the crop (centre, auto band or explicit), the line, and the
validated plan that :func:`spatial_spectrum` and :class:`~.spectrum.SpatialSpectrum`'s threads share.

Only the rows that are used are converted to gray, and a PNG is decoded only down to the last row the line uses.
"""
from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass

import numpy as np

from .. import defaults
from .._util.checks import check_params
from ..defaults import CENTER_CROP_PX, MAX_PIXELS, PX_PER_MM, ROI
from ..errors import ConfigError, InputError
from ..io.images import as_image, check_pixels, decode, decode_png_top_rows, png_size, read_bytes, to_gray
from ..io.sensor_settings import Roi, check_max_pixels, parse_roi, roi_misfit
from .contact_geometry import CONTACT_MEASURES, band_profile, contact_measures
from .descriptors import press_descriptors, press_strips
from .grid import SETTINGS, _normalise, frequency_grid, line_amplitude

#: ``auto`` looks at every 2nd row and every 4th column: the band is ~150 rows tall and its texture spans
#: many pixels, so 1/8 of the frame locates it to a row while costing a few % of decoding.
AUTO_STRIDE_ROWS, AUTO_STRIDE_COLS = 2, 4


def _auto_band(pixels: np.ndarray, height_px: int) -> int:
    """Top row of the ``height_px``-row window with the most horizontal texture.

    Texture of a row = mean squared difference of gray levels AUTO_STRIDE_COLS px apart along it;
    the best window maximises the sum over its rows (a box filter), the first one on ties. Only finite
    differences count: one NaN pixel anywhere would otherwise make its row's texture NaN, and ``argmax`` would
    pick the first window holding it (a crop that does hold one is refused later, by ``extract_line``).
    """
    total_rows = pixels.shape[0]
    cols = AUTO_STRIDE_COLS if pixels.shape[1] >= 8 * AUTO_STRIDE_COLS else 1
    gray = to_gray(pixels[::AUTO_STRIDE_ROWS, ::cols])
    with np.errstate(invalid="ignore", over="ignore"):  # inf - inf is a NaN here, dropped just below
        steps = np.diff(gray, axis=1)
    finite = np.isfinite(steps)
    counts = finite.sum(axis=1)
    energy = np.divide(np.square(np.where(finite, steps, 0.0)).sum(axis=1), counts,
                       out=np.zeros(len(counts)), where=counts > 0)
    energy = np.repeat(energy, AUTO_STRIDE_ROWS)[:total_rows]
    window_sum = np.convolve(energy, np.ones(height_px), mode="valid")
    return int(np.argmax(window_sum))


def resolve_roi(roi: Roi, pixels: np.ndarray, *, name=None, where: str = "") -> tuple[int, int, int, int]:
    """The crop (x, y, w, h) in pixels for this image; a crop that does not fit is refused (``roi_misfit``'s rule)."""
    height, width = pixels.shape[:2]
    roi = parse_roi(roi)
    misfit = roi_misfit(roi, width, height)
    if misfit is not None:
        hint = "; pass --roi X,Y,W,H or --roi auto" if roi == "center" else ""
        raise InputError(f"{where}image is {width}x{height} px, {misfit}{hint}", path=name)
    if roi == "center":
        crop_w, crop_h = CENTER_CROP_PX
        return ((width - crop_w) // 2, (height - crop_h) // 2, crop_w, crop_h)
    if roi == "auto":
        crop_w, crop_h = min(CENTER_CROP_PX[0], width), min(CENTER_CROP_PX[1], height)
        return ((width - crop_w) // 2, _auto_band(pixels, crop_h), crop_w, crop_h)
    return roi


def extract_line(pixels: np.ndarray, box: tuple[int, int, int, int], rows: int, *, name=None, where: str = "") -> np.ndarray:
    """Gray level along the middle row of the crop, or the mean of its ``rows`` central rows.

    The central rows start at (h - rows) // 2, so one row of a 150-row crop is row 74 (MATLAB's
    ``round(end/2)``). Only those rows are converted to gray: cropping comes before the colour work.
    """
    x, y, w, h = box
    if rows > h:
        raise InputError(f"{where}rows {rows} is more than the crop height ({h} px)", path=name)
    top = y + (h - rows) // 2
    gray = to_gray(pixels[top : top + rows, x : x + w])
    line = gray.mean(axis=0) if rows > 1 else gray[0]
    if not np.all(np.isfinite(line)):
        raise InputError(f"{where}image contains NaN or infinite values in the crop", path=name)
    return line


def scale_misfit(px_per_mm: float, roi: Roi, *, f_min_per_mm: float = defaults.F_MIN_PER_MM,
                 f_max_per_mm: float = defaults.F_MAX_PER_MM) -> str | None:
    """Why a camera scale cannot measure the band with this crop (None if it can): f_max at or above the Nyquist
    frequency, or a line (the crop's width; at most the centre crop's for 'auto') shorter than 1/f_min. What
    ``roughsense check`` calls an implausible scale; ``_Plan`` refuses the first and every image the second."""
    if not px_per_mm / 2 > f_max_per_mm:
        return (f"px_per_mm {px_per_mm:g} cannot resolve the band: its Nyquist frequency {px_per_mm / 2:g} mm^-1 is not "
                f"above f_max {f_max_per_mm:g} mm^-1 (it must be above {2 * f_max_per_mm:g} px/mm)")
    width_px = CENTER_CROP_PX[0] if isinstance(roi, str) else roi[2]
    if width_px / px_per_mm < 1 / f_min_per_mm:
        return (f"px_per_mm {px_per_mm:g} makes the line {width_px / px_per_mm:.3g} mm long ({width_px} px), shorter "
                f"than 1/f_min = {1 / f_min_per_mm:g} mm: the band's coarse end cannot be measured")
    return None


@dataclass(frozen=True)
class _Plan:
    """Validated settings, shared read-only by the worker threads."""

    px_per_mm: float
    roi: Roi
    rows: int
    freq_per_mm: np.ndarray
    window: str
    max_pixels: int = MAX_PIXELS
    #: Set on a per-image copy by :meth:`reading` and :meth:`contact`: where the line's read leaves the pixels it
    #: decoded and the crop (``"decoded"``), so that the descriptors and the contact read them at no second decoding.
    describe: dict | None = None

    @classmethod
    def build(cls, px_per_mm, roi, rows, f_min_per_mm, f_max_per_mm, n_freqs, window,
              max_pixels=MAX_PIXELS) -> _Plan:
        px = check_params({"px_per_mm": px_per_mm}, SETTINGS)["px_per_mm"]
        max_pixels = check_max_pixels(max_pixels)
        check_params({"rows": rows, "window": window}, SETTINGS)
        roi = parse_roi(roi)
        crop_h = CENTER_CROP_PX[1] if roi == "center" else roi[3] if not isinstance(roi, str) else None
        if crop_h is not None and rows > crop_h:
            raise ConfigError(f"rows {rows} is more than the crop height ({crop_h} px)")
        freqs = frequency_grid(f_min_per_mm, f_max_per_mm, n_freqs)
        if freqs[-1] >= px / 2:
            raise ConfigError(  # names the key: callers add where it came from (study.toml or an option)
                f"px_per_mm {px:g} is too coarse: its Nyquist frequency {px / 2:g} mm^-1 is not above the band's "
                f"f_max {freqs[-1]:g} mm^-1 (it must be above {2 * freqs[-1]:g} px/mm)"
            )
        return cls(px, roi, int(rows), freqs, window, max_pixels)

    def spectrum(self, image, index: int | None = None) -> np.ndarray:
        return self.spectrum_and_line(image, index)[0]

    def spectrum_and_line(self, image, index: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The normalised spectrum and the gray line it was taken from (the band and scale checks read the line)."""
        is_file = isinstance(image, (str, os.PathLike))
        name = image if is_file else None
        where = "" if is_file or index is None else f"image {index} of the batch: "
        pixels = box = None
        if is_file:
            data = read_bytes(image, max_pixels=self.max_pixels)
            check_pixels(data, self.max_pixels, image)  # before any decoding: a small file may claim gigapixels
            pixels, box = self._top_rows_only(data, name)
            if pixels is None:
                pixels = decode(data, image, max_pixels=self.max_pixels)
        else:
            pixels = as_image(image, name=where.rstrip(": ") or None)
        if box is None:
            box = resolve_roi(self.roi, pixels, name=name, where=where)
        line_mm = box[2] / self.px_per_mm
        min_mm = 1.0 / self.freq_per_mm[0]
        if line_mm < min_mm * (1 - 1e-12):
            raise InputError(
                f"{where}the line is {line_mm:.3g} mm long ({box[2]} px at {self.px_per_mm:g} px/mm), shorter than "
                f"1/f_min = {min_mm:.3g} mm, so it cannot resolve the band",
                path=name,
            )
        line = extract_line(pixels, box, self.rows, name=name, where=where)
        amplitude = line_amplitude(line, px_per_mm=self.px_per_mm, freq_per_mm=self.freq_per_mm, window=self.window)
        if self.describe is not None:  # predict's gate and the contact: the pixels decoded for the line, read again
            self.describe["decoded"] = (pixels, box)
        return _normalise(amplitude, self.freq_per_mm, name, where), line

    def reading(self, image, index: int | None = None, ridge_period_mm: float | None = None):
        """(spectrum, line, descriptors) of one press, or the :class:`InputError` that refused it: one unreadable
        image in a batch is that image's reason, never the batch's end (``sensor/descriptors.py``)."""
        plan = dataclasses.replace(self, describe={})
        try:
            spectrum, line = plan.spectrum_and_line(image, index)
        except InputError as exc:
            return exc
        pixels, box = plan.describe["decoded"]
        described = press_descriptors(press_strips(pixels, box, self.rows), line, self.px_per_mm,
                                      float(self.freq_per_mm[0]), float(self.freq_per_mm[-1]), ridge_period_mm)
        described.update(zip(CONTACT_MEASURES, self._contact(pixels, box, ridge_period_mm).tolist()))
        return spectrum, line, described

    def contact(self, image, index: int | None = None, ridge_period_mm: float | None = None):
        """(spectrum, contact measures (len(CONTACT_MEASURES),)) of one image; an unreadable image raises, as
        :meth:`spectrum` does. The measures read the band of rows the line's decoding already holds."""
        plan = dataclasses.replace(self, describe={})
        spectrum, _ = plan.spectrum_and_line(image, index)
        pixels, box = plan.describe["decoded"]
        return spectrum, self._contact(pixels, box, ridge_period_mm)

    def _contact(self, pixels, box, ridge_period_mm: float | None) -> np.ndarray:
        """The contact measures (``sensor/contact_geometry.py``) of the band from the crop's top down to the line."""
        return contact_measures(band_profile(pixels, box, self.rows), self.px_per_mm,
                                ridge_period_mm=ridge_period_mm)

    def _top_rows_only(self, data: np.ndarray, name) -> tuple[np.ndarray | None, tuple | None]:
        """Decode a PNG only down to the last row the line uses (same result, about half the decoding).

        Not for ``roi="auto"``, which must see the whole frame to find the band.
        """
        if self.roi == "auto":
            return None, None
        size = png_size(data)
        if size is None:
            return None, None
        box = resolve_roi(self.roi, np.empty((*size, 0), dtype=np.uint8), name=name)
        x, y, w, h = box
        if self.rows > h:
            return None, None
        stop_row = y + (h - self.rows) // 2 + self.rows
        pixels = decode_png_top_rows(data, stop_row)
        return (pixels, box) if pixels is not None else (None, None)


def spatial_spectrum(
    image,
    *,
    px_per_mm: float = PX_PER_MM,
    roi: Roi = ROI,
    rows: int = defaults.ROWS,
    f_min_per_mm: float = defaults.F_MIN_PER_MM,
    f_max_per_mm: float = defaults.F_MAX_PER_MM,
    n_freqs: int = defaults.N_FREQS,
    window: str = defaults.WINDOW,
) -> np.ndarray:
    """Normalised amplitude spectrum (n_freqs,) of one contact image (path or array) on the frequency grid.

    The function form of :class:`SpatialSpectrum` for a single image (docs/sensor.md gives every step).

    Parameters
    ----------
    image : str, os.PathLike or numpy.ndarray
        An image file, or its pixels (gray or RGB; uint8, uint16 or float in 0-1).
    px_per_mm : float
        The camera's scale, pixels per mm (the paper's rig: 34.9).
    roi : {"center", "auto"} or tuple of int
        Where the contact band is: the 1900 x 150 px centre crop, the band with the strongest horizontal
        texture, or an explicit crop (x, y, w, h) in pixels.
    rows : int
        How many central rows of the crop are averaged into the line.
    f_min_per_mm, f_max_per_mm, n_freqs
        The frequency grid (:func:`frequency_grid`).
    window : str
        The window applied to the line ("hann", the default, or "none").

    Returns
    -------
    numpy.ndarray
        (n_freqs,) amplitudes, normalised to unit area over mm^-1.

    Examples
    --------
    A synthetic band whose brightness repeats every 2 mm peaks near 0.5 mm^-1:

    >>> import numpy as np
    >>> import roughsense as rs
    >>> x_mm = np.arange(700) / 34.9
    >>> image = np.tile(0.5 + 0.4 * np.sin(2 * np.pi * x_mm / 2.0), (20, 1))
    >>> spectrum = rs.spatial_spectrum(image, px_per_mm=34.9, roi=(0, 0, 700, 20))
    >>> spectrum.shape
    (45,)
    >>> round(float(rs.frequency_grid()[spectrum.argmax()]), 2)
    0.51
    """
    plan = _Plan.build(px_per_mm, roi, rows, f_min_per_mm, f_max_per_mm, n_freqs, window)
    return plan.spectrum(image)
