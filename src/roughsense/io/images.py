"""Image decoding and MATLAB-compatible grayscale: the only place that decodes image files.

Decoding goes through OpenCV (``imdecode`` releases the GIL, so a thread pool scales over files) and keeps
the file's bit depth, so 16-bit images are not silently reduced to 8 bits. Failures become one
:class:`~roughsense.errors.InputError` naming the file, never a codec message on stderr.
"""
from __future__ import annotations

import contextlib
import os
import zlib
from pathlib import Path

import numpy as np

from ..errors import InputError

#: MATLAB ``rgb2gray`` weights: the first row of the inverse NTSC (YIQ -> RGB) matrix, unrounded
#: (0.2989, 0.5870, 0.1140 to four places). They sum to 1, so a neutral RGB image equals its gray version.
GRAY_WEIGHTS_RGB = (0.298936021293775, 0.587043074451121, 0.114020904255103)

#: Largest image read, in pixels (width x height): a header claiming more is refused before decoding, so a
#: small file that inflates to gigabytes (a "decompression bomb") cannot exhaust memory. 100 Mpx is above
#: every camera a bench uses (the paper's is 2 Mpx); ``[sensor] max_pixels`` in study.toml changes it.
DEFAULT_MAX_PIXELS = 100_000_000
#: The highest pixel limit a study or option may set: OpenCV's decoders refuse images above 2**30 pixels anyway,
#: so a larger limit (``max_pixels = 1e300``) would only promise what no read can keep.
MAX_PIXELS_LIMIT = 2**30


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_cv2 = None


def _opencv():
    """Import OpenCV once and silence its logger: the CLI's one-line error is the only message."""
    global _cv2
    if _cv2 is None:
        import cv2

        with contextlib.suppress(AttributeError):  # very old builds have no logging module
            cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
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


def max_file_bytes(max_pixels: int) -> int:
    """Largest image file read for a pixel limit: 8 bytes per pixel (16-bit RGBA, stored raw) plus 16 MB of headers
    and metadata. A bigger file cannot be an image within the limit, so it is refused before it is read whole."""
    return 8 * int(max_pixels) + (16 << 20)


