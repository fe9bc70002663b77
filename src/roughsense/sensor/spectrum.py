"""Contact image -> spatial spectrum: the predictors X of the paper (section 3.2), as a scikit-learn transformer.

crop the contact band -> gray (MATLAB weights) -> middle row (or mean of the N central rows) ->
remove the line mean -> Hann window -> amplitude of the DFT evaluated exactly at an evenly spaced grid
of spatial frequencies (mm^-1) -> normalise to unit trapezoid area over mm^-1.

The image-to-line steps and the one-image function are :mod:`.line`'s, the grid and the DFT :mod:`.grid`'s; this
module is the transformer over many images. Decoding is the floor, and
:meth:`SpatialSpectrum.iter_transform` overlaps it over threads (:func:`roughsense._util.workers.thread_map`) while
holding only a handful of images in memory. The choices the paper leaves open are explained in docs/sensor.md.
"""
from __future__ import annotations

import functools
import os
from collections.abc import Iterable, Iterator, Sequence

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin

from .. import defaults
from .._util.checks import POSITIVE_INT, AnyOf, Described, Integer, check
from .._util.workers import thread_map, usable_cores
from ..defaults import CENTER_CROP_PX, MAX_PIXELS, PX_PER_MM, ROI
from ..errors import ConfigError, InputError
from ..io.images import GRAY_WEIGHTS_RGB, as_image
from ..io.sensor_settings import Roi
from .contact_geometry import band_profile, read_contact
from .line import _Plan, extract_line, resolve_roi

__all__ = ["SpatialSpectrum", "combine_forces"]

FEATURE_VERSION = 1
N_JOBS = Described(AnyOf(POSITIVE_INT, Integer(-1, -1)), "a positive whole number or -1")


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
        As :func:`.line.spatial_spectrum`.
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
        px_per_mm: float = PX_PER_MM,
        roi: Roi = ROI,
        rows: int = defaults.ROWS,
        f_min_per_mm: float = defaults.F_MIN_PER_MM,
        f_max_per_mm: float = defaults.F_MAX_PER_MM,
        n_freqs: int = defaults.N_FREQS,
        n_jobs: int = 1,
        window: str = defaults.WINDOW,
        max_pixels: int = MAX_PIXELS,
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

    def iter_transform_contact(self, images: Iterable, ridge_period_mm: float | None = None
                               ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """As :meth:`iter_transform`, each spectrum with the press's contact measures
        (``sensor/contact_geometry.py``: :data:`~.contact_geometry.CONTACT_MEASURES`, NaN where one cannot be read),
        read from the rows the spectrum's decoding already holds. An unreadable image raises as in
        :meth:`iter_transform`.

        Parameters
        ----------
        images : iterable of str, os.PathLike or numpy.ndarray
            Image files or pixel arrays.
        ridge_period_mm : float, optional
            The pad's ridge period (None: a smooth pad); a ridged pad's land and groove are read on its crests.

        Returns
        -------
        iterator of tuple
            (spectrum (n_freqs,), contact (len(CONTACT_MEASURES),) float64) per image, in order.
        """
        return self._iter(images, functools.partial(_Plan.contact, ridge_period_mm=ridge_period_mm))

    def iter_readings(self, images: Iterable, ridge_period_mm: float | None = None) -> Iterator:
        """As :meth:`iter_transform_lines`, with each press's descriptors (``sensor/descriptors.py``) and contact
        measures (one key per :data:`~.contact_geometry.CONTACT_MEASURES` name): per image
        ``(spectrum, line, descriptors)``, or the :class:`InputError` that refused it (predict withholds that press
        and goes on with the others).

        Parameters
        ----------
        images : iterable of str, os.PathLike or numpy.ndarray
            Image files or pixel arrays.
        ridge_period_mm : float, optional
            The pad's ridge period (None: a smooth pad).

        Returns
        -------
        iterator
            One tuple or error per image, in order.
        """
        return self._iter(images, functools.partial(_Plan.reading, ridge_period_mm=ridge_period_mm))

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

    def contact_reading(self, image, ridge_period_mm: float | None = None):
        """The band profile (the crop's rows down to the line, averaged) and its contact reading
        (:class:`~.contact_geometry.ContactReading`: the measures, the spans read, the threshold): what
        ``roughsense features --plot`` draws.

        Parameters
        ----------
        image : str, os.PathLike or numpy.ndarray
            One image file or pixel array.
        ridge_period_mm : float, optional
            The pad's ridge period (None: a smooth pad).

        Returns
        -------
        profile : numpy.ndarray
            (w,) gray values of the band.
        reading : ContactReading
            Its measures and spans.
        """
        plan = self._plan()
        pixels = as_image(image, max_pixels=plan.max_pixels)
        box = resolve_roi(plan.roi, pixels, name=image if isinstance(image, (str, os.PathLike)) else None)
        profile = band_profile(pixels, box, plan.rows)
        return profile, read_contact(profile, plan.px_per_mm, ridge_period_mm=ridge_period_mm)

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
    def from_definition(cls, definition: dict, *, n_jobs: int = 1, max_pixels: int = MAX_PIXELS) -> SpatialSpectrum:
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
