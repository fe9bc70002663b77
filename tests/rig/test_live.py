"""Live scoring: every frame of a video source is scored in order, and a frame the model cannot take is reported."""
from __future__ import annotations

import io
import os

import numpy as np
import pytest
from rich.console import Console

from roughsense.errors import ConfigError, InputError
from roughsense.rig.camera import open_source
from roughsense.rig.live import live_scores, render_live
from tests.videos import decoded_frames, write_video


def red_minus_green(frame: np.ndarray) -> float:
    """A score that depends on channel order, so a BGR/RGB mix-up would show."""
    return float(frame[..., 0].mean() - frame[..., 1].mean())


def test_scores_every_frame_in_order(tmp_path):
    video = write_video(tmp_path / "live.avi")
    expected = [red_minus_green(f) for f in decoded_frames(video)]
    results = list(live_scores(str(video), red_minus_green))
    assert [score for _, score in results] == pytest.approx(expected, abs=1e-12)
    stamps = [stamp for stamp, _ in results]
    assert stamps == sorted(stamps)
    assert expected[0] < -200 and expected[-1] > expected[0] + 200  # red ramps up, green ramps down


def test_max_frames_and_rate_limit(tmp_path):
    video = write_video(tmp_path / "live.avi")
    expected = [red_minus_green(f) for f in decoded_frames(video)]
    assert [s for _, s in live_scores(str(video), red_minus_green, max_frames=3)] == pytest.approx(expected[:3])
    # a long interval: the first frame is scored, the rest of the file is dropped undecoded
    with open_source(video) as source:
        assert [s for _, s in live_scores(source, red_minus_green, min_interval_s=60)] == pytest.approx(expected[:1])
        assert source.frames_read == 12


def test_frame_that_does_not_fit_the_model(tmp_path):
    video = write_video(tmp_path / "live.avi")

    def needs_1080p(frame):
        if frame.shape[1] < 1900:
            raise ConfigError(f"ROI 1900x150 px does not fit in a {frame.shape[1]}x{frame.shape[0]} px image")
        return 0.0

    with pytest.raises(InputError) as info:
        list(live_scores(str(video), needs_1080p))
    message = str(info.value)
    assert message == f"{video}: frame 1 (64x48 px): ROI 1900x150 px does not fit in a 64x48 px image"
    assert "\n" not in message


def test_source_that_does_not_open_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="video source not found"):
        next(live_scores(str(tmp_path / "gone.avi"), red_minus_green))


def test_render_live_shows_the_last_score():
    buffer = io.StringIO()
    console = Console(file=buffer, width=60, force_terminal=False, color_system=None)
    stream = [(100.0 + 0.1 * k, 1.5 + 0.25 * k) for k in range(5)]
    summary = render_live(iter(stream), console=console, label="roughness")
    assert summary.updates == 5 and summary.last_score == 2.5
    assert summary.updates_per_s == pytest.approx(10.0)
    text = buffer.getvalue()
    assert "roughness" in text and "2.500" in text and "1.500 .. 2.500" in text and "5 (10.0/s)" in text


def test_a_scorer_that_flags_extrapolation_yields_the_flag(tmp_path):
    video = write_video(tmp_path / "live.avi")
    expected = [red_minus_green(f) for f in decoded_frames(video)]

    def flagged_when_red(frame):
        score = red_minus_green(frame)
        return score, score > 0  # "outside the training range" once red dominates

    results = list(live_scores(str(video), flagged_when_red))
    assert [len(r) for r in results] == [3] * len(expected)
    assert [r[1] for r in results] == pytest.approx(expected, abs=1e-12)
    assert [r[2] for r in results] == [e > 0 for e in expected]
    assert all(type(r[2]) is bool for r in results)


def test_render_live_flags_a_value_that_extrapolates():
    def shown(stream):
        buffer = io.StringIO()
        console = Console(file=buffer, width=100, force_terminal=False, color_system=None)
        return render_live(iter(stream), console=console, label="roughness"), buffer.getvalue()

    summary, text = shown([(100.0 + 0.1 * k, 1.5 + 0.25 * k, k >= 3) for k in range(5)])
    assert summary.updates == 5 and summary.extrapolated == 2 and summary.last_score == 2.5
    assert "2.500  extrapolates (outside the training range)" in text
    summary, text = shown([(100.0, 1.5, True), (100.1, 1.75, False)])  # the flag belongs to the value shown
    assert summary.extrapolated == 1 and "1.750" in text and "extrapolates" not in text
    summary, text = shown([(100.0, 1.5), (100.1, 1.75)])  # a scorer without a flag: nothing flagged
    assert summary.extrapolated == 0 and "extrapolates" not in text


def test_render_live_shows_why_a_value_extrapolates():
    buffer = io.StringIO()
    console = Console(file=buffer, width=200, force_terminal=False, color_system=None)
    why = "finer than the sensor resolves: period 0.50 mm, below the band's 1 mm [1/f_max]"
    summary = render_live(iter([(100.0, 1.5, why), (100.1, 1.75, "")]), console=console, label="roughness")
    assert summary.extrapolated == 1 and summary.reason == why  # the last reason given, kept for the summary line
    summary = render_live(iter([(100.0, 1.5, ""), (100.1, 1.75, why)]), console=console, label="roughness")
    assert summary.extrapolated == 1 and f"1.750  extrapolates ({why})" in buffer.getvalue()  # markup escaped


@pytest.mark.parametrize("signum", ["SIGINT", "SIGTERM"])
def test_ctrl_c_ends_a_live_display_as_its_normal_end_and_sigterm_stops_the_run(signals, signum):
    """36.5: live scoring ends with Ctrl-C (its summary is the result); a SIGTERM there still stops the run."""
    import io
    import signal

    from rich.console import Console

    from roughsense.rig.live import render_live

    def frames():
        for i in range(10**9):
            if i == 3:
                os.kill(os.getpid(), getattr(signal, signum))
            yield float(i), 1.0 + i
    summary = render_live(frames(), console=Console(file=io.StringIO()))
    assert summary.updates == 3 and summary.last_score == 3.0
    assert signals.requested() == (None if signum == "SIGINT" else signal.SIGTERM)
