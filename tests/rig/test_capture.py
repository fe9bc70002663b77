"""``roughsense capture`` with a video file standing in for the camera and forces typed on stdin."""
from __future__ import annotations

import contextlib
import io
import os
import threading
import time
from datetime import UTC, datetime, timedelta

import cv2
import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as hs

from roughsense.errors import InputError
from roughsense.io.sensor_settings import roi_misfit
from roughsense.io.study import read_study
from roughsense.io.writer import StudyWriter
from roughsense.rig.capture import image_name, plan_steps
from roughsense.sensor.line import resolve_roi
from tests.videos import decoded_frames, write_damaged_video, write_video

G = 9.80665




@pytest.fixture
def video(tmp_path):
    return write_video(tmp_path / "camera.avi")


@pytest.fixture
def typed(monkeypatch):
    def feed(*lines: str) -> None:
        monkeypatch.setattr("sys.stdin", io.StringIO("".join(f"{line}\n" for line in lines)))

    return feed


def capture_args(video, out, *extra):
    # The test video is 64x48 px, too small for the default 1900x150 px centre crop: "auto" fits any frame.
    return ("capture", "--source", video, "--out", out, "--specimen", "R3", "--pad", "fp", "--roi", "auto", *extra)


def snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_full_protocol_writes_a_valid_study(tmp_path, video, run_cli, typed):
    out = tmp_path / "study"
    typed("", "2.05", "306 g", "0.98", "", "3.1")
    code, stdout, stderr = run_cli(*capture_args(video, out, "--repetitions", "2", "--shape", "rectangular",
                                                 "--wavelength-mm", "3"))
    assert code == 0, stderr
    assert "captured 6 image(s) of R3/fp" in stdout
    study = read_study(out)
    manifest = study.manifest
    assert study.forces_n == (1.0, 2.0, 3.0) and study.sensor.px_per_mm == 34.9 and study.sensor.roi == "auto"
    assert study.specimens.to_dict("records") == [{"specimen": "R3", "shape": "rectangular", "wavelength_mm": 3.0}]
    assert list(manifest["repetition"]) == [1, 1, 1, 2, 2, 2]
    assert list(manifest["condition"]) == ["1N", "2N", "3N"] * 2
    np.testing.assert_allclose(manifest["force_n"], [1.0, 2.05, 0.306 * G, 0.98, 2.0, 3.1], rtol=1e-6)
    assert list(manifest["image"]) == [f"images/R3_fp_r{r:02d}_{f}N.png" for r in (1, 2) for f in (1, 2, 3)]
    stamps = [datetime.fromisoformat(t) for t in manifest["timestamp"]]
    assert all(s.utcoffset() == timedelta(0) for s in stamps) and stamps == sorted(stamps)
    assert abs(datetime.now(UTC) - stamps[-1]) < timedelta(minutes=5)
    # each image is the next frame of the source, pixel for pixel
    for rel, frame in zip(manifest["image"], decoded_frames(video, rgb=False)):
        np.testing.assert_array_equal(cv2.imread(str(out / rel)), frame)


def test_interrupted_run_resumes_without_touching_what_exists(tmp_path, video, run_cli, typed):
    out = tmp_path / "study"
    args = capture_args(video, out, "--repetitions", "2", "--shape", "circular", "--wavelength-mm", "2.5")
    typed("", "", "", "1.1")  # stdin ends during repetition 2
    code, _, stderr = run_cli(*args)
    assert_one_line_error(code, stderr, "<stdin>: input ended before the operator answered (stdin closed)")
    assert len(read_study(out).manifest) == 4
    before = snapshot(out)

    typed("", "")
    code, stdout, stderr = run_cli(*args)
    assert code == 0, stderr
    assert "4 step(s) were already captured; captured 2 image(s)" in stdout
    after = snapshot(out)
    for path, data in before.items():
        if path.name != "manifest.csv":
            assert after[path] == data, f"{path} changed on resume"
    manifest = read_study(out).manifest
    assert list(zip(manifest["repetition"], manifest["condition"])) == [
        (1, "1N"), (1, "2N"), (1, "3N"), (2, "1N"), (2, "2N"), (2, "3N")
    ]
    assert manifest["force_n"].iloc[3] == 1.1

    code, stdout, _ = run_cli(*args)  # complete: nothing to do, nothing read from stdin
    assert code == 0 and "6 step(s) were already captured; captured 0 image(s)" in stdout
    assert snapshot(out) == after

    typed("", "", "")  # raising the target continues the count
    code, _, _ = run_cli(*args[:-6], "--repetitions", "3")
    assert code == 0
    assert list(read_study(out).manifest["repetition"])[-3:] == [3, 3, 3]


