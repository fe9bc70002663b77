"""Contact image -> spatial spectrum: the predictors X of the paper (section 3.2).

crop the contact band -> gray (MATLAB weights) -> middle row (or mean of the N central rows) ->
remove the line mean -> Hann window -> amplitude of the DFT evaluated exactly at an evenly spaced grid
of spatial frequencies (mm^-1) -> normalise to unit trapezoid area over mm^-1.

Only the rows that are used are converted to gray, so the work after decoding is a few thousand
multiply-adds per image; decoding is the floor, and :meth:`SpatialSpectrum.iter_transform` overlaps it
over threads while holding only a handful of images in memory. The choices the paper leaves open are
explained in docs/sensor.md.
"""
from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin

from .._util.checks import POSITIVE, POSITIVE_INT, AnyOf, Described, Integer, Options, check, check_params
from .._util.workers import thread_map, usable_cores
from ..errors import ConfigError, InputError
from ..io.images import (
    DEFAULT_MAX_PIXELS,
    GRAY_WEIGHTS_RGB,
    as_image,
    check_pixels,
    decode,
    decode_png_top_rows,
    png_size,
    read_bytes,
    to_gray,
)
from ..io.sensor_settings import (
    CENTER_CROP_PX,
    DEFAULT_PX_PER_MM,
    DEFAULT_ROI,
    Roi,
    check_max_pixels,
    parse_roi,
    roi_misfit,
)
from .settings import MAX_N_FREQS, SPECTRUM_DEFAULTS, WINDOWS

__all__ = [
    "SpatialSpectrum",
    "combine_forces",
    "frequency_grid",
    "line_amplitude",
    "resolve_roi",
    "spatial_spectrum",
]

FEATURE_VERSION = 1
_FREQUENCY = Described(POSITIVE, "a positive number (mm^-1)")
#: The settings and what each must be (scikit-learn's ``_parameter_constraints``, in roughsense's vocabulary); the
#: region of interest and the pixel limit are the study folder's (``io.sensor_settings``).
SETTINGS = {
    "px_per_mm": Described(POSITIVE, "a positive number"),
    "rows": Integer(1),
    "window": Described(Options(WINDOWS), f"one of {', '.join(WINDOWS)}"),
    "f_min_per_mm": _FREQUENCY,
    "f_max_per_mm": _FREQUENCY,
    "n_freqs": Integer(2, MAX_N_FREQS),
}
N_JOBS = Described(AnyOf(POSITIVE_INT, Integer(-1, -1)), "a positive whole number or -1")


def frequency_grid(
    f_min_per_mm: float = SPECTRUM_DEFAULTS.f_min_per_mm,
    f_max_per_mm: float = SPECTRUM_DEFAULTS.f_max_per_mm,
    n_freqs: int = SPECTRUM_DEFAULTS.n_freqs,
) -> np.ndarray:
    """Evenly spaced spatial frequencies in mm^-1, both ends included (the paper: 45 over 0.1-1.0).

    Parameters
    ----------
    f_min_per_mm, f_max_per_mm : float
        The band's ends (mm^-1), 0 < f_min < f_max.
    n_freqs : int
        How many frequencies (at least 2).

    Returns
    -------
    numpy.ndarray
        (n_freqs,) frequencies in mm^-1, the grid every spectrum is evaluated on.

    Examples
    --------
    >>> import roughsense as rs
    >>> grid = rs.frequency_grid()
    >>> grid.size, float(grid[0]), float(grid[-1])
    (45, 0.1, 1.0)
    >>> rs.frequency_grid(0.2, 1.0, 5)
    array([0.2, 0.4, 0.6, 0.8, 1. ])
    """
    _check_band(f_min_per_mm, f_max_per_mm, n_freqs)
    return np.linspace(float(f_min_per_mm), float(f_max_per_mm), int(n_freqs))


def grid_step(freq_per_mm) -> float:
    """The grid's spacing (mm^-1); 0 for a one-bin grid. The one home of the formula: peak frequencies are read
    to within a bin of it, and the law's domain widens by it."""
    return float(freq_per_mm[1] - freq_per_mm[0]) if len(freq_per_mm) > 1 else 0.0


def _check_band(f_min_per_mm, f_max_per_mm, n_freqs) -> None:
    band = check_params({"f_min_per_mm": f_min_per_mm, "f_max_per_mm": f_max_per_mm}, SETTINGS)
    if not band["f_min_per_mm"] < band["f_max_per_mm"]:
        raise ConfigError(f"band must satisfy 0 < f_min < f_max (mm^-1), got {f_min_per_mm!r}, {f_max_per_mm!r}")
    check_params({"n_freqs": n_freqs}, SETTINGS)


