"""Image decoding and MATLAB-compatible grayscale: the only place that touches image files.

Decoding goes through OpenCV (``imdecode`` releases the GIL, so a thread pool scales over files) and keeps
the file's bit depth, so 16-bit images are not silently reduced to 8 bits. Failures become one
:class:`~roughsense.errors.InputError` naming the file, never a codec message on stderr.
"""
from __future__ import annotations

import os
import zlib
from pathlib import Path

import numpy as np

from .errors import InputError

#: MATLAB ``rgb2gray`` weights: the first row of the inverse NTSC (YIQ -> RGB) matrix, unrounded
#: (0.2989, 0.5870, 0.1140 to four places). They sum to 1, so a neutral RGB image equals its gray version.
GRAY_WEIGHTS_RGB = (0.298936021293775, 0.587043074451121, 0.114020904255103)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_cv2 = None


def _opencv():
    """Import OpenCV once and silence its logger: the CLI's one-line error is the only message."""
    global _cv2
    if _cv2 is None:
        import cv2

        try:
            cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
        except AttributeError:  # very old builds without the logging module
            pass
        _cv2 = cv2
    return _cv2


def _png_is_complete(data: np.ndarray) -> bool:
    """Walk the PNG chunk list and check every chunk's CRC.

    A truncated or corrupted file is refused here, before a decoder sees it: libpng would print its own
    message to stderr, and a decoder that stops early (see :func:`decode_png_top_rows`) would not notice
    damage below the rows it reads. The CRCs cost about 2 % of a full decode.
    """
    raw = data.data
    size = len(raw)
    pos = len(_PNG_SIGNATURE)
    while pos + 12 <= size:
        length = int.from_bytes(raw[pos : pos + 4], "big")
        end = pos + 12 + length
        if end > size:
            return False
        stored = int.from_bytes(raw[end - 4 : end], "big")
        if zlib.crc32(raw[pos + 4 : end - 4]) != stored:
            return False
        if bytes(raw[pos + 4 : pos + 8]) == b"IEND":
            return True
        pos = end
    return False


def read_bytes(path: str | os.PathLike[str]) -> np.ndarray:
    """The file's bytes, with the usual failures turned into one InputError naming the file."""
    path = Path(path)
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except FileNotFoundError:
        raise InputError("image file not found", path=path) from None
    except IsADirectoryError:
        raise InputError("is a folder, expected an image file", path=path) from None
    except OSError as exc:
        raise InputError(f"cannot read image: {exc.strerror or exc}", path=path) from None
    if data.size == 0:
        raise InputError("image file is empty", path=path)
    if bytes(data[: len(_PNG_SIGNATURE)]) == _PNG_SIGNATURE and not _png_is_complete(data):
        raise InputError("PNG file is truncated or corrupt (a chunk is cut short or fails its CRC)", path=path)
    return data


def png_size(data: np.ndarray) -> tuple[int, int] | None:
    """(height, width) from a PNG's IHDR if the top rows alone can be decoded, else None.

    Only 8-bit gray, RGB and RGBA PNGs without interlacing qualify: their rows are stored top to
    bottom, so the rows above the contact line can be decoded without the rest of the frame.
    """
    head = bytes(data[:33])
    if len(head) < 33 or head[:8] != _PNG_SIGNATURE or head[12:16] != b"IHDR":
        return None
    width, height = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    bit_depth, colour_type, interlace = head[24], head[25], head[28]
    if bit_depth != 8 or colour_type not in (0, 2, 6) or interlace != 0:
        return None
    return height, width


