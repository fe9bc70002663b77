"""Small video files standing in for a camera, and the frames OpenCV decodes from them (the reference)."""
from __future__ import annotations

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
