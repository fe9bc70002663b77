"""Writing rendered frames as PNG: the encoder's settings and the worker task that renders and writes one mount's
trials (its forces, whose contacts are solved together)."""
from __future__ import annotations

from ..io.writer import StudyWriter
from .frames import render_mount
from .plan import Trial

_WRITERS: dict[tuple[str, bool], StudyWriter] = {}


def write_mount(args: tuple[str, bool, list[Trial]]) -> list[tuple[str, float]]:
    """Render and write the trials of one mount (:func:`.frames.render_mount`): each image's name and contact fraction."""
    root, force, trials = args
    writer = _WRITERS.get((root, force))
    if writer is None:  # each worker reopens the folder the parent already checked and created
        writer = _WRITERS[(root, force)] = StudyWriter(root, force=force, resume=True)
    return [(writer.write_image(trial.image, frame, params=png_params()), fraction)
            for trial, (frame, fraction) in zip(trials, render_mount(trials))]


def png_params() -> tuple[int, ...]:
    """How frames are encoded: PNG, each row predicted by the "average" filter, Huffman coding only.

    A noisy camera frame has almost no repeated strings, so LZ77's match search costs time and saves nothing; and
    the mean of the left and upper neighbours predicts a pixel with less residual noise (variance 1.5 sigma^2) than
    OpenCV's default "sub" filter (2 sigma^2): ~4 % smaller at the same speed, lossless (BENCHMARKS.md, first run).
    """
    import cv2

    return (cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY,
            cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_AVG)