def decode_png_top_rows(data: np.ndarray, stop_row: int) -> np.ndarray | None:
    """Decode only rows [0, stop_row) of an eligible PNG (see :func:`png_size`); None if not possible.

    PNG rows are filtered against the row above, so decoding must start at the top, but it can stop at
    the last row the sensor uses: for the paper's centred crop that is half the inflate and unfilter work.
    Pillow's decoder fills exactly the tile it is given, which is what makes the early stop possible.
    """
    import io

    from PIL import Image

    try:
        with Image.open(io.BytesIO(data.data)) as image:
            width, height = image.size
            if stop_row >= height or len(image.tile) != 1:
                return None
            tile = image.tile[0]
            image._size = (width, stop_row)
            extents = (0, 0, width, stop_row)
            image.tile = [tile._replace(extents=extents) if hasattr(tile, "_replace") else (tile[0], extents, *tile[2:])]
            image.load()
            pixels = np.asarray(image)
    except Exception:  # any surprise (a Pillow without these internals, an odd file): decode the usual way
        return None
    if pixels.shape[:2] != (stop_row, width):
        return None
    if pixels.ndim == 3:
        pixels = pixels[:, :, :3]
    return pixels


def read_image(path: str | os.PathLike[str]) -> np.ndarray:
    """Decode an image file to (H, W) gray or (H, W, 3) RGB in its own dtype (uint8, uint16 or float).

    The RGB array is a reversed-channel view of OpenCV's BGR buffer: no copy of the full frame.
    """
    return decode(read_bytes(path), path)


def decode(data: np.ndarray, path: str | os.PathLike[str] | None = None) -> np.ndarray:
    """Decode a whole encoded image with OpenCV (any format, 8 or 16 bit)."""
    cv2 = _opencv()
    image = cv2.imdecode(data, cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH)
    if image is None:
        raise InputError("not a readable image (expected PNG, JPEG, TIFF or BMP) or the file is corrupt", path=path)
    if image.ndim == 3:
        if image.shape[2] == 1:
            return image[:, :, 0]
        image = image[:, :, 2::-1]  # BGR(A) -> RGB, dropping alpha
    return image


def as_image(image, *, name: str | None = None) -> np.ndarray:
    """Accept a path or an array and return a decoded (H, W) or (H, W, 3) array; arrays are checked, not copied."""
    if isinstance(image, (str, os.PathLike)):
        return read_image(image)
    array = np.asarray(image)
    where = name or "image array"
    if array.ndim == 3 and array.shape[2] == 1:
        array = array[:, :, 0]
    elif array.ndim == 3 and array.shape[2] == 4:
        array = array[:, :, :3]
    if not (array.ndim == 2 or (array.ndim == 3 and array.shape[2] == 3)):
        raise InputError(f"{where}: expected shape (H, W) or (H, W, 3), got {array.shape}")
    if array.dtype == bool or not (np.issubdtype(array.dtype, np.integer) or np.issubdtype(array.dtype, np.floating)):
        raise InputError(f"{where}: expected an integer or float image, got dtype {array.dtype}")
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise InputError(f"{where}: image is empty ({array.shape})")
    return array


def intensity_scale(dtype: np.dtype) -> float:
    """Full scale of a pixel type: 8- and 16-bit images map to [0, 1]; floats are taken as they are."""
    dtype = np.dtype(dtype)
    if dtype == np.uint8:
        return 255.0
    if dtype == np.uint16:
        return 65535.0
    return 1.0


def to_gray(pixels: np.ndarray) -> np.ndarray:
    """MATLAB rgb2gray weights, in float64 and without MATLAB's rounding back to the input type."""
    scale = intensity_scale(pixels.dtype)
    if pixels.ndim == 2:
        gray = pixels.astype(np.float64)
    else:
        r, g, b = GRAY_WEIGHTS_RGB
        gray = r * pixels[..., 0].astype(np.float64)
        gray += g * pixels[..., 1]
        gray += b * pixels[..., 2]
    if scale != 1.0:
        gray /= scale
    return gray


def load_gray(image) -> np.ndarray:
    """Decode (if a path) and convert the whole image to gray, float64, 8/16-bit intensities scaled to [0, 1]."""
    gray = to_gray(as_image(image))
    if not np.all(np.isfinite(gray)):
        raise InputError("image contains NaN or infinite values", path=image if isinstance(image, (str, os.PathLike)) else None)
    return gray
