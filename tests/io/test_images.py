"""io/images.py: what is refused before decoding (issue 44: a multi-page TIFF was read from its first page unsaid)."""
from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from roughsense.errors import InputError
from roughsense.io.images import check_pixels, decode, read_image


def _tiff(pages: int, byteorder: str = "<") -> bytes:
    frames = [Image.fromarray(np.full((40, 60), 30 * i, np.uint8)) for i in range(pages)]
    buffer = io.BytesIO()
    frames[0].save(buffer, format="TIFF", save_all=True, append_images=frames[1:], tiffinfo={})
    return buffer.getvalue()


@pytest.mark.parametrize("pages", [2, 5])
def test_a_tiff_of_several_pages_is_refused_naming_the_file(tmp_path, pages):
    path = tmp_path / "stack.tif"
    path.write_bytes(_tiff(pages))
    with pytest.raises(InputError, match="several pages") as raised:
        read_image(path)
    assert str(raised.value).startswith(str(path))
    with pytest.raises(InputError, match="several pages"):
        check_pixels(np.frombuffer(path.read_bytes(), np.uint8), 10**6, path)


def test_a_single_page_tiff_is_read_as_before(tmp_path):
    path = tmp_path / "one.tif"
    path.write_bytes(_tiff(1))
    assert read_image(path).shape == (40, 60)
    assert decode(np.frombuffer(path.read_bytes(), np.uint8)).shape == (40, 60)


def test_the_cli_refuses_a_stack_in_one_line(run_cli, tmp_path):
    path = tmp_path / "stack.tif"
    path.write_bytes(_tiff(3))
    code, out, err = run_cli("features", path, "--out", tmp_path / "f.csv", "--roi", "0,0,60,40", "--px-per-mm", "10")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "stack.tif" in lines[0] and "several pages" in lines[0], err
    assert not (tmp_path / "f.csv").exists()


def test_a_jpeg_exif_orientation_does_not_rotate_the_pixels(tmp_path):
    """Also seen: a JPEG with EXIF orientation 6 was rotated while the same pixels in a PNG (eXIf chunk) were not."""
    import numpy as np
    from PIL import Image

    from roughsense.io.images import read_image

    rng = np.random.default_rng(0)
    pixels = np.repeat(np.repeat(rng.integers(0, 256, (12, 20), dtype=np.uint8), 8, axis=0), 8, axis=1)  # 96 x 160
    exif = Image.Exif()
    exif[0x0112] = 6  # rotate 90 degrees clockwise to display
    Image.fromarray(pixels).save(tmp_path / "a.jpg", quality=100, exif=exif)
    Image.fromarray(pixels).save(tmp_path / "a.png", exif=exif)
    jpeg, png = read_image(tmp_path / "a.jpg"), read_image(tmp_path / "a.png")
    assert jpeg.shape == png.shape == pixels.shape
    np.testing.assert_array_equal(png, pixels)
    assert np.abs(jpeg.astype(int) - pixels).mean() < 2  # the same picture, to JPEG's loss
