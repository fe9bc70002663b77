"""The sensor's defaults in one place: the paper's band and grid, the line, the taper (section 3.2).

Every entry point (``SpatialSpectrum``, ``spatial_spectrum``, ``frequency_grid``, the CLI's options) takes its
default from :data:`SPECTRUM_DEFAULTS`, so the paper's choices are written once. A model file keeps the values it
was written with (one that predates the taper option was fitted with Hann, and is read so).
The camera's scale, the region of interest and the pixel limit are the study folder's ``[sensor]`` table
(:class:`roughsense.io.sensor_settings.SensorSettings`).
"""
from __future__ import annotations

from dataclasses import dataclass

#: Tapers the DFT accepts: Hann (our default: the band's edges leak less) or none (the paper's literal choice).
WINDOWS = ("hann", "none")


@dataclass(frozen=True)
class SpectrumDefaults:
    """How a gray line becomes the model's features when nobody says otherwise."""

    f_min_per_mm: float = 0.1  # the paper's band, 0.1-1.0 mm^-1 ...
    f_max_per_mm: float = 1.0
    n_freqs: int = 45  # ... sampled at 45 evenly spaced frequencies
    rows: int = 1  # image rows averaged into the line (the paper reads one row)
    window: str = "hann"


SPECTRUM_DEFAULTS = SpectrumDefaults()
#: Most frequencies a grid may hold. A line of a few thousand pixels resolves about a hundred frequencies in the
#: paper's band, so 5000 oversamples it fifty-fold (a fine grid locates a peak); the DFT basis grows with the grid
#: (about 0.4 GB at 5000 frequencies on the paper's 1900 px line; 200,000 frequencies from a re-signed model file
#: took 24 GB), so a larger grid is refused before any image is read.
MAX_N_FREQS = 5000