# --------------------------------------------------------------------------- the spectrum of one line


@lru_cache(maxsize=16)
def _dft_basis(width_px: int, px_per_mm: float, freqs: tuple[float, ...], window: str) -> np.ndarray:
    """(2K, W) real matrix: windowed cos and sin rows at the K grid frequencies, scaled to sine amplitude.

    Evaluating the DFT directly at the grid frequencies is the limit of infinite zero-padding: it needs
    no interpolation between FFT bins, and costs K*W multiply-adds (45 x 1900 for the paper).
    """
    x_mm = (np.arange(width_px) - (width_px - 1) / 2.0) / px_per_mm  # centred: phases stay small
    taper = np.hanning(width_px) if window == "hann" else np.ones(width_px)
    gain = 2.0 / taper.sum()  # a sinusoid of amplitude A reads A at its own frequency
    phase = 2.0 * np.pi * np.outer(np.asarray(freqs), x_mm)
    basis = np.vstack([np.cos(phase) * taper, np.sin(phase) * taper]) * gain
    basis.setflags(write=False)
    return basis


def line_amplitude(line, *, px_per_mm: float, freq_per_mm, window: str = SPECTRUM_DEFAULTS.window) -> np.ndarray:
    """Amplitude spectrum of one gray-level line at the given frequencies, before normalisation.

    The mean is removed first, so brightness offsets and the DC leakage into the band vanish.
    """
    line = np.asarray(line, dtype=np.float64)
    freqs = tuple(float(f) for f in np.asarray(freq_per_mm, dtype=np.float64))
    basis = _dft_basis(line.shape[-1], float(px_per_mm), freqs, window)
    centred = line - line.mean(axis=-1, keepdims=True)
    parts = basis @ centred.T if centred.ndim > 1 else basis @ centred
    k = len(freqs)
    return np.hypot(parts[:k], parts[k:]).T


def _normalise(amplitude: np.ndarray, freq_per_mm: np.ndarray, name: str | None, where: str) -> np.ndarray:
    area = np.trapezoid(amplitude, freq_per_mm)
    if not (np.isfinite(area) and area > 0):
        raise InputError(f"{where}no texture along the line (flat gray level); the spectrum cannot be normalised", path=name)
    return amplitude / area


# --------------------------------------------------------------------------- crop and line


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


def scale_misfit(px_per_mm: float, roi: Roi, *, f_min_per_mm: float = SPECTRUM_DEFAULTS.f_min_per_mm,
                 f_max_per_mm: float = SPECTRUM_DEFAULTS.f_max_per_mm) -> str | None:
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
    max_pixels: int = DEFAULT_MAX_PIXELS

    @classmethod
    def build(cls, px_per_mm, roi, rows, f_min_per_mm, f_max_per_mm, n_freqs, window,
              max_pixels=DEFAULT_MAX_PIXELS) -> _Plan:
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
        return _normalise(amplitude, self.freq_per_mm, name, where), line

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
    px_per_mm: float = DEFAULT_PX_PER_MM,
    roi: Roi = DEFAULT_ROI,
    rows: int = SPECTRUM_DEFAULTS.rows,
    f_min_per_mm: float = SPECTRUM_DEFAULTS.f_min_per_mm,
    f_max_per_mm: float = SPECTRUM_DEFAULTS.f_max_per_mm,
    n_freqs: int = SPECTRUM_DEFAULTS.n_freqs,
    window: str = SPECTRUM_DEFAULTS.window,
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


def combine_forces(spectra_by_force: Sequence[np.ndarray]) -> np.ndarray:
    """Concatenate the spectra of one trial at each force (1 N, 2 N, 3 N): (n, 3 * n_freqs), as in the paper."""
    blocks = [np.atleast_2d(np.asarray(s, dtype=np.float64)) for s in spectra_by_force]
    if not blocks:
        raise InputError("combine_forces needs at least one block of spectra")
    n_rows = {b.shape[0] for b in blocks}
    if len(n_rows) != 1 or any(b.ndim != 2 for b in blocks):
        raise InputError(
            f"combine_forces needs the same number of trials at every force, got shapes {[b.shape for b in blocks]}"
        )
    return np.hstack(blocks)


# --------------------------------------------------------------------------- the scikit-learn transformer


