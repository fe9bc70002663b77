"""Image decoding and MATLAB-compatible grayscale: the only place that decodes image files.

Decoding goes through OpenCV (``imdecode`` releases the GIL, so a thread pool scales over files) and keeps
the file's bit depth, so 16-bit images are not silently reduced to 8 bits. Headers are read with Pillow,
which reads only the header. Failures become one :class:`~roughsense.errors.InputError` naming the file,
never a codec message on stderr.
"""
from __future__ import annotations

import contextlib
import io
import os
import threading
import zlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .. import defaults
from .._util.files import open_regular
from ..errors import InputError

#: MATLAB ``rgb2gray`` weights: the first row of the inverse NTSC (YIQ -> RGB) matrix, unrounded
#: (0.2989, 0.5870, 0.1140 to four places). They sum to 1, so a neutral RGB image equals its gray version.
GRAY_WEIGHTS_RGB = (0.298936021293775, 0.587043074451121, 0.114020904255103)

#: Largest image read, in pixels (width x height): a header claiming more is refused before decoding, so a
#: small file that inflates to gigabytes (a "decompression bomb") cannot exhaust memory. 100 Mpx is above
#: every camera a bench uses (the paper's is 2 Mpx); ``[sensor] max_pixels`` in study.toml changes it. Its home is
#: :data:`roughsense.defaults.MAX_PIXELS`.
#: The highest pixel limit a study or option may set: OpenCV's decoders refuse images above 2**30 pixels anyway,
#: so a larger limit (``max_pixels = 1e300``) would only promise what no read can keep.
MAX_PIXELS_LIMIT = 2**30


class PixelLimitError(InputError):
    """An image above the pixel limit. The message says the size and the limit, never how to raise it: that is the
    command's to say (a study's ``[sensor] max_pixels``, ``features --max-pixels``; ``predict`` has no way), so no
    message advises an option the command at hand does not have."""


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_MODES = {0: "L", 2: "RGB", 6: "RGBA"}  # 8-bit colour types whose rows Pillow's "zip" decoder unpacks as they are
_PILLOW_GUARD = threading.Lock()  # Pillow's bomb limit is a module global: one read at a time lifts it
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


def _png_chunks(raw: memoryview) -> Iterator[tuple[memoryview, memoryview, int]]:
    """(type, body, stored CRC) of each chunk after the signature; stops at a chunk the file cuts short."""
    pos = len(_PNG_SIGNATURE)
    while pos + 12 <= len(raw):
        end = pos + 12 + int.from_bytes(raw[pos : pos + 4], "big")
        if end > len(raw):
            return
        yield raw[pos + 4 : pos + 8], raw[pos + 8 : end - 4], int.from_bytes(raw[end - 4 : end], "big")
        pos = end


def _png_is_complete(data: np.ndarray) -> bool:
    """Check every chunk's CRC, up to IEND.

    A truncated or corrupted file is refused here, before a decoder sees it: libpng would print its own
    message to stderr, and a decoder that stops early (see :func:`decode_png_top_rows`) would not notice
    damage below the rows it reads. The CRCs cost about 2 % of a full decode.
    """
    for kind, body, stored in _png_chunks(data.data):
        if zlib.crc32(body, zlib.crc32(kind)) != stored:
            return False
        if kind == b"IEND":
            return True
    return False


def max_file_bytes(max_pixels: int) -> int:
    """Largest image file read for a pixel limit: 8 bytes per pixel (16-bit RGBA, stored raw) plus 16 MB of headers
    and metadata. A bigger file cannot be an image within the limit, so it is refused before it is read whole."""
    return 8 * int(max_pixels) + (16 << 20)


