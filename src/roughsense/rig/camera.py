"""Frames from anything OpenCV's VideoCapture opens: a camera index, a video file or an image sequence.

A file or an image sequence stands in for the camera, which is what makes capture testable without a
bench. Frames are returned as RGB (the convention of :meth:`StudyWriter.write_image` and of the sensor).

Stale frames: a camera driver queues a few frames, so the frame returned by ``read()`` right after the
operator has set the force can show the pad *before* the force was reached. :meth:`FrameSource.read_fresh`
therefore drops ``discard`` queued frames first. A file has no stale frames (every frame is the next
piece of the recording), so the default drops frames only for live devices.
"""
from __future__ import annotations

import contextlib
import os
import re
import stat
import sys
import tempfile
import warnings
from pathlib import Path

import cv2
import numpy as np

from .. import defaults
from .._util.files import kind_of, open_regular
from ..errors import ConfigError, InputError, RoughsenseWarning
from ..io.images import header_size

#: Frames dropped before a capture on a live device: V4L2 queues 4 buffers by default, plus the one in flight.
DEVICE_DISCARD = 5

#: Damaged frames skipped in a row before the source is refused: a glitch is dropped, a broken stream is not.
MAX_DAMAGED_FRAMES = 5

_STREAM = re.compile(r"^[a-z][a-z0-9+.-]*://", re.IGNORECASE)
_FFMPEG_PREFIX = re.compile(r"^\[(\w+) @ 0x[0-9a-f]+\]\s*")


@contextlib.contextmanager
def _quiet_opencv():
    """OpenCV logs failed opens to stderr; the CLI's one-line error is the only message we want."""
    logging = getattr(getattr(cv2, "utils", None), "logging", None)
    if logging is None:
        yield
        return
    previous = logging.getLogLevel()
    logging.setLogLevel(logging.LOG_LEVEL_SILENT)
    try:
        yield
    finally:
        logging.setLogLevel(previous)


@contextlib.contextmanager
def _decoder_messages():
    """OpenCV quiet, and what its codecs print on file descriptor 2 caught as a list of lines.

    ffmpeg and libjpeg write below Python, straight to fd 2: uncaught, they are stray "[mjpeg @ 0x...]" lines
    on the user's terminal and the frame they describe is kept as data. Caught, the frame is known to be damaged.
    """
    messages: list[str] = []
    with _quiet_opencv(), tempfile.TemporaryFile() as sink:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(sink.fileno(), 2)
        try:
            yield messages
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            text = sink.read(4096).decode("utf-8", errors="replace")
            messages.extend(_FFMPEG_PREFIX.sub(r"\1: ", line.strip()) for line in text.splitlines() if line.strip())


def _describe(spec: str | int) -> tuple[str | int, bool]:
    """(argument for VideoCapture, is it a live device?)."""
    if isinstance(spec, int):
        return spec, True
    text = str(spec).strip()
    if text.isdigit():
        return int(text), True
    if text.startswith("/dev/") or _STREAM.match(text):
        return text, True
    return text, False


class FrameSource:
    """One open video source. Use as a context manager; frames are (H, W, 3) uint8 RGB."""

    def __init__(self, spec: str | int, *, discard: int | None = None, max_pixels: int = defaults.MAX_PIXELS) -> None:
        target, self.is_device = _describe(spec)
        self.name = str(spec)
        self.max_pixels = int(max_pixels)
        if discard is None:
            discard = DEVICE_DISCARD if self.is_device else 0
        if discard < 0:
            raise ConfigError(f"frames to discard must be >= 0, got {discard}")
        self.discard = int(discard)
        if not self.is_device and "%" not in str(target) and not Path(target).exists():
            raise InputError("video source not found (expected a camera index, a video file or an image pattern)",
                             path=self.name)
        if not self.is_device and "%" not in str(target):
            os.close(open_regular(target, what="video file"))  # a FIFO would hang OpenCV's open
        elif not self.is_device:
            _check_sequence(str(target))  # and a FIFO among a sequence's files its read of that frame
        if not self.is_device:
            _check_image_header(str(target), self.max_pixels, self.name)  # before OpenCV decodes a frame of it
        with _decoder_messages() as messages:
            self._cap = cv2.VideoCapture(target)
            opened = self._cap.isOpened()
        if not opened:
            self._cap.release()
            why = f": {_said(messages)}" if messages else ""
            raise InputError(f"cannot open video source (OpenCV VideoCapture refused it{why})", path=self.name)
        if self.is_device:
            # Not every backend honours this; the explicit discard covers the others.
            self._cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
        self.frames_read = 0
        self._check_size(int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))

    def _check_size(self, width: int, height: int) -> None:
        """Refuse frames above ``max_pixels`` (the source's stated size, then each decoded frame's)."""
        if width * height > self.max_pixels:
            self.close()
            raise InputError(f"frames are {width} x {height} px ({width * height / 1e6:.3g} Mpx), above the limit of "
                             f"{self.max_pixels / 1e6:.3g} Mpx; raise [sensor] max_pixels in study.toml if it is genuine",
                             path=self.name)

    # ------------------------------------------------------------------ reading

    def grab(self) -> bool:
        """Advance one frame without decoding it to an array (cheap way to drop a frame; a damaged one is dropped)."""
        with _decoder_messages():
            ok = bool(self._cap.grab())
        if ok:
            self.frames_read += 1
        return ok

    def read_next(self) -> np.ndarray | None:
        """The next frame that decodes cleanly, or None at the end of a file or sequence.

        A frame the decoder reports errors for is never handed on as data: it is skipped with a warning naming
        it; :data:`MAX_DAMAGED_FRAMES` in a row, or a frame that does not decode at all, is an InputError.
        """
        for _ in range(MAX_DAMAGED_FRAMES):
            with _decoder_messages() as messages:
                ok, frame = self._cap.read()
            if not ok or frame is None or frame.size == 0:
                if messages:
                    raise InputError(f"frame {self.frames_read + 1} does not decode ({_said(messages)})",
                                     path=self.name)
                return None
            self.frames_read += 1
            self._check_size(frame.shape[1], frame.shape[0])
            if not messages:
                return _to_rgb(frame)
            warnings.warn(RoughsenseWarning(f"{self.name}: frame {self.frames_read} decoded with errors "
                                            f"({_said(messages)}); skipped"), stacklevel=2)
        raise InputError(f"{MAX_DAMAGED_FRAMES} frames in a row decoded with errors, up to frame {self.frames_read} "
                         f"({_said(messages)})", path=self.name)

    def read_fresh(self) -> np.ndarray:
        """Drop the queued (stale) frames, then return the next one; a source that yields nothing is an error."""
        for _ in range(self.discard):
            if not self.grab():
                break
        frame = self.read_next()
        if frame is None:
            where = "at its end" if not self.is_device else "no frame delivered"
            raise InputError(f"video source yielded no frame ({where}, after {self.frames_read} frame(s))",
                             path=self.name)
        return frame

    def __iter__(self):
        while (frame := self.read_next()) is not None:
            yield frame

    # ------------------------------------------------------------------ lifetime

    def close(self) -> None:
        self._cap.release()

    def __enter__(self) -> FrameSource:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        kind = "device" if self.is_device else "file"
        return f"FrameSource({self.name!r}, {kind}, discard={self.discard})"