def test_crash_between_image_and_row_leaves_an_orphan_that_is_not_overwritten(tmp_path, video, run_cli, typed, monkeypatch):
    out = tmp_path / "study"
    args = capture_args(video, out, "--repetitions", "1", "--shape", "rectangular", "--wavelength-mm", "4")
    real_append = StudyWriter.append_manifest_row
    calls = []

    def crash_on_second(self, row):
        calls.append(row["image"])
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real_append(self, row)

    monkeypatch.setattr(StudyWriter, "append_manifest_row", crash_on_second)
    typed("", "", "")
    code, _, stderr = run_cli(*args)
    assert code == 130 and "rerun the same command to resume" in stderr
    orphan = out / "images" / "R3_fp_r01_2N.png"
    orphan_bytes = orphan.read_bytes()
    assert list(read_study(out).manifest["image"]) == ["images/R3_fp_r01_1N.png"]
    assert not [p for p in (out / "images").iterdir() if p.suffix == ".tmp"]

    monkeypatch.setattr(StudyWriter, "append_manifest_row", real_append)
    typed("", "")
    code, stdout, stderr = run_cli(*args)
    assert code == 0
    assert "images/R3_fp_r01_2N.png has no manifest row" in stderr
    assert orphan.read_bytes() == orphan_bytes
    manifest = read_study(out).manifest
    assert list(manifest["image"]) == ["images/R3_fp_r01_1N.png", "images/R3_fp_r01_2N-2.png", "images/R3_fp_r01_3N.png"]
    # the rerun opened the source afresh, so the retake is its first frame
    np.testing.assert_array_equal(cv2.imread(str(out / manifest["image"][1])), decoded_frames(video, rgb=False)[0])


def test_second_specimen_extends_the_folder_and_blank_metadata_is_named(tmp_path, video, run_cli, typed):
    out = tmp_path / "study"
    typed("", "", "")
    assert run_cli(*capture_args(video, out, "--repetitions", "1", "--shape", "rectangular", "--wavelength-mm", "3"))[0] == 0
    typed("", "", "")
    code, stdout, stderr = run_cli("capture", "--source", video, "--out", out, "--specimen", "C2.5", "--pad", "fp",
                                   "--repetitions", "1")
    assert code == 0 and "fill in shape and wavelength_mm for C2.5" in stdout
    # the scale is checked after every capture; a folder not yet readable as a study says why, once
    [scale] = [line for line in stderr.splitlines() if "scale" in line]
    assert scale.startswith("roughsense: scale could not be confirmed: ")
    assert scale.endswith("specimens.csv, row 3, column 'shape': empty value")
    with pytest.raises(InputError, match=r"specimens.csv, row 3, column 'shape': empty value"):
        read_study(out)
    # completing the row from the command line fills the blanks only
    code, stdout, _ = run_cli("capture", "--source", video, "--out", out, "--specimen", "C2.5", "--pad", "fp",
                              "--repetitions", "1", "--shape", "circular", "--wavelength-mm", "2.5")
    assert code == 0 and "fill in" not in stdout
    study = read_study(out)
    assert study.specimens.to_dict("records") == [
        {"specimen": "R3", "shape": "rectangular", "wavelength_mm": 3.0},
        {"specimen": "C2.5", "shape": "circular", "wavelength_mm": 2.5},
    ]
    assert list(study.manifest["specimen"]) == ["R3"] * 3 + ["C2.5"] * 3


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (("--forces-n", "1,2"), "--forces-n 1,2 differs from this study's protocol 1,2,3"),
        (("--px-per-mm", "20"), "--px-per-mm 20 differs from 34.9"),
        (("--shape", "circular"),
         "specimens.csv, row 2, column 'shape': specimen 'R3' has shape rectangular; --shape says circular"),
        (("--wavelength-mm", "5"), "column 'wavelength_mm': specimen 'R3' has wavelength_mm 3; --wavelength-mm says 5"),
    ],
)
def test_resume_refuses_contradicting_options(tmp_path, video, run_cli, typed, extra, message):
    out = tmp_path / "study"
    typed("", "", "")
    run_cli(*capture_args(video, out, "--repetitions", "1", "--shape", "rectangular", "--wavelength-mm", "3"))
    before = snapshot(out)
    typed("", "", "")
    code, _, stderr = run_cli(*capture_args(video, out, "--repetitions", "2", *extra))
    assert code == 2 and message in stderr and len(stderr.strip().splitlines()) == 1
    assert snapshot(out) == before


