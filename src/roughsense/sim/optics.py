"""What the camera sees: the gap along the line becomes a bright band, then lens, light and sensor degrade it.

The clean image is separable -- (vignetting x illumination)(x, y) times (background(y) + band(y) * line(x)) --
so blur and shading are applied to 1D profiles and the frame is two outer products. Only the sensor noise is
drawn per pixel, and only for the rows stored (a window of the sensor round the band): a frame costs milliseconds.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.special import log_ndtr, ndtr, ndtri

from .. import defaults
from ..errors import ConfigError

WIDTH_PX = 1920
HEIGHT_PX = 1080
VIEW_ANGLE_DEG = 45.0


@dataclass(frozen=True)
class Camera:
    """Camera, lens and light. Values the paper does not give are documented in docs/simulator.md."""

    width_px: int = WIDTH_PX
    height_px: int = HEIGHT_PX
    # Rows kept per stored frame, centred on the sensor (0: all): the band (247 px) plus 3 SD of its placement on
    # each side. A camera's sensor window (AOI) would write the same frame; the paper's centred 1900 x 150 crop of
    # it is the crop of the full frame (docs/simulator.md, "Frames on disk").
    stored_height_px: int = defaults.STORED_HEIGHT_PX
    px_per_mm: float = defaults.PX_PER_MM
    contact_width_mm: float = 10.0  # the specimen's width, seen foreshortened at 45 degrees
    band_edge_px: float = 6.0  # softness of the band's upper and lower edges
    wavelength_mm: float = 550e-6  # the light's (mid-visible) wavelength in vacuum
    pad_index: float = 1.5  # refractive index of the PVC plastisol pad (air in the gap: 1.0)
    incidence_deg: float = 45.0  # angle of the imaging rays on the contact face, inside the pad
    micro_roughness_mm: float = 0.0005  # RMS of the local gap from the pad's and the sanded print's micro-roughness
    far_weight: float = 0.12  # faint view of the specimen through the pad where it does not touch
    far_decay_mm: float = 0.4
    blur_sigma_px: float = 1.5  # lens blur (Gaussian)
    background_dn: float = 14.0  # pad body outside the band
    band_floor_dn: float = 45.0  # band where nothing touches
    contact_dn: float = 120.0  # band at full contact
    vignetting: float = 0.25  # relative fall-off at the frame's corners
    read_noise_dn: float = 12.0
    shot_noise_gain: float = 0.08  # variance per DN of signal (Poisson-like)

    def __post_init__(self) -> None:
        if self.width_px < 16 or self.height_px < 16:
            raise ConfigError(f"image must be at least 16 x 16 px, got {self.width_px} x {self.height_px}")
        if not (math.isfinite(self.px_per_mm) and self.px_per_mm > 0):
            raise ConfigError(f"px_per_mm must be positive, got {self.px_per_mm!r}")
        stored = self.stored_height_px
        if not (isinstance(stored, (int, float)) and float(stored).is_integer() and (stored == 0 or stored >= 16)):
            raise ConfigError(f"stored_height_px must be 0 (the whole frame) or at least 16, got {self.stored_height_px!r}")
        if (self.height_px - self.frame_height_px) % 2:
            raise ConfigError(f"stored_height_px {self.stored_height_px} and height_px {self.height_px} must differ by an "
                              "even number of rows, so that the stored frame is centred on the sensor")
        for name in ("wavelength_mm", "pad_index"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"camera {name} must be a positive number, got {value!r}")
        if not (math.isfinite(self.micro_roughness_mm) and self.micro_roughness_mm >= 0):
            raise ConfigError(f"camera micro_roughness_mm must be >= 0, got {self.micro_roughness_mm!r}")
        if not self.pad_index * math.sin(math.radians(self.incidence_deg)) > 1.0:
            raise ConfigError(f"no total internal reflection at {self.incidence_deg:g} degrees in a pad of index "
                              f"{self.pad_index:g}: n sin(theta) must exceed 1 (the air's index)")

    @property
    def frame_height_px(self) -> int:
        """Rows of the stored frame: ``stored_height_px`` centred on the sensor, or all of them."""
        if self.stored_height_px == 0 or self.stored_height_px >= self.height_px:
            return int(self.height_px)
        return int(self.stored_height_px)

    @property
    def frame_top_px(self) -> int:
        """The sensor row the stored frame starts at."""
        return int(self.height_px - self.frame_height_px) // 2

    @property
    def field_mm(self) -> float:
        return self.width_px / self.px_per_mm

    @property
    def band_height_px(self) -> float:
        return self.contact_width_mm * math.cos(math.radians(VIEW_ANGLE_DEG)) * self.px_per_mm

    @property
    def evanescent_decay_mm(self) -> float:
        """Intensity decay length of the evanescent field behind the pad's face, d = lambda / (4 pi kappa).

        kappa = sqrt(n1^2 sin^2(theta) - n2^2) with n2 = 1 (air): the frustrated-reflection (and TIRF) result,
        e.g. Axelrod 2001; 0.12 um for n1 = 1.5 at 45 degrees and 550 nm.
        """
        kappa = math.sqrt((self.pad_index * math.sin(math.radians(self.incidence_deg))) ** 2 - 1.0)
        return self.wavelength_mm / (4.0 * math.pi * kappa)

    def optical_contact(self, gap_mm: np.ndarray) -> np.ndarray:
        """Fraction of the light coupled into the specimen at a mean-plane gap g, relative to g = 0.

        The local gap is g + sigma * z, z ~ N(0, 1), clipped at 0 (the micro-asperities that reach the specimen are
        in optical contact), and each local gap h couples exp(-h / d). Its mean over z is, in closed form,
        Phi(-g/sigma) + exp(s^2 / 2 - g/d) Phi(g/sigma - s), s = sigma / d (evaluated in logs: s is about 4).
        """
        g = np.maximum(np.asarray(gap_mm, dtype=float), 0.0)
        d, sigma = self.evanescent_decay_mm, self.micro_roughness_mm
        if sigma <= 0:
            return np.exp(-g / d)
        s = sigma / d
        # Beyond 10 sigma + d (s^2/2 + 30) both terms are below 1e-13: most of a line is either touching or microns
        # away, so the special functions are evaluated only on the thin rim between (about a third of the cost).
        coupled = np.zeros_like(g)
        near = g < 10.0 * sigma + d * (0.5 * s * s + 30.0)
        g_near = g[near]
        coupled[near] = ndtr(-g_near / sigma) + np.exp(0.5 * s * s - g_near / d + log_ndtr(g_near / sigma - s))
        at_contact = 0.5 + math.exp(0.5 * s * s + float(log_ndtr(-s)))
        return coupled / at_contact

    def contrast(self, gap_mm: np.ndarray) -> np.ndarray:
        """Brightness (0..1) of a point of the line from its gap: 1 in contact, fading as the pad lifts off.

        Optical contact (frustrated reflection through a micro-rough interface, sigma ~0.5 um) plus a faint view of the
        specimen through the pad that fades over ``far_decay_mm``; docs/simulator.md, Optics.
        """
        g = np.asarray(gap_mm, dtype=float)
        return (1.0 - self.far_weight) * self.optical_contact(g) + self.far_weight * np.exp(-g / self.far_decay_mm)


@dataclass(frozen=True)
class Lighting:
    """Trial-to-trial state of the light: overall gain, a left-right gradient, a slow ripple along the line."""

    gain: float = 1.0
    gradient: float = 0.0  # relative change across the frame, left to right
    ripple: tuple[tuple[float, float, float], ...] = ()  # (relative amplitude, wavelength_mm, phase)


def render(camera: Camera, line: np.ndarray, *, band_center_px: float, lighting: Lighting,
           rng: np.random.Generator, spots: tuple[tuple[float, float, float, float], ...] = (),
           rows: tuple[int, int] | None = None) -> np.ndarray:
    """Render an 8-bit gray frame from the line's brightness (0..1 per pixel column).

    The frame holds the sensor rows ``camera.frame_top_px`` on (``camera.frame_height_px`` of them): shading and
    band are those of the whole sensor, only the stored rows are drawn and noised. ``band_center_px`` is a sensor row.
    ``spots`` are dust specks, bubbles and smudges: (x_mm from the frame's left, y_mm from the band centre,
    size_mm, strength), each a Gaussian that darkens (strength > 0) or brightens the frame locally.
    ``rows=(start, stop)`` returns only rows start..stop-1 of that frame, bit-identical to them: the noise of the
    rows above is still drawn (the generator fills row by row), nothing below is (sweeps read one row per frame).
    """
    w, h = camera.width_px, camera.height_px
    kept = camera.frame_height_px
    start, stop = (0, kept) if rows is None else (int(rows[0]), int(rows[1]))
    if not 0 <= start < stop <= kept:
        raise ValueError(f"rows must satisfy 0 <= start < stop <= {kept}, got {rows}")
    line = np.asarray(line, dtype=float)
    if line.shape != (w,):
        raise ValueError(f"line must have {w} samples, got {line.shape}")
    shade_x, shade_y = _shading(camera, lighting)

    yc = np.arange(h) + 0.5  # row centres
    half = camera.band_height_px / 2.0
    edge = max(camera.band_edge_px, 1e-6)
    band = 0.5 * (np.tanh((yc - band_center_px + half) / edge) - np.tanh((yc - band_center_px - half) / edge))
    sigma = camera.blur_sigma_px
    if sigma > 0:
        line = gaussian_filter1d(line, sigma, mode="nearest")
        band = gaussian_filter1d(band, sigma, mode="nearest")

    band_x = (camera.band_floor_dn + (camera.contact_dn - camera.band_floor_dn) * line) * shade_x
    top = camera.frame_top_px
    rows_kept = slice(top + start, top + stop)
    band, shade_y = band[rows_kept], shade_y[rows_kept]
    col_bg = (camera.background_dn * shade_y).astype(np.float32)
    col_band = (band * shade_y).astype(np.float32)
    frame = _clean_frame(col_bg * (1.0 - band.astype(np.float32)), shade_x.astype(np.float32), col_band,
                         band_x.astype(np.float32))
    for x_mm0, y_mm0, size_mm, strength in spots:
        _add_spot(frame, x_mm0 * camera.px_per_mm, band_center_px - top + y_mm0 * camera.px_per_mm,
                  size_mm * camera.px_per_mm, strength, first_row=start)
    return _expose(frame, camera, rng, start, stop)


def _clean_frame(background: np.ndarray, shade_x: np.ndarray, band: np.ndarray, band_x: np.ndarray) -> np.ndarray:
    """The two outer products background x shade_x + band x band_x (float32), in blocks of :data:`EXPOSE_ROWS` rows
    so the second product and the sum stay in cache (the same numbers as whole ``np.outer`` products)."""
    frame = np.empty((background.size, shade_x.size), dtype=np.float32)
    for top in range(0, background.size, EXPOSE_ROWS):
        rows = slice(top, top + EXPOSE_ROWS)
        np.multiply(background[rows, None], shade_x[None, :], out=frame[rows])
        frame[rows] += np.multiply(band[rows, None], band_x[None, :])
    return frame


def _shading(camera: Camera, lighting: Lighting) -> tuple[np.ndarray, np.ndarray]:
    """Illumination across the sensor as a column profile times a row profile (vignetting, gain, gradient, ripple).

    Gaussian vignetting is separable, exp(-r^2) = exp(-x^2) exp(-y^2), so the whole sensor's shading is an outer
    product; it is scaled to the requested fall-off in the corner.
    """
    w, h = camera.width_px, camera.height_px
    x = (np.arange(w) + 0.5 - w / 2) / (w / 2)  # -1..1
    y = (np.arange(h) + 0.5 - h / 2) / (w / 2)  # same scale as x (square pixels)
    corner = 1.0 + (h / w) ** 2
    k = -math.log(1.0 - camera.vignetting) / corner
    shade_x = np.exp(-k * x * x) * lighting.gain * (1.0 + 0.5 * lighting.gradient * x)
    x_mm = (np.arange(w) + 0.5) / camera.px_per_mm
    for amplitude, wavelength_mm, phase in lighting.ripple:
        shade_x = shade_x * (1.0 + amplitude * np.sin(2.0 * math.pi * x_mm / wavelength_mm + phase))
    return shade_x, np.exp(-k * y * y)


def _expose(frame: np.ndarray, camera: Camera, rng: np.random.Generator, start: int, stop: int) -> np.ndarray:
    """Sensor noise (read noise + signal-dependent shot noise), then 8-bit quantisation, in place.

    The noise of rows above ``start`` is drawn and dropped, so a slice of rows is bit-identical to the same rows
    of the whole frame (the generator fills row by row). The draws are made at once; the arithmetic runs in blocks
    of :data:`EXPOSE_ROWS` rows, each small enough to stay in cache through its eight passes (the same numbers,
    about 15 % less time per frame than whole-frame passes).
    """
    index = rng.integers(0, NOISE_TABLE_SIZE, (stop, camera.width_px), dtype=np.uint16)[start:]
    table = standard_normal_table()
    gain, read_variance = np.float32(camera.shot_noise_gain), np.float32(camera.read_noise_dn**2)
    exposed = np.empty(frame.shape, dtype=np.uint8)
    for top in range(0, frame.shape[0], EXPOSE_ROWS):
        block = frame[top:top + EXPOSE_ROWS]
        noise = table.take(index[top:top + EXPOSE_ROWS])
        sd = np.maximum(block, np.float32(0.0))
        sd *= gain
        sd += read_variance
        np.sqrt(sd, out=sd)
        noise *= sd
        block += noise
        np.clip(block, 0.0, 255.0, out=block)
        np.rint(block, out=block)
        exposed[top:top + EXPOSE_ROWS] = block  # whole numbers in 0..255: the cast is exact
    return exposed


#: Rows exposed per block: 32 x 1920 float32 is 240 KiB, within a core's L2 cache.
EXPOSE_ROWS = 32
NOISE_TABLE_SIZE = 1 << 16


@functools.cache
def standard_normal_table() -> np.ndarray:
    """Standard normal quantiles at the midpoints of 2^16 equal-probability bins (float32).

    Indexing it with uniform 16-bit integers samples the sensor noise four times faster than NumPy's ziggurat (a
    frame has 0.6 M pixels). The draws are exact quantiles: only tails beyond 4.3 sigma are cut (1.7e-5 of pixels,
    52 DN at the 12 DN read noise), which an 8-bit frame already clips.
    """
    return ndtri((np.arange(NOISE_TABLE_SIZE) + 0.5) / NOISE_TABLE_SIZE).astype(np.float32)


def apparent_contact_fraction(line: np.ndarray, camera: Camera) -> float:
    """Fraction of pixel columns that look in contact: brighter, after the lens blur, than half-way from "nothing
    touches" (the faint view of the specimen through the pad, ``far_weight``) to full contact.

    What one reads off the band; compared with the solver's contact in tests and scripts/contact_agreement.py.
    """
    line = np.asarray(line, dtype=float)
    if camera.blur_sigma_px > 0:
        line = gaussian_filter1d(line, camera.blur_sigma_px, mode="nearest")
    return float(np.mean(line > 0.5 * (1.0 + camera.far_weight)))


def bin_to_pixels(values: np.ndarray, width_px: int) -> np.ndarray:
    """Average ``width_px * s`` sub-pixel samples into ``width_px`` pixels (a pixel integrates its area)."""
    values = np.asarray(values, dtype=float)
    sub = values.size // width_px
    if sub * width_px != values.size:
        raise ValueError("sample count must be a multiple of the pixel count")
    return values.reshape(width_px, sub).mean(axis=1)


def _add_spot(frame: np.ndarray, cx: float, cy: float, sigma: float, strength: float, *, first_row: int = 0) -> None:
    """Darken a Gaussian spot at (cx, cy) in frame pixels; ``frame`` holds the rows from ``first_row`` on."""
    h, w = frame.shape
    r = int(math.ceil(4 * sigma))
    x0, x1 = max(int(cx) - r, 0), min(int(cx) + r + 1, w)
    y0, y1 = max(int(cy) - r, first_row), min(int(cy) + r + 1, first_row + h)
    if x0 >= x1 or y0 >= y1:
        return
    gx = np.exp(-0.5 * ((np.arange(x0, x1) + 0.5 - cx) / sigma) ** 2).astype(np.float32)
    gy = np.exp(-0.5 * ((np.arange(y0, y1) + 0.5 - cy) / sigma) ** 2).astype(np.float32)
    rows = slice(y0 - first_row, y1 - first_row)
    frame[rows, x0:x1] *= 1.0 - np.float32(min(strength, 0.95)) * np.outer(gy, gx)  # a spot never inverts