#: Bytes read of an image source to find its size in its header (a JPEG's size may follow 64 kB of EXIF).
_HEADER_BYTES = 1 << 20


def _check_image_header(target: str, max_pixels: int, name: str) -> None:
    """An image file (or a pattern's first image) whose header states more than ``max_pixels``: refused unread.

    A video file's header is not an image's: its size is checked once opened (``CAP_PROP_FRAME_*``).
    """
    paths = [target] if "%" not in target else [_pattern_file(target, i) for i in (0, 1)]
    path = next((Path(p) for p in paths if p is not None and Path(p).is_file()), None)
    if path is None:
        return
    try:
        with os.fdopen(open_regular(path, what="image file"), "rb") as handle:  # never a FIFO swapped in since
            head = np.frombuffer(handle.read(_HEADER_BYTES), np.uint8)
    except OSError:
        return  # OpenCV names the problem
    size = header_size(head)
    if size is not None and size[0] * size[1] > max_pixels:
        raise InputError(f"image is {size[0]} x {size[1]} px ({size[0] * size[1] / 1e6:.3g} Mpx), above the limit of "
                         f"{max_pixels / 1e6:.3g} Mpx; raise [sensor] max_pixels in study.toml if it is genuine",
                         path=name if path == Path(target) else path)


#: Most files of an image sequence checked before OpenCV reads it (hours of frames at a camera's rate).
MAX_SEQUENCE_FILES = 1_000_000


def _check_sequence(pattern: str) -> None:
    """Each file of the image sequence ``pattern`` is a regular file (else :class:`InputError` naming it).

    OpenCV counts a sequence's files as they exist from index 0 (or 1) up, then opens each by name when its frame
    is read: a FIFO among them would block that read for good. So every one is checked first, as OpenCV will find
    them (following links); a file swapped in afterwards is OpenCV's to open.
    """
    for index in range(MAX_SEQUENCE_FILES):
        name = _pattern_file(pattern, index)
        if name is None:
            return
        try:
            mode = os.stat(name).st_mode
        except OSError:
            if index == 0:
                continue  # a sequence may start at 1
            return
        if not stat.S_ISREG(mode):
            raise InputError(f"is {kind_of(mode)}, not a regular image file; give the image file itself", path=name)


def _pattern_file(pattern: str, index: int) -> str | None:
    try:
        return pattern % index
    except (TypeError, ValueError):
        return None


def _said(messages: list[str]) -> str:
    """The decoder's first messages as one short clause of an error or warning line."""
    text = "; ".join(messages[:2])
    return text if len(text) <= 160 else text[:157] + "..."


def _to_rgb(frame: np.ndarray) -> np.ndarray:
    """RGB as a reversed-channel view of OpenCV's BGR buffer: no copy of a 1080p frame per update."""
    if frame.ndim == 2:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2RGB)
    if frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2RGB)
    return frame[:, :, ::-1]


def open_source(spec: str | int | os.PathLike[str], *, discard: int | None = None,
                max_pixels: int = defaults.MAX_PIXELS) -> FrameSource:
    """Open ``spec``: "0" (camera index), "/dev/video2", "rtsp://...", "run.avi" or "frames/img_%04d.png"."""
    return FrameSource(os.fspath(spec) if isinstance(spec, os.PathLike) else spec, discard=discard,
                       max_pixels=max_pixels)
