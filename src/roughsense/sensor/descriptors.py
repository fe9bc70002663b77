"""What a press looks like as a whole, in a few numbers: the contact-image gate's inputs and the grating's orientation.

A spectrum says how rough a surface is only if the image is a contact image of the pad the model was trained on, at
its scale and orientation. These descriptors say whether it is, cheaply, from what the spectrum already decoded: the
gray line and a thin strip of :data:`STRIP_ROWS` rows ending at it (the PNG is decoded only down to the line, so the
strip costs no decoding). Each one answers a way a real rig goes wrong:

``peak_over_noise``
    The band's strongest peak (below the ridge window) over the line spectrum's noise floor (the median amplitude from
    f_min to Nyquist: a grating's harmonics are a few bins, so the median is the noise). A grating stands far above
    it; a blank frame, noise or a photograph does not. "No grating".
``ridges_over_noise``
    The strongest peak at the fingerprint pad's ridge frequency (1 / ridge period, +-5 %: the twin's mounts vary
    its scale by 2 %) over the same floor: present on a fingerprint pad, absent on a smooth one. "Another pad".
``ridges_over_band``
    That peak over the band's own: a smooth pad's gratings may put a harmonic at 1 mm^-1, but far below their
    fundamental; a fingerprint pad's ridges rival or exceed it.
``ridge_period_mm`` (a ridged pad only)
    Where the strongest peak around the ridge frequency (x0.8-1.25) is: a press magnified by 10 % puts 1 mm ridges at
    1.1 mm.
``contrast_dn``
    The line's 5-95 % gray range in 8-bit levels (DN): the contact band's contrast; a bare background or a blank frame
    has none, a photograph has another.
``mean_dn``
    The line's mean gray (DN): the band's brightness (illumination, exposure, a bare background).
``noise_dn``
    The pixel noise: the standard deviation of the strip's row-to-row differences over sqrt 2. The grating's lines
    run along the columns, so these differences are the camera's noise; another camera, a synthetic frame or a
    resampled one has another.
``noise_whiteness``
    The variance of the second row differences over the first's: 3 for white pixel noise; a digitally magnified
    (interpolated) press has smoothed, correlated noise and a smaller ratio, whatever its grating says.
``coherence``
    The structure tensor's coherence over the strip, ((Jxx - Jyy)^2 + 4 Jxy^2)^0.5 / (Jxx + Jyy): how much of the
    strip's structure runs in one direction (a grating's lines) rather than every way (a photograph, noise).

``orientation_deg`` is the angle of the grating's lines from the image columns (0 when they run straight across the
line), from how the grating's phase moves down the strip (:func:`line_shift_angle`); on a ridged pad, from the
ridges' phase where it moves more cleanly (the ridges run along the grating's lines, and the grating's own peak is
mixed there with the ridges' sidebands). It is not a gate
input but a flag with its own tolerance (``model/contact_gate.py``), said beside each prediction.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..io.images import GRAY_WEIGHTS_RGB, intensity_scale

#: Rows of the strip ending at the line (it lies inside the crop's upper half, which the line's decoding covers):
#: the orientation reads every ORIENTATION_STRIDE-th of them (a phase slope over 64 rows), the noise and the
#: structure tensor the last NOISE_ROWS.
STRIP_ROWS = 64
ORIENTATION_STRIDE = 4
NOISE_ROWS = 16
#: Columns of the strip the noise and the structure tensor read (its centre): 18 mm at 34.9 px/mm, several periods
#: of any grating in the band, and 10 000 pixel differences, at a third of the whole strip's cost.
STRIP_COLUMNS = 640
#: The fingerprint pad's ridge window, as factors of its ridge frequency; a pad without ridges is looked at 1 mm.
RIDGE_WINDOW = (0.8, 1.25)
RIDGE_PEAK = (0.95, 1.05)
DEFAULT_RIDGE_PERIOD_MM = 1.0
#: 8-bit gray levels: the unit of contrast, brightness and noise the reasons speak in.
DN = 255.0

#: Every descriptor a gate may use, in order.
DESCRIPTORS = ("peak_over_noise", "ridges_over_noise", "ridges_over_band", "ridge_period_mm", "contrast_dn",
               "mean_dn", "noise_dn", "noise_whiteness", "coherence")


def descriptor_names(ridged: bool) -> tuple[str, ...]:
    """The gate's inputs for a pad with ridges (``ridged``) or without: a smooth pad has no ridge period to read."""
    return tuple(n for n in DESCRIPTORS if ridged or n != "ridge_period_mm")


