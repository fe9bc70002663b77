"""Small video files standing in for a camera, and the frames OpenCV decodes from them (the reference)."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np


def write_video(path, n_frames=12, size=(64, 48)):
    """An MJPG .avi whose frames differ in every channel (so order and BGR/RGB mix-ups show)."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, size)
    assert writer.isOpened()
    for k in range(n_frames):
        frame = np.zeros((size[1], size[0], 3), np.uint8)
        frame[..., 0] = 20 * k
        frame[..., 1] = 250 - 20 * k
        frame[:, : size[0] // 2, 2] = 10 * k
        writer.write(frame)
    writer.release()
    return path


def decoded_frames(path, *, rgb: bool = True):
    """Every frame as OpenCV decodes it: RGB (as roughsense hands frames on) or BGR (as cv2.imread reads PNGs)."""
    capture = cv2.VideoCapture(str(path))
    frames = []
    while (item := capture.read())[0]:
        frames.append(item[1][:, :, ::-1] if rgb else item[1])
    capture.release()
    return frames


def write_damaged_video(path, *, frame=5, how="garbled", n_frames=12, size=(64, 48)):
    """:func:`write_video` with frame ``frame`` (0-based) damaged inside its JPEG scan data, its framing intact.

    ``garbled`` flips 10 bytes early in the scan: ffmpeg decodes the frame but reports errors (the frame is wrong).
    ``broken`` overwrites 40 bytes with a pattern of markers: ffmpeg cannot decode the frame at all.
    """
    write_video(path, n_frames=n_frames, size=size)
    data = bytearray(Path(path).read_bytes())
    starts = [i for i in range(len(data) - 1) if data[i] == 0xFF and data[i + 1] == 0xD8]  # JPEG SOI per frame
    begin, end = starts[frame], starts[frame + 1]
    if how == "garbled":
        scan = data.index(b"\xff\xda", begin)  # start of scan: entropy-coded data follows its header
        for k in range(scan + 20, scan + 30):
            data[k] ^= 0x5A
    else:
        middle = begin + (end - begin) * 2 // 3
        for k in range(middle, middle + 40):
            data[k] = 0x00 if k % 3 else 0xFF
    Path(path).write_bytes(bytes(data))
    return path