def read_bytes(path: str | os.PathLike[str], *, max_pixels: int = defaults.MAX_PIXELS) -> np.ndarray:
    """The file's bytes, with the usual failures turned into one InputError naming the file."""
    path = Path(path)
    try:
        with os.fdopen(open_regular(path, what="image file"), "rb") as handle:  # a FIFO or a device: refused, no wait
            size = os.fstat(handle.fileno()).st_size
            if size > max_file_bytes(max_pixels):
                raise PixelLimitError(f"image file is {size / 1e6:.0f} MB, more than any image within the pixel "
                                      f"limit of {max_pixels / 1e6:.3g} Mpx can take", path=path)
            data = np.fromfile(handle, dtype=np.uint8)
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

    Pillow's ``Image.open`` reads the header and decodes nothing, so a file claiming billions of pixels costs
    nothing to inspect. Its own bomb guard refuses above 179 Mpx without giving the size, where ours is a setting
    (:func:`check_pixels`) and names it: only for such a file is Pillow's limit lifted, one read at a time, so
    another Pillow user in the process is left unguarded for no ordinary image. A PNG's size is read from its IHDR
    chunk without Pillow. Pillow's warnings (its bomb warning above 89 Mpx, odd metadata) are left to the process's
    warning filters: this runs in decode threads,
    which never touch those filters (``catch_warnings`` is not thread-safe: two at once can leave a filter
    behind for the rest of the process). The command line ignores Pillow's warnings once, in its main thread
    (``roughsense.cli.main``).
    """
    from PIL import Image

    head = bytes(data[:24])
    if head[:8] == _PNG_SIGNATURE and head[12:16] == b"IHDR":  # the size is in the first chunk: no Pillow, no warning
        return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    stream = io.BytesIO(data.data)
    try:
        return _pillow_size(stream)
    except Image.DecompressionBombError:
        with contextlib.suppress(Exception), _PILLOW_GUARD:
            saved, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
            try:
                return _pillow_size(stream)
            finally:
                Image.MAX_IMAGE_PIXELS = saved
    except Exception:  # not a format Pillow opens, or a damaged header
        pass
    return _tiff_size(stream)


def _pillow_size(stream: io.BytesIO) -> tuple[int, int]:
    from PIL import Image

    stream.seek(0)
    with Image.open(stream) as image:
        return image.size


def _tiff_size(stream: io.BytesIO) -> tuple[int, int] | None:
    """ImageWidth and ImageLength from a classic TIFF's first IFD (the page OpenCV decodes).

    For the pixel layouts OpenCV reads but Pillow does not open (float or int16 RGB, float64), so their size
    is still known before decoding.
    """
    from PIL import TiffImagePlugin

    header = stream.getbuffer()[:8].tobytes()
    if header[:4] not in (b"II*\x00", b"MM\x00*"):
        return None
    try:
        directory = TiffImagePlugin.ImageFileDirectory_v2(header)
        stream.seek(directory.next)
        directory.load(stream)
        return int(directory[256]), int(directory[257])
    except Exception:  # a damaged directory, or one without the two sizes
        return None


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
        raise PixelLimitError(f"image is {width} x {height} px ({width * height / 1e6:.3g} Mpx), above the limit of "
                              f"{max_pixels / 1e6:.3g} Mpx", path=path)
    _refuse_pages(data, path)
    return width, height


def _refuse_pages(data: np.ndarray, path) -> None:
    """A TIFF of several pages (a stack, a multi-exposure file) is refused: OpenCV would read its first page
    without a word, and which page is the press is not the reader's to guess."""
    from PIL import TiffImagePlugin

    head = data[:8].tobytes()
    if head[:4] not in (b"II*\x00", b"MM\x00*"):
        return
    try:
        directory = TiffImagePlugin.ImageFileDirectory_v2(head)
        stream = io.BytesIO(data.tobytes())
        stream.seek(directory.next)
        directory.load(stream)
        more = directory.next != 0
    except Exception:  # a damaged directory: the decoder's to report
        return
    if more:
        raise InputError("a TIFF of several pages: save the press as a single-page image (which page is the press "
                         "is not roughsense's to guess)", path=path)


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
    if bit_depth != 8 or colour_type not in _PNG_MODES or interlace != 0:
        return None
    return height, width


def decode_png_top_rows(data: np.ndarray, stop_row: int) -> np.ndarray | None:
    """Decode only rows [0, stop_row) of an eligible PNG (see :func:`png_size`); None if not possible.

    PNG rows are filtered against the row above, so decoding must start at the top, but it can stop at
    the last row the sensor uses: for the paper's centred crop that is half the inflate and unfilter work.
    Pillow's ``Image.frombytes`` with its PNG ("zip") decoder fills an image of the size it is given and
    stops there, so the compressed stream is passed whole and only the rows asked for are decoded.
    """
    from PIL import Image

    size = png_size(data)
    if size is None or not 0 < stop_row < size[0]:
        return None
    mode = _PNG_MODES[int(data[25])]
    stream = b"".join(body for kind, body, _ in _png_chunks(data.data) if kind == b"IDAT")
    try:
        pixels = np.asarray(Image.frombytes(mode, (size[1], stop_row), stream, "zip", mode))
    except (ValueError, OSError):  # the stream ends before those rows, or does not inflate: decode the usual way
        return None
    return pixels[:, :, :3] if pixels.ndim == 3 else pixels


def read_image(path: str | os.PathLike[str], *, max_pixels: int = defaults.MAX_PIXELS) -> np.ndarray:
    """Decode an image file to (H, W) gray or (H, W, 3) RGB in its own dtype (uint8, uint16 or float).

    The RGB array is a reversed-channel view of OpenCV's BGR buffer: no copy of the full frame.
    """
    return decode(read_bytes(path, max_pixels=max_pixels), path, max_pixels=max_pixels)


def decode(data: np.ndarray, path: str | os.PathLike[str] | None = None, *,
           max_pixels: int = defaults.MAX_PIXELS) -> np.ndarray:
    """Decode a whole encoded image with OpenCV (any format, 8 or 16 bit), after :func:`check_pixels`.

    The pixels as the sensor stored them: an EXIF orientation is ignored (OpenCV applies a JPEG's, not a PNG's), so
    the same frame gives the same rows, and the same spectrum, in every format.
    """
    check_pixels(data, max_pixels, path)
    cv2 = _opencv()
    try:
        image = cv2.imdecode(data, cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH | cv2.IMREAD_IGNORE_ORIENTATION)
    except cv2.error:
        image = None
    if image is None:
        raise InputError("not a readable image (expected PNG, JPEG, TIFF or BMP) or the file is corrupt", path=path)
    if image.ndim == 3:
        if image.shape[2] == 1:
            return image[:, :, 0]
        image = image[:, :, 2::-1]  # BGR(A) -> RGB, dropping alpha
    return image


def as_image(image, *, name: str | None = None, max_pixels: int = defaults.MAX_PIXELS) -> np.ndarray:
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