def press_strips(pixels: np.ndarray, box: tuple[int, int, int, int], rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The gray rows the descriptors read, from pixels already decoded down to the line: every
    :data:`ORIENTATION_STRIDE`-th row of the :data:`STRIP_ROWS` ending at the line (full width), and the last
    :data:`NOISE_ROWS` rows' central :data:`STRIP_COLUMNS` columns. Only those pixels are converted to gray."""
    x, y, w, h = box
    stop = y + (h - rows) // 2 + rows
    start = max(y, stop - STRIP_ROWS)
    picked = np.arange(stop - 1, start - 1, -ORIENTATION_STRIDE)[::-1]
    left = x + max(0, (w - STRIP_COLUMNS) // 2)
    return (_gray(pixels[picked, x:x + w]), _gray(pixels[max(y, stop - NOISE_ROWS):stop, left:left + min(w, STRIP_COLUMNS)]))


def _gray(pixels: np.ndarray) -> np.ndarray:
    """Gray 0-1 in float32 (the line's scale; single precision is ample for these statistics and halves their cost)."""
    scale = np.float32(1.0 / intensity_scale(pixels.dtype))
    if pixels.ndim == 2:
        return pixels.astype(np.float32) * scale
    return pixels[..., :3].astype(np.float32) @ (np.asarray(GRAY_WEIGHTS_RGB, dtype=np.float32) * scale)


@functools.lru_cache(maxsize=8)
def _hann(n: int) -> np.ndarray:
    """The Hann window of n points, read-only and shared (every press of a batch has the same width)."""
    window = np.hanning(n)
    window.flags.writeable = False
    return window


def line_spectrum(line: np.ndarray, px_per_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies in mm^-1, amplitudes) of the mean-removed, Hann-windowed line: one real FFT."""
    n = line.size
    amplitude = np.abs(np.fft.rfft((line - line.mean()) * _hann(n)))
    return np.arange(amplitude.size) * (px_per_mm / n), amplitude


def _peak(freq: np.ndarray, amplitude: np.ndarray, low: float, high: float) -> tuple[float, float]:
    """(largest amplitude, its frequency) on low..high mm^-1; (0, nan) where no bin falls there."""
    start, stop = int(np.searchsorted(freq, low, side="left")), int(np.searchsorted(freq, high, side="right"))
    if stop <= start:
        return 0.0, math.nan
    best = start + int(np.argmax(amplitude[start:stop]))
    return float(amplitude[best]), float(freq[best])


def press_descriptors(strips: tuple[np.ndarray, np.ndarray], line: np.ndarray, px_per_mm: float, f_min: float,
                      f_max: float, ridge_period_mm: float | None = None) -> dict[str, float]:
    """The descriptors of one press (module docstring) and its orientation: ``strips`` as :func:`press_strips` gives
    them, ``line`` the gray line (gray 0-1) the spectrum read."""
    ridge_mm = ridge_period_mm or DEFAULT_RIDGE_PERIOD_MM
    freq, amplitude = line_spectrum(line, px_per_mm)
    floor = float(np.median(amplitude[freq >= f_min])) or 1e-12
    ridge_low, ridge_high = RIDGE_WINDOW[0] / ridge_mm, RIDGE_WINDOW[1] / ridge_mm
    band_high = min(f_max, ridge_low)  # the ridges' window is theirs, on either pad: "another pad" reads it
    band_peak, band_freq = _peak(freq, amplitude, f_min, band_high)
    _, ridge_freq = _peak(freq, amplitude, ridge_low, ridge_high)
    ridge_peak, _ = _peak(freq, amplitude, RIDGE_PEAK[0] / ridge_mm, RIDGE_PEAK[1] / ridge_mm)
    n = line.size
    ordered = np.partition(line, (n // 20, n - 1 - n // 20))
    values = {"peak_over_noise": band_peak / floor, "ridges_over_noise": ridge_peak / floor,
              "ridges_over_band": ridge_peak / band_peak if band_peak > 0 else math.nan,
              "ridge_period_mm": 1.0 / ridge_freq if ridge_freq > 0 else math.nan,
              "contrast_dn": float(ordered[n - 1 - n // 20] - ordered[n // 20]) * DN,
              "mean_dn": float(line.mean()) * DN}
    spaced, centre = strips
    values.update(_noise(centre))
    values["coherence"], _ = structure_tensor(centre)
    candidates = [line_shift_angle(spaced, band_freq / px_per_mm, ORIENTATION_STRIDE)]
    if ridge_period_mm:  # the ridges run along the grating's lines: the clearer phase of the two is read
        candidates.append(line_shift_angle(spaced, ridge_freq / px_per_mm, ORIENTATION_STRIDE))
    values["orientation_deg"] = min(candidates, key=lambda c: c[1] if math.isfinite(c[1]) else math.inf)[0]
    return values


def line_shift_angle(rows: np.ndarray, cycles_per_px: float, stride: int = 1) -> tuple[float, float]:
    """The grating lines' angle from the image columns (degrees, positive where they lean right going down): how far
    the grating's phase at its own frequency moves down ``rows`` (``stride`` px apart), one projection per row.

    A row shifted by s px multiplies that projection by exp(-2 pi i f s), so the least-squares slope of the unwrapped
    phase over the rows gives s per row = tan(angle), with the whole line's width behind each row (a structure
    tensor's angle over the same strip is noisier by far: every pixel's noise enters its gradients). Returns the
    angle and the phase's RMS residual about its line (radians): how clearly this frequency's phase moved.
    """
    if rows.shape[0] < 3 or not cycles_per_px > 0:
        return math.nan, math.nan
    x = (2 * np.pi * cycles_per_px) * np.arange(rows.shape[1], dtype=np.float32)
    window = _hann(rows.shape[1]).astype(np.float32)
    phase = np.unwrap(np.arctan2(-(rows @ (window * np.sin(x))), rows @ (window * np.cos(x))).astype(np.float64))
    depth = np.arange(phase.size) * float(stride)
    depth -= depth.mean()
    slope = float(depth @ phase) / float(depth @ depth)
    residual = phase - phase.mean() - slope * depth
    return math.degrees(math.atan(-slope / (2 * np.pi * cycles_per_px))), float(np.sqrt(np.mean(residual ** 2)))


def _noise(strip: np.ndarray) -> dict[str, float]:
    """Pixel noise from the rows' differences (the grating's lines run along the columns)."""
    if strip.shape[0] < 3:
        return {"noise_dn": math.nan, "noise_whiteness": math.nan}
    first = np.diff(strip, axis=0)
    second = np.diff(first, axis=0)
    var1 = float(np.mean(np.square(first - first.mean())))
    var2 = float(np.mean(np.square(second - second.mean())))
    return {"noise_dn": math.sqrt(var1 / 2) * DN, "noise_whiteness": var2 / var1 if var1 > 0 else math.nan}


def structure_tensor(strip: np.ndarray) -> tuple[float, float]:
    """(coherence 0-1, orientation in degrees) of the strip's structure tensor, averaged over the strip.

    Gradients are central differences of 2 x 2 block means, which halves the pixel noise each one carries while
    keeping a 3-8 mm grating's edges; orientation is the lines' angle from the image columns, positive clockwise.
    """
    if strip.shape[0] < 6 or strip.shape[1] < 6:  # 2 x 2 blocks, then a central difference each way
        return math.nan, math.nan
    h, w = strip.shape[0] // 2 * 2, strip.shape[1] // 2 * 2
    blocks = strip[0:h:2, 0:w:2] + strip[1:h:2, 0:w:2] + strip[0:h:2, 1:w:2] + strip[1:h:2, 1:w:2]  # 4 x the means
    gx = blocks[1:-1, 2:] - blocks[1:-1, :-2]
    gy = blocks[2:, 1:-1] - blocks[:-2, 1:-1]
    jxx, jyy, jxy = float(np.mean(gx * gx)), float(np.mean(gy * gy)), float(np.mean(gx * gy))
    total = jxx + jyy
    if total <= 0:
        return 0.0, math.nan
    coherence = math.hypot(jxx - jyy, 2 * jxy) / total
    return coherence, math.degrees(0.5 * math.atan2(2 * jxy, jxx - jyy))


