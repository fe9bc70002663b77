"""The smallest study folder the io tests write and read back: two specimens, one image each."""
from __future__ import annotations

import numpy as np
import pandas as pd

from roughsense.io.sensor_settings import SensorSettings
from roughsense.io.writer import StudyWriter


def write_minimal_study(root):
    writer = StudyWriter(root)
    writer.write_config(name="t", sensor=SensorSettings(px_per_mm=20.0, roi=(0, 0, 64, 8)))
    writer.write_specimens(pd.DataFrame({"specimen": ["R2", "R3"], "shape": ["rectangular"] * 2, "wavelength_mm": [2.0, 3.0]}))
    rows = []
    for specimen in ("R2", "R3"):
        rel = writer.write_image(f"{specimen}.png", np.full((8, 64), 128, np.uint8))
        rows.append({"image": rel, "specimen": specimen, "pad": "smooth", "force_n": 1.02, "repetition": 1})
    writer.write_manifest(pd.DataFrame(rows))
    return writer
