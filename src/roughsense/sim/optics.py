"""What the camera sees: the gap along the line becomes a bright band, then lens, light and sensor degrade it.

The clean image is separable -- (vignetting x illumination)(x, y) times (background(y) + band(y) * line(x)) --
so blur and shading are applied to 1D profiles and the frame is two outer products. Only the sensor noise is
drawn per pixel. That keeps a 1920 x 1080 frame at a few tens of milliseconds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..errors import ConfigError

WIDTH_PX = 1920
HEIGHT_PX = 1080
PX_PER_MM = 34.9  # 349 px/cm, paper section 2.1
VIEW_ANGLE_DEG = 45.0


@dataclass(frozen=True)
class Camera:
    """Camera, lens and light. Values the paper does not give are documented in docs/simulator.md."""

    width_px: int = WIDTH_PX
    height_px: int = HEIGHT_PX
    px_per_mm: float = PX_PER_MM
    contact_width_mm: float = 10.0  # the specimen's width, seen foreshortened at 45 degrees
    band_edge_px: float = 6.0  # softness of the band's upper and lower edges
    gap_decay_mm: float = 0.02  # contrast ~ exp(-gap / delta): frustrated reflection fades within tens of um
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

    @property
    def field_mm(self) -> float:
        return self.width_px / self.px_per_mm

    @property
    def band_height_px(self) -> float:
        return self.contact_width_mm * math.cos(math.radians(VIEW_ANGLE_DEG)) * self.px_per_mm

    def contrast(self, gap_mm: np.ndarray) -> np.ndarray:
        """Brightness (0..1) of a point of the line from its gap: 1 in contact, fading as the pad lifts off."""
        g = np.asarray(gap_mm, dtype=float)
        return (1.0 - self.far_weight) * np.exp(-g / self.gap_decay_mm) + self.far_weight * np.exp(-g / self.far_decay_mm)


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

    ``spots`` are dust specks, bubbles and smudges: (x_mm from the frame's left, y_mm from the band centre,
    size_mm, strength), each a Gaussian that darkens (strength > 0) or brightens the frame locally.
    ``rows=(start, stop)`` returns only rows start..stop-1, bit-identical to those rows of the whole frame: the
    noise of the rows above is still drawn (the generator fills row by row), nothing below is.
    """
    w, h = camera.width_px, camera.height_px
    start, stop = (0, h) if rows is None else (int(rows[0]), int(rows[1]))
    if not 0 <= start < stop <= h:
        raise ValueError(f"rows must satisfy 0 <= start < stop <= {h}, got {rows}")
    line = np.asarray(line, dtype=float)
    if line.shape != (w,):
        raise ValueError(f"line must have {w} samples, got {line.shape}")
    x = (np.arange(w) + 0.5 - w / 2) / (w / 2)  # -1..1
    y = (np.arange(h) + 0.5 - h / 2) / (w / 2)  # same scale as x (square pixels)
    corner = 1.0 + (h / w) ** 2
    # Gaussian vignetting is separable: exp(-r^2) = exp(-x^2) exp(-y^2); scaled to the requested corner fall-off.
    k = -math.log(1.0 - camera.vignetting) / corner
    shade_x = np.exp(-k * x * x) * lighting.gain * (1.0 + 0.5 * lighting.gradient * x)
    x_mm = (np.arange(w) + 0.5) / camera.px_per_mm
    for amplitude, wavelength_mm, phase in lighting.ripple:
        shade_x = shade_x * (1.0 + amplitude * np.sin(2.0 * math.pi * x_mm / wavelength_mm + phase))
    shade_y = np.exp(-k * y * y)

    rows = np.arange(h) + 0.5
    half = camera.band_height_px / 2.0
    edge = max(camera.band_edge_px, 1e-6)
    band = 0.5 * (np.tanh((rows - band_center_px + half) / edge) - np.tanh((rows - band_center_px - half) / edge))
    sigma = camera.blur_sigma_px
    if sigma > 0:
        line = gaussian_filter1d(line, sigma, mode="nearest")
        band = gaussian_filter1d(band, sigma, mode="nearest")

    band_x = (camera.band_floor_dn + (camera.contact_dn - camera.band_floor_dn) * line) * shade_x
    col_bg = (camera.background_dn * shade_y).astype(np.float32)[start:stop]
    col_band = (band * shade_y).astype(np.float32)[start:stop]
    frame = np.outer(col_bg * (1.0 - band.astype(np.float32)[start:stop]), shade_x.astype(np.float32))
    frame += np.outer(col_band, band_x.astype(np.float32))
    for x_mm0, y_mm0, size_mm, strength in spots:
        _add_spot(frame, x_mm0 * camera.px_per_mm, band_center_px + y_mm0 * camera.px_per_mm,
                  size_mm * camera.px_per_mm, strength, first_row=start)
    # sensor noise: read noise + signal-dependent shot noise, then 8-bit quantisation
    noise = rng.standard_normal((stop, w), dtype=np.float32)[start:]
    noise *= np.sqrt(np.float32(camera.read_noise_dn**2) + np.float32(camera.shot_noise_gain) * np.maximum(frame, 0))
    frame += noise
    np.clip(frame, 0.0, 255.0, out=frame)
    return np.rint(frame).astype(np.uint8)


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
