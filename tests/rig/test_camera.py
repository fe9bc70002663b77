"""Frame sources: a video file and an image sequence stand in for the camera."""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from roughsense.errors import InputError, RoughsenseWarning
from roughsense.rig.camera import DEVICE_DISCARD, FrameSource, _describe, open_source
from tests.commands import HANG_GUARD_S, one_error
from tests.videos import decoded_frames, write_damaged_video, write_video


def test_video_file_frames_are_rgb_in_order(tmp_path):
    video = write_video(tmp_path / "clip.avi")
    reference = decoded_frames(video)
    assert len(reference) == 12
    with open_source(video) as source:
        assert not source.is_device and source.discard == 0
        frames = list(source)
    assert len(frames) == 12
    for got, want in zip(frames, reference):
        np.testing.assert_array_equal(got, want)
    # the ramp survives MJPG: frame k's blue channel is ~20k, so RGB order is right
    assert abs(int(frames[5][0, -1, 2]) - 100) <= 3 and abs(int(frames[5][0, -1, 0]) - 0) <= 3


def test_read_fresh_drops_the_queued_frames(tmp_path):
    video = write_video(tmp_path / "clip.avi")
    reference = decoded_frames(video)
    with FrameSource(str(video), discard=2) as source:
        taken = [source.read_fresh() for _ in range(4)]  # frames 2, 5, 8, 11
        with pytest.raises(InputError, match=r"yielded no frame \(at its end, after 12 frame\(s\)\)"):
            source.read_fresh()
    for got, index in zip(taken, (2, 5, 8, 11)):
        np.testing.assert_array_equal(got, reference[index])


def test_image_sequence_pattern(tmp_path):
    images = []
    for k in range(3):
        image = np.full((20, 30, 3), 40 * k + 10, np.uint8)
        image[:, :, 0] = 200
        cv2.imwrite(str(tmp_path / f"img_{k:03d}.png"), image)
        images.append(image[:, :, ::-1])
    with open_source(str(tmp_path / "img_%03d.png")) as source:
        frames = list(source)
    assert len(frames) == 3
    for got, want in zip(frames, images):
        np.testing.assert_array_equal(got, want)


def test_sources_that_do_not_open(tmp_path):
    with pytest.raises(InputError, match="video source not found") as info:
        open_source(tmp_path / "missing.avi")
    assert str(info.value).startswith(str(tmp_path / "missing.avi"))
    text = tmp_path / "notes.txt"
    text.write_text("not a video\n")
    with pytest.raises(InputError, match="cannot open video source"):
        open_source(text)


def test_live_devices_discard_by_default():
    assert _describe("0") == (0, True)
    assert _describe(2) == (2, True)
    assert _describe("/dev/video2") == ("/dev/video2", True)
    assert _describe("rtsp://cam.local/stream") == ("rtsp://cam.local/stream", True)
    assert _describe("run_0001.avi") == ("run_0001.avi", False)
    assert DEVICE_DISCARD >= 4  # V4L2's default queue is 4 buffers


# --------------------------------------------------------------------------- damaged frames (issue 22)


def test_a_frame_decoded_with_errors_is_skipped_with_one_warning_and_nothing_on_stderr(tmp_path, capfd):
    clean = decoded_frames(write_video(tmp_path / "clean.avi"))
    video = write_damaged_video(tmp_path / "damaged.avi", frame=5)
    with pytest.warns(RoughsenseWarning) as caught, open_source(video) as source:
        frames = list(source)
    assert [str(w.message) for w in caught] == [
        f"{video}: frame 6 decoded with errors (mjpeg: error count: 268435455; mjpeg: error y=0 x=2); skipped"]
    assert len(frames) == 11  # every frame but the damaged one, in order, exactly as decoded from the clean file
    for got, want in zip(frames, clean[:5] + clean[6:]):
        np.testing.assert_array_equal(got, want)
    assert capfd.readouterr().err == ""  # ffmpeg's own lines were caught, not printed


def test_a_frame_that_does_not_decode_is_an_error_not_the_end_of_the_file(tmp_path, capfd):
    video = write_damaged_video(tmp_path / "broken.avi", frame=5, how="broken")
    with open_source(video) as source:
        for _ in range(5):
            source.read_next()
        with pytest.raises(InputError, match=r"frame 6 does not decode \(mjpeg: huffman table decode error\)") as info:
            source.read_next()
    assert str(info.value).startswith(f"{video}: ")
    assert capfd.readouterr().err == ""


