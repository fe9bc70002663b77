"""Lower layers' defaults that the options show in --help, as literals.

Their home modules import NumPy (0.1 s), which ``roughsense COMMAND --help`` must not pay for; so the options
read them from here and tests/test_cli_style.py checks each equals its home's value.
"""
from __future__ import annotations

from ..paper import FINGERPRINT_PAD, SMOOTH_PAD  # no NumPy: paper.py reads its tables on first use

#: roughsense.io.images.DEFAULT_MAX_PIXELS
DEFAULT_MAX_PIXELS = 100_000_000
#: roughsense.io.sensor_settings: the paper's camera scale (349 px/cm), its crop and the default ROI.
DEFAULT_PX_PER_MM = 34.9
CENTER_CROP_PX = (1900, 150)
DEFAULT_ROI = "center"
#: roughsense.analysis.controls.MAX_PERMUTATIONS
MAX_PERMUTATIONS = 10_000
#: roughsense.sim.pads
DEFAULT_FINGERPRINT_PERIOD_MM = 1.0
DEFAULT_RIDGE_HEIGHT_MM = 0.2
PAD_NAMES = (SMOOTH_PAD, FINGERPRINT_PAD)