def read_bytes(path: str | os.PathLike[str], *, max_pixels: int = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """The file's bytes, with the usual failures turned into one InputError naming the file."""
    path = Path(path)
    try:
        size = os.stat(path).st_size
        if size > max_file_bytes(max_pixels):
            raise InputError(f"image file is {size / 1e6:.0f} MB, more than any image within the pixel limit of "
                             f"{max_pixels / 1e6:.3g} Mpx can take; raise [sensor] max_pixels if it is genuine",
                             path=path)
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


def header_size(data: np.ndarray) -> tuple[int, int] | None:
    """(width, height) in pixels from the file's header alone, or None if the format is not recognised.

    Parsed by hand for PNG (IHDR), JPEG (the SOF marker), TIFF (the first IFD, the page OpenCV decodes) and
    BMP; any other format is asked of Pillow, whose ``Image.open`` reads only the header. Nothing is decoded,
    so a file claiming billions of pixels costs nothing to inspect.
    """
    raw = bytes(data[:32])
    if raw[:8] == _PNG_SIGNATURE:
        if len(raw) < 24 or raw[12:16] != b"IHDR":
            return None
        return int.from_bytes(raw[16:20], "big"), int.from_bytes(raw[20:24], "big")
    if raw[:2] == b"\xff\xd8":
        return _jpeg_size(data)
    if raw[:4] in (b"II*\x00", b"MM\x00*"):
        return _tiff_size(data)
    if raw[:2] == b"BM" and len(raw) >= 26:
        header_bytes = int.from_bytes(raw[14:18], "little")
        if header_bytes == 12:  # OS/2 BITMAPCOREHEADER: 16-bit sizes
            return int.from_bytes(raw[18:20], "little"), int.from_bytes(raw[20:22], "little")
        width = int.from_bytes(raw[18:22], "little", signed=True)
        height = int.from_bytes(raw[22:26], "little", signed=True)
        return abs(width), abs(height)  # a negative height is a top-down bitmap
    return _pillow_size(data)


def _jpeg_size(data: np.ndarray) -> tuple[int, int] | None:
    """Walk the JPEG markers up to the first start-of-frame (SOF0..SOF15 but DHT, JPG, DAC)."""
    raw = data.data
    size = len(raw)
    pos = 2
    while pos + 4 <= size:
        if raw[pos] != 0xFF:
            return None
        marker = raw[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker in (0x01, *range(0xD0, 0xD8)):  # markers without a length
            pos += 2
            continue
        length = int.from_bytes(raw[pos + 2 : pos + 4], "big")
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            if pos + 9 > size:
                return None
            height = int.from_bytes(raw[pos + 5 : pos + 7], "big")
            width = int.from_bytes(raw[pos + 7 : pos + 9], "big")
            return width, height
        if marker == 0xDA or length < 2:  # start of scan before any frame header: not a JPEG we know
            return None
        pos += 2 + length
    return None


def _tiff_size(data: np.ndarray) -> tuple[int, int] | None:
    """ImageWidth (256) and ImageLength (257) from the first IFD of a classic TIFF."""
    raw = data.data
    order = "little" if bytes(raw[:2]) == b"II" else "big"
    size = len(raw)
    offset = int.from_bytes(raw[4:8], order)
    if offset + 2 > size:
        return None
    count = int.from_bytes(raw[offset : offset + 2], order)
    width = height = None
    for k in range(count):
        entry = offset + 2 + 12 * k
        if entry + 12 > size:
            return None
        tag = int.from_bytes(raw[entry : entry + 2], order)
        kind = int.from_bytes(raw[entry + 2 : entry + 4], order)
        if tag in (256, 257):
            value = int.from_bytes(raw[entry + 8 : entry + 10], order) if kind == 3 else int.from_bytes(
                raw[entry + 8 : entry + 12], order)
            if tag == 256:
                width = value
            else:
                height = value
    return (width, height) if width is not None and height is not None else None


def _pillow_size(data: np.ndarray) -> tuple[int, int] | None:
    import io
    import warnings

    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # Pillow's own DecompressionBombWarning: our limit decides
            with Image.open(io.BytesIO(data.data)) as image:
                return tuple(image.size)
    except Image.DecompressionBombError:  # more than twice Pillow's limit (about 179 Mpx)
        return _HUGE
    except Exception:  # not a format Pillow knows, or a damaged header
        return None


_HUGE = (1 << 31, 1 << 31)  # "larger than any limit": Pillow refused to report the size


def check_pixels(data: np.ndarray, max_pixels: int, path: str | os.PathLike[str] | None = None) -> tuple[int, int]:
    """Refuse an image whose header claims more than ``max_pixels`` pixels, before anything is decoded.

    Returns (width, height). An image whose size cannot be read from its header is refused too: decoding it
    would be the very risk this check exists to bound.
    """
    size = header_size(data)
    if size is None:
        raise InputError("not a readable image (expected PNG, JPEG, TIFF or BMP) or its header is damaged", path=path)
    width, height = size
    if width < 1 or height < 1:
        raise InputError(f"image header gives an empty size ({width} x {height} px)", path=path)
    if width * height > max_pixels:
        raise InputError(
            f"image is {width} x {height} px ({width * height / 1e6:.3g} Mpx), above the limit of "
            f"{max_pixels / 1e6:.3g} Mpx; raise [sensor] max_pixels in study.toml (or --max-pixels) if it is genuine",
            path=path,
        )
    return width, height


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


def read_image(path: str | os.PathLike[str], *, max_pixels: int = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """Decode an image file to (H, W) gray or (H, W, 3) RGB in its own dtype (uint8, uint16 or float).

    The RGB array is a reversed-channel view of OpenCV's BGR buffer: no copy of the full frame.
    """
    return decode(read_bytes(path, max_pixels=max_pixels), path, max_pixels=max_pixels)


def decode(data: np.ndarray, path: str | os.PathLike[str] | None = None, *,
           max_pixels: int = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """Decode a whole encoded image with OpenCV (any format, 8 or 16 bit), after :func:`check_pixels`."""
    check_pixels(data, max_pixels, path)
    cv2 = _opencv()
    try:
        image = cv2.imdecode(data, cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH)
    except cv2.error:
        image = None
    if image is None:
        raise InputError("not a readable image (expected PNG, JPEG, TIFF or BMP) or the file is corrupt", path=path)
    if image.ndim == 3:
        if image.shape[2] == 1:
            return image[:, :, 0]
        image = image[:, :, 2::-1]  # BGR(A) -> RGB, dropping alpha
    return image


def as_image(image, *, name: str | None = None, max_pixels: int = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """Accept a path or an array and return a decoded (H, W) or (H, W, 3) array; arrays are checked, not copied."""
    if isinstance(image, (str, os.PathLike)):
        return read_image(image, max_pixels=max_pixels)
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