def test_a_run_of_damaged_frames_refuses_the_source(tmp_path, monkeypatch):
    from roughsense.rig import camera

    video = write_video(tmp_path / "clip.avi")

    @contextlib.contextmanager
    def always_complaining():
        yield ["mjpeg: error y=0 x=2"]

    monkeypatch.setattr(camera, "_decoder_messages", always_complaining)
    with open_source(video) as source, pytest.warns(RoughsenseWarning):
        with pytest.raises(InputError, match=rf"{camera.MAX_DAMAGED_FRAMES} frames in a row decoded with errors, "
                                             rf"up to frame {camera.MAX_DAMAGED_FRAMES}"):
            source.read_fresh()


def test_a_fifo_as_a_video_source_is_refused_at_once(tmp_path):
    """36.6 (the rule, the rig): OpenCV would block opening a FIFO given as a video file."""
    from roughsense.errors import InputError
    from roughsense.rig.camera import open_source

    os.mkfifo(tmp_path / "run.avi")
    with pytest.raises(InputError, match="is a FIFO \\(named pipe\\), not a regular video file"):
        open_source(tmp_path / "run.avi")


def _frames(folder, count: int) -> str:
    rng = np.random.default_rng(0)
    for i in range(count):
        cv2.imwrite(str(folder / f"img_{i:03d}.png"), rng.integers(0, 255, (40, 60, 3), dtype=np.uint8))
    return str(folder / "img_%03d.png")


@pytest.mark.parametrize("where", [0, 2])
def test_a_fifo_in_an_image_sequence_is_refused_not_waited_on(tmp_path, where):
    """36.6 for --source PATTERN (predict --live, capture): a FIFO among the sequence's files hung OpenCV's read,
    the first one before a frame was shown, a later one mid-run."""
    pattern = _frames(tmp_path, 4)
    fifo = tmp_path / f"img_{where:03d}.png"
    fifo.unlink()
    os.mkfifo(fifo)
    code = ("import sys\nfrom roughsense.errors import InputError\nfrom roughsense.rig.camera import open_source\n"
            "try:\n    print(len(list(open_source(sys.argv[1]))))\nexcept InputError as exc:\n    print(exc)\n")
    done = subprocess.run([sys.executable, "-c", code, pattern], capture_output=True, text=True,
                          timeout=HANG_GUARD_S)
    assert done.stdout.strip() == f"{fifo}: is a FIFO (named pipe), not a regular image file; give the image file itself"


def test_an_image_sequence_of_regular_files_still_reads_every_frame(tmp_path):
    from roughsense.rig.camera import open_source

    pattern = _frames(tmp_path, 5)
    with open_source(pattern) as source:
        frames = list(source)
    assert len(frames) == 5
    np.testing.assert_array_equal(frames[3], cv2.imread(pattern % 3)[:, :, ::-1])


def png_claiming(width: int, height: int) -> bytes:
    """A PNG whose header claims ``width`` x ``height`` px (its data is empty: never decoded here)."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"")) + chunk(b"IEND", b""))


def test_live_and_capture_refuse_a_frame_above_max_pixels_before_decoding(run_cli, tmp_path, tiny_model_2n):
    """28.13: a 16000 x 15000 PNG peaked at 1.9 GB (predict --live) and 3.2 GB (capture, which wrote it)."""
    big = tmp_path / "big.png"
    big.write_bytes(png_claiming(16000, 15000))
    pattern = tmp_path / "frames"
    pattern.mkdir()
    (pattern / "f_0000.png").write_bytes(png_claiming(16000, 15000))
    for source in (big, pattern / "f_%04d.png"):
        line = one_error(run_cli, "predict", tiny_model_2n, "--live", "--source", source, "--max-frames", "1")
        assert "image is 16000 x 15000 px (240 Mpx), above the limit of 100 Mpx" in line
        line = one_error(run_cli, "capture", "--source", source, "--out", tmp_path / "captured", "--specimen", "R2",
                         "--pad", "smooth")
        assert "image is 16000 x 15000 px (240 Mpx), above the limit of 100 Mpx" in line
        assert not (tmp_path / "captured").exists()
