"""The spectrum's limits: the tapers the DFT accepts and the largest grid.

Its defaults (the paper's band and grid, the line, the taper; section 3.2) are :mod:`roughsense.defaults`', which
every entry point (``SpatialSpectrum``, ``spatial_spectrum``, ``frequency_grid``, the CLI's options) reads. A model
file keeps the values it was written with (one that predates the taper option was fitted with Hann, and is read so).
The camera's scale, the region of interest and the pixel limit are the study folder's ``[sensor]`` table
(:class:`roughsense.io.sensor_settings.SensorSettings`).
"""
from __future__ import annotations

#: Tapers the DFT accepts: Hann (the default: the band's edges leak less) or none (the paper's literal choice).
WINDOWS = ("hann", "none")
#: Most frequencies a grid may hold. A line of a few thousand pixels resolves about a hundred frequencies in the
#: paper's band, so 5000 oversamples it fifty-fold (a fine grid locates a peak); the DFT basis grows with the grid
#: (about 0.4 GB at 5000 frequencies on the paper's 1900 px line; 200,000 frequencies from a re-signed model file
#: took 24 GB), so a larger grid is refused before any image is read.
MAX_N_FREQS = 5000
