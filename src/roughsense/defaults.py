"""Every default a user can see, in one light module that the library and the command line both import.

It imports nothing, so ``roughsense COMMAND --help`` shows these values
without loading the numerics, and no default is written twice.
"""
from __future__ import annotations

#: Every random draw's seed unless --seed says otherwise.
SEED = 0
#: PLS components cross-validated at most.
MAX_COMPONENTS = 20
#: Specimen-level shufflings of the permutation control: p-values down to 0.005.
PERMUTATIONS = 199
#: The most shufflings allowed: their targets are held at once, one column per shuffling (10^9 of them ran out of
#: memory after half a minute), so more is refused before any work.
MAX_PERMUTATIONS = 10_000
#: An image with more pixels is refused before it is decoded.
MAX_PIXELS = 100_000_000
#: The paper's camera scale (349 px/cm), its centre crop (width, height) and the default region of interest.
PX_PER_MM = 34.9
CENTER_CROP_PX = (1900, 150)
ROI = "center"
#: The simulated fingerprint pad's ridges.
FINGERPRINT_PERIOD_MM = 1.0
RIDGE_HEIGHT_MM = 0.2
#: The simulated panel's ratings: the paper's values for its presets, the finger model for anything else.
RATINGS_FROM = "paper"
#: Rows of each simulated frame stored, centred on the sensor (0: whole frames).
STORED_HEIGHT_PX = 320
#: The spectrum (paper section 3.2): the band 0.1-1.0 mm^-1 at 45 evenly spaced frequencies, from one image row
#: (the paper reads one), with a Hann taper (the band's edges leak less; "none" is the paper's literal choice).
F_MIN_PER_MM = 0.1
F_MAX_PER_MM = 1.0
N_FREQS = 45
ROWS = 1
WINDOW = "hann"
#: The report figures' formats and resolution.
FIGURE_FORMATS = ("png", "svg", "pdf")
DPI = 110
