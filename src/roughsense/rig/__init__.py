"""The physical rig: a camera, a digital scale and the paper's acquisition protocol (section 3.2) -> a study folder.

A source of study folders like the simulator: it writes through ``io/`` and knows nothing about the analysis;
live scoring takes the scoring function as an argument, and the CLI wires in the model.
"""
from __future__ import annotations

from .camera import FrameSource, open_source
from .capture import CaptureResult, capture_session
from .live import live_scores, render_live
from .scale import ManualForce, SerialScale, open_force_input, parse_scale_line

__all__ = [
    "FrameSource",
    "open_source",
    "CaptureResult",
    "capture_session",
    "live_scores",
    "render_live",
    "ManualForce",
    "SerialScale",
    "open_force_input",
    "parse_scale_line",
]