class SpatialSpectrum(TransformerMixin, BaseEstimator):
    """scikit-learn transformer: a list of contact images (paths or arrays) -> (n, n_freqs) spectra.

    Stateless: ``fit`` only validates the settings and records the grid in ``freq_per_mm_``, so it can
    sit in front of a regressor in a Pipeline and be cross-validated like any other step.
    ``n_jobs`` threads overlap decoding (OpenCV releases the GIL); ``-1`` uses every core.

    Parameters
    ----------
    px_per_mm, roi, rows, f_min_per_mm, f_max_per_mm, n_freqs, window
        As :func:`spatial_spectrum`.
    n_jobs : int
        Threads decoding images (``-1``: every core).
    max_pixels : int
        The largest image decoded, in pixels (a guard against decompression bombs).

    Examples
    --------
    >>> import numpy as np
    >>> import roughsense as rs
    >>> x_mm = np.arange(700) / 34.9
    >>> images = [np.tile(0.5 + 0.4 * np.sin(2 * np.pi * x_mm / period), (20, 1)) for period in (2.0, 4.0)]
    >>> spectra = rs.SpatialSpectrum(roi=(0, 0, 700, 20)).fit_transform(images)
    >>> spectra.shape
    (2, 45)
    >>> rs.SpatialSpectrum().get_feature_names_out()[:3]
    array(['0.1', '0.12045454545454545', '0.14090909090909093'], dtype=object)
    """

    def __init__(
        self,
        px_per_mm: float = DEFAULT_PX_PER_MM,
        roi: Roi = DEFAULT_ROI,
        rows: int = SPECTRUM_DEFAULTS.rows,
        f_min_per_mm: float = SPECTRUM_DEFAULTS.f_min_per_mm,
        f_max_per_mm: float = SPECTRUM_DEFAULTS.f_max_per_mm,
        n_freqs: int = SPECTRUM_DEFAULTS.n_freqs,
        n_jobs: int = 1,
        window: str = SPECTRUM_DEFAULTS.window,
        max_pixels: int = DEFAULT_MAX_PIXELS,
    ) -> None:
        self.max_pixels = max_pixels
        self.px_per_mm = px_per_mm
        self.roi = roi
        self.rows = rows
        self.f_min_per_mm = f_min_per_mm
        self.f_max_per_mm = f_max_per_mm
        self.n_freqs = n_freqs
        self.n_jobs = n_jobs
        self.window = window

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.requires_fit = False
        tags.input_tags.two_d_array = False
        return tags

    def _plan(self) -> _Plan:
        return _Plan.build(
            self.px_per_mm, self.roi, self.rows, self.f_min_per_mm, self.f_max_per_mm, self.n_freqs, self.window,
            self.max_pixels,
        )

    def _jobs(self) -> int:
        n = check(self.n_jobs, N_JOBS, name="n_jobs")
        return usable_cores() if n == -1 else n

    def fit(self, X=None, y=None) -> SpatialSpectrum:
        """Check the settings and record the grid in ``freq_per_mm_``; no image is read.

        Parameters
        ----------
        X, y : ignored
            Accepted for scikit-learn's API.

        Returns
        -------
        SpatialSpectrum
            This transformer.
        """
        self.freq_per_mm_ = self._plan().freq_per_mm
        self._jobs()
        return self

    def transform(self, X) -> np.ndarray:
        """The spectra of the images, one row each.

        Parameters
        ----------
        X : iterable of str, os.PathLike or numpy.ndarray
            Image files or pixel arrays.

        Returns
        -------
        numpy.ndarray
            (n_images, n_freqs) spectra, in the order given.
        """
        n_freqs = self._plan().freq_per_mm.size
        rows = list(self.iter_transform(X))
        return np.vstack(rows) if rows else np.empty((0, n_freqs))

    def iter_transform(self, images: Iterable) -> Iterator[np.ndarray]:
        """Yield one spectrum per image, in order, holding at most ~2 x n_jobs decoded images at a time.

        Parameters
        ----------
        images : iterable of str, os.PathLike or numpy.ndarray
            Image files or pixel arrays (read lazily, so a long list costs no memory).

        Returns
        -------
        iterator of numpy.ndarray
            One (n_freqs,) spectrum per image.
        """
        return self._iter(images, _Plan.spectrum)

    def iter_transform_lines(self, images: Iterable) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """As :meth:`iter_transform`, each spectrum with the gray line it was taken from: what the band and scale
        checks (``sensor/band.py``, ``sensor/period.py``) read, at no second decoding.

        Parameters
        ----------
        images : iterable of str, os.PathLike or numpy.ndarray
            Image files or pixel arrays.

        Returns
        -------
        iterator of tuple
            (spectrum (n_freqs,), gray line (w,)) per image, in order.
        """
        return self._iter(images, _Plan.spectrum_and_line)

    def _iter(self, images: Iterable, one) -> Iterator:
        plan = self._plan()  # checked at the first image, as before: a generator, like the loop it replaced
        yield from thread_map(lambda numbered: one(plan, numbered[1], numbered[0]), enumerate(images), self._jobs())

    def line(self, image) -> tuple[np.ndarray, tuple[int, int, int, int]]:
        """The gray line (values along the row, one per px) whose spectrum :meth:`transform` takes, and its crop
        (x, y, w, h): what ``roughsense features --plot`` draws beside the spectrum.

        Parameters
        ----------
        image : str, os.PathLike or numpy.ndarray
            One image file or pixel array.

        Returns
        -------
        line : numpy.ndarray
            (w,) gray values of the crop's central row(s).
        box : tuple of int
            The crop (x, y, w, h) in pixels.
        """
        plan = self._plan()
        pixels = as_image(image, max_pixels=plan.max_pixels)
        box = resolve_roi(plan.roi, pixels, name=image if isinstance(image, (str, os.PathLike)) else None)
        return extract_line(pixels, box, plan.rows), box

    def get_feature_names_out(self, input_features=None) -> np.ndarray:
        """Column names: each frequency in mm^-1 as the shortest decimal that round-trips to the float.

        Parameters
        ----------
        input_features : ignored
            Accepted for scikit-learn's API.

        Returns
        -------
        numpy.ndarray
            (n_freqs,) strings.
        """
        return np.asarray([repr(float(f)) for f in self._plan().freq_per_mm], dtype=object)

    def feature_definition(self) -> dict:
        """JSON-able record of everything needed to recompute these features from the same images.

        Returns
        -------
        dict
            Settings and conventions; a model file stores it, and :meth:`from_definition` reads it back.
        """
        plan = self._plan()
        roi = plan.roi if isinstance(plan.roi, str) else list(plan.roi)
        return {
            "kind": "roughsense.SpatialSpectrum",
            "version": FEATURE_VERSION,
            "px_per_mm": plan.px_per_mm,
            "roi": roi,
            "center_crop_px": list(CENTER_CROP_PX) if roi in ("center", "auto") else None,
            "rows": plan.rows,
            "row_selection": "rows (h - rows) // 2 ... + rows - 1 of the crop, averaged",
            "gray_weights_rgb": list(GRAY_WEIGHTS_RGB),
            "intensity_scale": "uint8 / 255, uint16 / 65535, float as is",
            "f_min_per_mm": float(plan.freq_per_mm[0]),
            "f_max_per_mm": float(plan.freq_per_mm[-1]),
            "n_freqs": int(plan.freq_per_mm.size),
            "freq_per_mm": [float(f) for f in plan.freq_per_mm],
            "dc_removal": "subtract line mean",
            "window": plan.window,
            "evaluation": "direct DFT at the grid frequencies (no zero-padding, no interpolation)",
            "amplitude_scale": "2 / sum(window)",
            "normalisation": "trapezoid area over mm^-1 equals 1",
        }

    @classmethod
    def from_definition(cls, definition: dict, *, n_jobs: int = 1, max_pixels: int = DEFAULT_MAX_PIXELS) -> SpatialSpectrum:
        """Rebuild the transformer from :meth:`feature_definition` (e.g. one stored in a model file).

        Parameters
        ----------
        definition : dict
            A :meth:`feature_definition`.
        n_jobs, max_pixels
            As the constructor's (they do not change the features, so the definition leaves them out).

        Returns
        -------
        SpatialSpectrum
            A transformer computing the same features.
        """
        try:
            if definition.get("kind") != "roughsense.SpatialSpectrum" or definition.get("version") != FEATURE_VERSION:
                raise KeyError("kind/version")
            roi = definition["roi"]
            return cls(
                px_per_mm=float(definition["px_per_mm"]),
                roi=roi if isinstance(roi, str) else tuple(int(v) for v in roi),
                rows=int(definition["rows"]),
                f_min_per_mm=float(definition["f_min_per_mm"]),
                f_max_per_mm=float(definition["f_max_per_mm"]),
                n_freqs=int(definition["n_freqs"]),
                n_jobs=n_jobs,
                window=str(definition.get("window", "hann")),  # files from before the option: always Hann
                max_pixels=max_pixels,
            )
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ConfigError(f"not a usable SpatialSpectrum feature definition ({exc})") from None
