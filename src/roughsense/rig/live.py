"""Live scoring: the predicted roughness of whatever the pad is pressed on, updated continuously.

The scoring function is passed in (the CLI builds it from a model file), so the rig stays independent
of the analysis. A scorer may also say, per frame, that its model extrapolates (the frame's features lie outside
what the model was trained on); the display then flags that value. Frames are read in order; on a camera the
driver queue is kept at one frame (see :mod:`.camera`), so as long as scoring keeps up with the camera the score
is of a fresh frame.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from .._util import interrupt
from ..errors import InputError, RoughsenseError
from .camera import FrameSource, open_source


def live_scores(
    source: FrameSource | str | int,
    score_frame: Callable[[np.ndarray], float | tuple[float, bool | str]],
    *,
    max_frames: int | None = None,
    min_interval_s: float = 0.0,
) -> Iterator[tuple[float, float] | tuple[float, float, bool | str]]:
    """Yield ``(timestamp_s, score)`` per scored frame; ``timestamp_s`` is Unix time at the frame's arrival.

    ``score_frame`` gets an (H, W, 3) uint8 RGB frame and returns the score, or ``(score, extrapolates)``; the
    latter yields ``(timestamp_s, score, extrapolates)`` (a text ``extrapolates``, the reason, passes as it is).
    Frames arriving sooner than ``min_interval_s`` after the last scored one are dropped undecoded. A
    :class:`RoughsenseError` from ``score_frame`` (for example a frame smaller than the model's ROI) stops the loop
    as an InputError naming the source and the frame. The loop ends at the end of a file, after ``max_frames``
    scores, or when the consumer stops.
    """
    if max_frames is not None and max_frames < 1:
        raise ValueError("max_frames must be at least 1")
    own = not isinstance(source, FrameSource)
    # Opened now, not on the first frame: a source refused (missing, above max_pixels) is one line before any display.
    frames = open_source(source) if own else source
    return _scored_frames(frames, own, score_frame, max_frames=max_frames, min_interval_s=min_interval_s)


def _scored_frames(frames: FrameSource, own: bool, score_frame, *, max_frames: int | None, min_interval_s: float):
    """:func:`live_scores`' loop over an open source (closed at the end if ``own``)."""
    try:
        scored = 0
        last = -float("inf")
        while max_frames is None or scored < max_frames:
            if min_interval_s > 0 and time.monotonic() - last < min_interval_s:
                if not frames.grab():
                    return
                continue
            frame = frames.read_next()
            if frame is None:
                return
            now = time.monotonic()
            stamp = time.time()
            try:
                result = score_frame(frame)
            except RoughsenseError as exc:
                height, width = frame.shape[:2]
                raise InputError(f"frame {frames.frames_read} ({width}x{height} px): {exc.message}",
                                 path=frames.name) from exc
            last = now
            scored += 1
            if isinstance(result, tuple):
                yield stamp, float(result[0]), result[1] if isinstance(result[1], str) else bool(result[1])
            else:
                yield stamp, float(result)
    finally:
        if own:
            frames.close()


@dataclass
class LiveSummary:
    updates: int
    last_score: float | None
    updates_per_s: float
    extrapolated: int = 0  # frames whose model said they lie outside its training range
    reason: str = ""  # why the last such frame did, when the scorer said (e.g. finer than the sensor resolves)


def _latest(score: float, flagged: bool, why: str, escape) -> str:
    """The latest score as shown: flagged when it extrapolates; a frame the model's gate withheld has no number."""
    if math.isnan(score):
        return f"[bold yellow]withheld[/] ({escape(why or 'not a contact image')})"
    flag = f"  [bold yellow]extrapolates[/] ({escape(why or 'outside the training range')})" if flagged else ""
    return f"[bold cyan]{score:.3f}[/]{flag}"


def render_live(
    scores: Iterable[tuple[float, float] | tuple[float, float, bool | str]],
    *,
    console=None,
    label: str = "perceived roughness",
    refresh_per_second: float = 20.0,
) -> LiveSummary:
    """Show the latest score, its recent range and the update rate on the terminal until ``scores`` ends.

    A score that extrapolates (a third element that is true; a non-empty text says why) is flagged beside the value,
    so nobody reads a number held at the edge of the model's training range as a measurement. Ctrl-C ends the
    display cleanly and returns the summary so far.
    """
    from rich.console import Console
    from rich.live import Live
    from rich.markup import escape
    from rich.table import Table

    console = console or Console(stderr=True)
    recent: list[float] = []
    times: list[float] = []
    count = extrapolated = 0
    flagged, why, last_why = False, "", ""
    first = last_t = None

    def view() -> Table:
        table = Table.grid(padding=(0, 2))
        table.add_column(justify="right", style="bold")
        table.add_column()
        if not recent:
            table.add_row(label, "waiting for the first frame...")
            return table
        rate = (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 and times[-1] > times[0] else 0.0
        table.add_row(label, _latest(recent[-1], flagged, why, escape))
        shown = [v for v in recent if not math.isnan(v)]
        table.add_row("last 2 s", f"{min(shown):.3f} .. {max(shown):.3f}" if shown else "every frame withheld")
        table.add_row("updates", f"{count} ({rate:.1f}/s)")
        return table

    try:
        with interrupt.immediate(), Live(view(), console=console, refresh_per_second=refresh_per_second,
                                         transient=False) as live:
            for stamp, score, *flag in scores:
                count += 1
                flagged = bool(flag and flag[0])
                why = flag[0] if flagged and isinstance(flag[0], str) else ""
                extrapolated += flagged
                last_why = why or last_why
                first, last_t = (stamp if first is None else first), stamp
                recent.append(score)
                times.append(stamp)
                while times and times[-1] - times[0] > 2.0:
                    times.pop(0)
                    recent.pop(0)
                live.update(view())
    except KeyboardInterrupt:
        interrupt.forget_sigint()  # Ctrl-C is how the display ends; a SIGTERM still ends the run as stopped
    span = (last_t - first) if count > 1 else 0.0
    return LiveSummary(count, recent[-1] if recent else None, (count - 1) / span if span > 0 else 0.0, extrapolated,
                       last_why)