# --------------------------------------------------------------------------- bad input at the CLI


def assert_one_line_error(code, stderr, *fragments):
    """Exit 2 and exactly one error line, the last one (operator prompts precede it on stderr)."""
    assert code == 2
    lines = stderr.strip().splitlines()
    errors = [line for line in lines if line.startswith("roughsense:")]
    assert errors == [lines[-1]] and lines[-1].startswith("roughsense: error: ")
    assert "Traceback" not in stderr
    for fragment in fragments:
        assert fragment in lines[-1]


def test_source_that_does_not_open(tmp_path, run_cli, typed):
    typed("")
    notes = tmp_path / "notes.txt"
    notes.write_text("hello\n")
    out = tmp_path / "study"
    code, _, stderr = run_cli(*capture_args(notes, out))
    assert_one_line_error(code, stderr, str(notes), "cannot open video source")
    code, _, stderr = run_cli(*capture_args(tmp_path / "nope.avi", out))
    assert_one_line_error(code, stderr, "nope.avi", "video source not found")
    assert not out.exists()


def test_force_that_is_not_a_number(tmp_path, video, run_cli, typed):
    out = tmp_path / "study"
    typed("", "two")
    code, _, stderr = run_cli(*capture_args(video, out, "--shape", "rectangular", "--wavelength-mm", "3"))
    assert_one_line_error(code, stderr, "<stdin>: force 'two' is not a number")
    assert list(read_study(out).manifest["image"]) == ["images/R3_fp_r01_1N.png"]


def test_force_far_from_the_step_is_refused(tmp_path, video, run_cli, typed):
    out = tmp_path / "study"
    typed("20")
    code, _, stderr = run_cli(*capture_args(video, out))
    assert_one_line_error(code, stderr, "20 N is outside 0.5..1.5 N, the range for the 1 N step")
    assert not out.exists()  # nothing was captured, so nothing was written


class EnterKey(io.StringIO):
    """Operator input that runs ``before(n)`` ahead of answering the n-th prompt."""

    def __init__(self, text, before):
        super().__init__(text)
        self.before = before
        self.calls = 0

    def readline(self, *args):
        self.calls += 1
        self.before(self.calls)
        return super().readline(*args)


def test_silent_serial_port(tmp_path, video, run_cli, monkeypatch):
    master, slave = os.openpty()
    os.set_blocking(master, False)  # a full pty buffer must not block the scale thread
    port = os.ttyname(slave)
    out = tmp_path / "study"
    stop = threading.Event()

    def scale():
        while not stop.is_set():
            with contextlib.suppress(BlockingIOError):
                os.write(master, b"ST,+00102.0 g\r\n")
            time.sleep(0.01)

    thread = threading.Thread(target=scale, daemon=True)
    thread.start()

    def silence_from_second_prompt(n):  # the scale streams for the 1 N step, then goes quiet
        if n == 2:
            stop.set()
            thread.join()

    monkeypatch.setattr("sys.stdin", EnterKey("\n\n", silence_from_second_prompt))
    try:
        code, _, stderr = run_cli(*capture_args(video, out, "--forces-from", f"serial:{port}", "--timeout-s", "1",
                                                "--shape", "rectangular", "--wavelength-mm", "3"))
    finally:
        stop.set()
        thread.join()
        os.close(master)
        os.close(slave)
    assert_one_line_error(code, stderr, f"{port}: the scale sent nothing for 1 s")
    manifest = read_study(out).manifest
    assert list(manifest["image"]) == ["images/R3_fp_r01_1N.png"]
    assert manifest["force_n"].iloc[0] == pytest.approx(0.102 * G, rel=1e-6)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--specimen", "R 3"), "--specimen 'R 3': use letters, digits"),
        (("--pad", "../x"), "--pad '../x'"),
        (("--repetitions", "0"), "--repetitions must be a whole number from 1"),
        (("--shape", "wavy"), "--shape 'wavy'"),
        (("--forces-from", "usb"), "--forces-from must be 'manual' or 'serial:PORT[:BAUD]'"),
        (("--forces", "1,x"), "capture: --forces is now --forces-n"),  # the old spelling, refused naming the new
    ],
)
def test_bad_options(tmp_path, video, run_cli, typed, args, message):
    typed("")
    base = {"--specimen": "R3", "--pad": "fp"}
    base.update(dict(zip(args[::2], args[1::2])))
    flat = [item for pair in base.items() for item in pair]
    code, _, stderr = run_cli("capture", "--source", video, "--out", tmp_path / "s", *flat)
    assert_one_line_error(code, stderr, message)
    assert not (tmp_path / "s").exists()


