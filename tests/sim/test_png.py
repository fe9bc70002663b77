"""sim/png.py: the encoder settings frames are written with are lossless (every pixel decodes as it was)."""
from __future__ import annotations

import cv2
import numpy as np

from roughsense.sim.png import png_params


def test_frames_written_with_the_simulators_settings_decode_to_the_same_pixels(tmp_path):
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 256, (64, 300, 3), dtype=np.uint8)
    path = tmp_path / "frame.png"
    assert cv2.imwrite(str(path), frame, list(png_params()))
    np.testing.assert_array_equal(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), frame)
    assert path.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
