"""io/sensor_settings.py: the [sensor] table's values are bounded as OpenCV and the sensor can use them."""
from __future__ import annotations

import pytest

from roughsense.errors import InputError, RoughsenseError
from roughsense.io.sensor_settings import parse_roi
from roughsense.io.study import read_study


@pytest.mark.parametrize("value", ["1e300", "1073741825", "2e9"])
def test_a_pixel_limit_beyond_what_opencv_decodes_is_refused(tiny_copy, value):
    """28.16: ``[sensor] max_pixels = 1e300`` was accepted."""
    toml = tiny_copy / "study.toml"
    toml.write_text(toml.read_text().replace("[sensor]\n", f"[sensor]\nmax_pixels = {value}\n"))
    with pytest.raises(InputError, match=r"\[sensor\] max_pixels must be a whole number of pixels from 1 to 1073741824"):
        read_study(tiny_copy)


@pytest.mark.parametrize(
    "text, expected",
    [("center", "center"), ("auto", "auto"), ("10,20,300,40", (10, 20, 300, 40)), ([0, 0, 5, 5], (0, 0, 5, 5))],
)
def test_parse_roi(text, expected):
    assert parse_roi(text) == expected


@pytest.mark.parametrize("text", ["1,2,3", "a,b,c,d", "0,0,0,5", "-1,0,5,5", "1.5,0,5,5"])
def test_parse_roi_rejects(text):
    with pytest.raises(RoughsenseError):
        parse_roi(text)