def test_refuses_a_folder_that_is_not_a_study(tmp_path, video, run_cli, typed):
    (tmp_path / "photos").mkdir()
    (tmp_path / "photos" / "holiday.jpg").write_bytes(b"x")
    typed("")
    code, _, stderr = run_cli(*capture_args(video, tmp_path / "photos"))
    assert_one_line_error(code, stderr, "has no study.toml")


def test_plan_fills_holes_in_protocol_order():
    manifest = pd.DataFrame({
        "specimen": ["R3", "R3", "R3", "C3"], "pad": ["fp", "fp", "flat", "fp"],
        "repetition": [1, 1, 1, 1], "nominal_force_n": [1.0, 3.0, 2.0, 2.0],
    })
    assert plan_steps(manifest, "R3", "fp", (1.0, 2.0, 3.0), 2) == [(1, 2.0), (2, 1.0), (2, 2.0), (2, 3.0)]
    assert image_name("R3", "fp", 7, 2.5) == "R3_fp_r07_2.5N.png"
    assert image_name("R3", "fp", 12, 1.0, attempt=3) == "R3_fp_r12_1N-3.png"


# --------------------------------------------------------------------------- frame size vs the study's ROI


def write_frames(folder, width, height, n_frames=3):
    """An image sequence (exact frame size, unlike codecs that round it) standing in for the camera."""
    folder.mkdir()
    for k in range(n_frames):
        cv2.imwrite(str(folder / f"img_{k:04d}.png"), np.full((height, width, 3), 40 * k, np.uint8))
    return str(folder / "img_%04d.png")


def test_frame_smaller_than_the_centre_crop_is_refused_before_anything_is_written(tmp_path, video, run_cli, typed):
    out = tmp_path / "study"
    typed("")
    code, _, stderr = run_cli("capture", "--source", video, "--out", out, "--specimen", "R3", "--pad", "fp")
    assert_one_line_error(code, stderr, f"{video}: frame is 64x48 px", "1900x150 px centre crop")
    assert not out.exists()


@pytest.mark.parametrize(
    ("size", "roi", "ok"),
    [
        ((1900, 150), "center", True),  # exactly the centre crop
        ((1900, 149), "center", False),
        ((1899, 150), "center", False),
        ((2, 1), "auto", True),  # auto clips the crop to the frame: any frame two pixels wide will do
        ((1, 8), "auto", False),
        ((40, 30), "0,0,40,30", True),  # an explicit ROI that fills the frame
        ((40, 30), "1,0,40,30", False),
        ((40, 30), "0,0,40,31", False),
    ],
)
def test_frame_size_rule_at_its_boundaries(tmp_path, run_cli, typed, size, roi, ok):
    source = write_frames(tmp_path / "frames", *size)
    out = tmp_path / "study"
    typed("", "", "")
    code, stdout, stderr = run_cli("capture", "--source", source, "--out", out, "--specimen", "R3", "--pad", "fp",
                                   "--repetitions", "1", "--roi", roi, "--shape", "rectangular", "--wavelength-mm", "3")
    if ok:
        assert code == 0, stderr
        study = read_study(out)  # the analysis's own crop rule accepts every saved frame
        for path in study.image_paths:
            resolve_roi(study.sensor.roi, cv2.imread(str(path)))
    else:
        assert_one_line_error(code, stderr, f"frame is {size[0]}x{size[1]} px")
        assert not out.exists()


