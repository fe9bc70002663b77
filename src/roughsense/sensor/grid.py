"""The frequency grid every spectrum is evaluated on, and the DFT evaluated exactly on it (the paper's section 3.2).

A gray line becomes a spectrum here: remove its mean, taper it, take the amplitude of its DFT at each grid frequency
and normalise to unit area over mm^-1. The settings' constraints live here too, for the grid and the single-image
plan (:mod:`.line`) both check against them.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .. import defaults
from .._util.checks import POSITIVE, Described, Integer, Options, check_params
from ..errors import ConfigError, InputError
from .settings import MAX_N_FREQS, WINDOWS

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


def frequency_grid(
    f_min_per_mm: float = defaults.F_MIN_PER_MM,
    f_max_per_mm: float = defaults.F_MAX_PER_MM,
    n_freqs: int = defaults.N_FREQS,
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


def line_amplitude(line, *, px_per_mm: float, freq_per_mm, window: str = defaults.WINDOW) -> np.ndarray:
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
