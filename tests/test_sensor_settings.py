"""io/sensor_settings.py: the [sensor] table's values are bounded as OpenCV and the sensor can use them."""
from __future__ import annotations

import pytest

from roughsense.errors import InputError
from roughsense.io.study import read_study


@pytest.mark.parametrize("value", ["1e300", "1073741825", "2e9"])
def test_a_pixel_limit_beyond_what_opencv_decodes_is_refused(tiny_copy, value):
    """28.16: ``[sensor] max_pixels = 1e300`` was accepted."""
    toml = tiny_copy / "study.toml"
    toml.write_text(toml.read_text().replace("[sensor]\n", f"[sensor]\nmax_pixels = {value}\n"))
    with pytest.raises(InputError, match=r"\[sensor\] max_pixels must be a whole number of pixels from 1 to 1073741824"):
        read_study(tiny_copy)