def test_resumed_session_with_a_smaller_camera_changes_nothing(tmp_path, run_cli, typed):
    out = tmp_path / "study"
    big = write_frames(tmp_path / "big", 64, 48)
    typed("", "", "")
    args = ("--out", out, "--specimen", "R3", "--pad", "fp", "--shape", "rectangular", "--wavelength-mm", "3")
    code, _, stderr = run_cli("capture", "--source", big, *args, "--repetitions", "1", "--roi", "8,8,48,32")
    assert code == 0, stderr
    before = snapshot(out)
    small = write_frames(tmp_path / "small", 48, 36)
    typed("", "", "")
    code, _, stderr = run_cli("capture", "--source", small, *args, "--repetitions", "2")
    assert_one_line_error(code, stderr, small, "frame is 48x36 px, ROI 8,8,48,32 reaches outside it")
    assert snapshot(out) == before
    assert len(read_study(out).manifest) == 3


_ROIS = hs.one_of(hs.sampled_from(["center", "auto"]), hs.tuples(*[hs.integers(0, 40)] * 2, *[hs.integers(1, 40)] * 2))


@given(roi=_ROIS, width=hs.integers(1, 2000), height=hs.integers(1, 200))
def test_study_roi_rule_agrees_with_the_sensor(roi, width, height):
    """The rig checks frames with study.roi_misfit; it must accept exactly what the analysis can crop."""
    try:
        resolve_roi(roi, np.zeros((height, width), np.uint8))
        accepted = True
    except InputError:
        accepted = False
    assert accepted == (roi_misfit(roi, width, height) is None)


# --------------------------------------------------------------------------- a folder knows its source (issue 22)


def _simulated(tmp_path):
    from roughsense.sim.config import SimulationConfig
    from roughsense.sim.optics import Camera
    from roughsense.sim.simulate import simulate_study

    config = SimulationConfig(pads=("smooth",), specimens=("R2", "R3"), forces_n=(1.0, 2.0), repetitions=1,
                              camera=Camera(width_px=400, height_px=300), participants=3, sessions=1)
    return simulate_study(tmp_path / "sim", config, jobs=1)


@pytest.mark.parametrize("sign", ["complete", "interrupted", "marker only"])
def test_capture_refuses_a_folder_the_simulator_wrote(tmp_path, video, run_cli, typed, sign):
    """Real frames in a simulated folder would be reported as simulated (and deleted by simulate --force)."""
    from roughsense.io.study import COMPLETE_MARKER, STUDY_TOML

    sim = _simulated(tmp_path)
    if sign == "interrupted":  # killed before its marker: the [simulation] table alone says it
        (sim / COMPLETE_MARKER).unlink()
    if sign == "marker only":  # a hand-edited study.toml without the table: the marker alone says it
        toml = (sim / STUDY_TOML).read_text()
        (sim / STUDY_TOML).write_text(toml[:toml.index("[simulation]")])
    before = snapshot(sim)
    typed("", "", "")
    code, _, stderr = run_cli(*capture_args(video, sim, "--repetitions", "1", "--forces-n", "1,2"))
    assert_one_line_error(code, stderr, f"{sim}: is a simulated study", "capture into a folder of their own")
    assert snapshot(sim) == before


def test_the_rigs_writer_refuses_a_simulated_folder_whoever_calls_it(tmp_path):
    from roughsense.errors import OutputExistsError

    sim = _simulated(tmp_path)
    with pytest.raises(OutputExistsError, match="is a simulated study"):
        StudyWriter(sim, resume=True, source="captured")
    StudyWriter(sim, resume=True)  # the simulator's own reopening is unchanged


def test_a_second_capture_into_the_folder_names_the_first(tmp_path, video, run_cli, typed):
    """Two captures into one folder (the rig's own lock, now the one every writer shares): the second names the first."""
    import subprocess
    import sys
    from pathlib import Path

    from roughsense._util.lock import lock_path

    out = tmp_path / "study"
    src = str(Path(__file__).resolve().parents[2] / "src")
    first = subprocess.Popen(
        [sys.executable, "-m", "roughsense.cli", *map(str, capture_args(video, out, "--repetitions", "1"))],
        env={**os.environ, "PYTHONPATH": src}, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE)  # waits at its first force prompt, holding the folder
    try:
        deadline = time.monotonic() + 300  # a hang guard: importing roughsense on a busy machine takes a while
        while not (lock_path(out).exists() and lock_path(out).stat().st_size):
            assert first.poll() is None, first.stderr.read()  # it ended: its stderr is complete
            assert time.monotonic() < deadline, "the first capture never took the lock"  # no read: it still runs
            time.sleep(0.05)
        typed("")
        code, _, stderr = run_cli(*capture_args(video, out, "--repetitions", "1"))
        assert_one_line_error(code, stderr, f"{out}: another run is writing this folder (roughsense capture, PID "
                                            f"{first.pid} on")
    finally:
        first.communicate(b"\n\n\n", timeout=300)
    assert first.returncode == 0 and len(pd.read_csv(out / "manifest.csv")) == 3 and not lock_path(out).exists()


def test_a_new_study_toml_with_the_default_scale_says_so_and_a_stated_one_does_not(tmp_path, video, run_cli, typed):
    """On 390ce82 capture wrote the paper's 34.9 px/mm into a new rig's study.toml without a word."""
    typed("", "", "")
    code, _, err = run_cli(*capture_args(video, tmp_path / "default", "--repetitions", "1"))
    assert code == 0, err
    [line] = [line for line in err.splitlines() if "px_per_mm = 34.9" in line]
    assert line.startswith("roughsense: warning: ") and "not measured on this rig" in line
    assert f"roughsense calibrate {tmp_path / 'default'}" in line
    typed("", "", "")
    code, _, err = run_cli(*capture_args(video, tmp_path / "default", "--repetitions", "2"))
    assert code == 0 and "not measured on this rig" not in err  # said by the run that wrote it
    typed("", "", "")
    code, _, err = run_cli(*capture_args(video, tmp_path / "stated", "--repetitions", "1", "--px-per-mm", "30"))
    assert code == 0 and "not measured on this rig" not in err, err


def test_a_frame_above_the_studys_max_pixels_is_not_written(tiny_smooth):
    import numpy as np

    from roughsense.io.sensor_settings import SensorSettings
    from roughsense.rig.camera import open_source
    from roughsense.rig.capture import _check_frame

    image = next((tiny_smooth / "images").iterdir())
    with pytest.raises(InputError, match=r"frames? is 600 ?x ?64 px|image is 600 x 64 px"):
        open_source(image, max_pixels=1000)
    with open_source(image) as frames:
        frame = frames.read_fresh()
    with pytest.raises(InputError, match="above the study's \\[sensor\\] max_pixels of 0.001 Mpx; nothing of it was written"):
        _check_frame(frame, SensorSettings(max_pixels=1000), frames)
    _check_frame(frame, SensorSettings(roi=(0, 0, 600, 64)), frames)
    assert np.asarray(frame).shape == (64, 600, 3)


def grating_capture_args(video, out):
    return ("capture", "--source", video, "--out", out, "--specimen", "R3", "--pad", "fp", "--roi", "auto",
            "--shape", "rectangular", "--wavelength-mm", "3", "--repetitions", "1")


def test_capture_skips_a_damaged_frame_with_one_warning_and_no_ffmpeg_lines(tmp_path, monkeypatch, capfd):
    import io

    from roughsense.cli import main
    from roughsense.io.study import read_study

    video = write_damaged_video(tmp_path / "camera.avi", frame=1)
    clean = decoded_frames(write_video(tmp_path / "clean.avi"))
    monkeypatch.setattr("sys.stdin", io.StringIO("\n\n\n"))
    code = main([str(a) for a in grating_capture_args(video, tmp_path / "study")])
    err = capfd.readouterr().err  # at the file descriptor: ffmpeg writes to fd 2 directly, below Python
    assert code == 0, err
    assert "[mjpeg @" not in err and "Traceback" not in err
    warned = [line for line in err.splitlines() if "decoded with errors" in line]
    assert len(warned) == 1 and warned[0].endswith("); skipped"), err
    assert warned[0].startswith(f"roughsense: warning: {video}: frame 2 decoded with errors (mjpeg: error ")
    loaded = read_study(tmp_path / "study")
    assert len(loaded.manifest) == 3
    # the frames kept are the file's 1st, 3rd and 4th: the damaged 2nd is not among the data
    import cv2

    for path, want in zip(loaded.image_paths, (clean[0], clean[2], clean[3])):
        np.testing.assert_array_equal(cv2.imread(str(path))[:, :, ::-1], want)
