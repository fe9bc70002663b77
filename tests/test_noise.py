"""Quiet and contained (issue 22): error lines cap echoed input, library warnings and codec messages become our own
one line, a damaged video frame is never data, and every error names its file (a scale below Nyquist, a full disk)."""
from __future__ import annotations

import errno
import shutil
import tracemalloc
import warnings

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from roughsense.errors import LINE_MAX_CHARS, QUOTE_MAX_CHARS, RoughsenseError, one_line

from .videos import decoded_frames, write_damaged_video, write_video

HUGE = 5_000_000  # a 5 MB cell stands in for the 100 MB one of the report: the same path, a fast test


def error_line(code: int, err: str) -> str:
    """The one ``roughsense: error:`` line of a refused run, every stderr line being roughsense's own."""
    assert code == 2, err[:2000]
    assert "Traceback" not in err and all(line.startswith("roughsense: ") for line in err.splitlines()), err[:2000]
    lines = [line for line in err.splitlines() if line.startswith("roughsense: error: ")]
    assert len(lines) == 1, err[:2000]
    return lines[0]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    from roughsense.sim.config import SimulationConfig, with_image_size
    from roughsense.sim.simulate import simulate_study

    config = SimulationConfig(pads=("smooth",), specimens=("R2", "R3", "R4"), repetitions=1, seed=5, participants=3,
                              sessions=2)
    return simulate_study(tmp_path_factory.mktemp("noise") / "study", with_image_size(config, 1920, 170), jobs=1)


# --------------------------------------------------------------------------- item 12: echoed input is capped


@given(st.text(max_size=5000))
def test_one_line_is_one_bounded_line_whatever_it_is_given(text):
    line = one_line(text)
    assert "\n" not in line and "\r" not in line
    assert len(line) <= LINE_MAX_CHARS + 60


@given(st.text(st.characters(blacklist_categories=("Cc", "Cs", "Zl", "Zp", "Zs", "Cf", "Co", "Cn")), max_size=300))
def test_short_messages_are_left_as_they_are(text):
    message = f"ratings.csv, row 2: not a number: {text[:QUOTE_MAX_CHARS]!r}"
    if message.isprintable() and len(message) <= LINE_MAX_CHARS:
        assert one_line(message) == message


def test_a_huge_value_is_quoted_by_its_start_and_its_length():
    line = one_line(f"ratings.csv, row 2, column 'rating': not a number: '{'9' * HUGE}x'")
    assert line.startswith("ratings.csv, row 2, column 'rating': not a number: '999")
    assert f"...({HUGE + 3} characters)" in line and len(line) < 400  # the whole quoted run: '9...9x'


def test_a_huge_rating_cell_is_one_short_line_in_bounded_memory(run_cli, tmp_path):
    ratings = tmp_path / "ratings.csv"
    pd.DataFrame({"participant": ["P01", "P01"], "session": [1, 1], "specimen": ["R2", "R4"],
                  "rating": ["9" * HUGE + "x", "1.0"]}).to_csv(ratings, index=False)
    tracemalloc.start()
    try:
        code, _, err = run_cli("ratings", ratings, "--out", tmp_path / "agg.csv")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    line = error_line(code, err)
    assert line.startswith(f"roughsense: error: {ratings}, row 2, column 'rating': not a number: '999")
    assert len(err) < 1000
    assert peak < 40 * HUGE  # escaping a cell character by character took ~16 bytes a character on top of reading it


def test_a_huge_image_path_in_the_manifest_is_one_short_line(run_cli, study, tmp_path):
    root = shutil.copytree(study, tmp_path / "study")
    manifest = pd.read_csv(root / "manifest.csv", dtype=str, keep_default_na=False)
    manifest.loc[0, "image"] = "images/" + "a" * HUGE + ".png"
    manifest.to_csv(root / "manifest.csv", index=False)
    code, _, err = run_cli("study", "--study", root, "--out", tmp_path / "report")
    assert str(root) in error_line(code, err)
    assert len(err) < 2000


def test_a_huge_option_value_is_one_short_line(run_cli, tmp_path):
    code, _, err = run_cli("ratings", tmp_path / "r.csv", "--out", tmp_path / "o.csv", "--reference", "R" * 100_000)
    assert len(error_line(code, err)) < 600


# --------------------------------------------------------------------------- item 13: warnings and codec messages


def test_a_library_warning_is_one_line_of_ours_without_source(run_cli, tmp_path, monkeypatch):
    """Any warning a library raises during a command (numpy here) is one ``roughsense: warning:`` line."""
    import roughsense.analysis.magnitude_estimation as analysis

    aggregate = analysis.aggregate_ratings

    def noisy(*args, **kwargs):
        np.log(np.zeros(1))  # RuntimeWarning: divide by zero encountered in log
        return aggregate(*args, **kwargs)

    monkeypatch.setattr(analysis, "aggregate_ratings", noisy)
    ratings = tmp_path / "ratings.csv"
    pd.DataFrame({"participant": ["P01", "P01"], "session": [1, 1], "specimen": ["R2", "R4"],
                  "rating": ["1.0", "0.5"]}).to_csv(ratings, index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        code, _, err = run_cli("ratings", ratings, "--out", tmp_path / "agg.csv")
    assert code == 0, err
    lines = [line for line in err.splitlines() if "RuntimeWarning" in line]
    assert lines == [line for line in lines if line.startswith("roughsense: warning: RuntimeWarning: divide by zero")]
    assert len(lines) == 1 and "np.log" not in err and "test_noise.py:" in lines[0]


@pytest.mark.parametrize("modulus_pa", [1e-300, 1e308])
def test_an_absurd_pad_modulus_raises_no_numpy_warning(modulus_pa):
    """A grating pressed by a pad of absurd stiffness: one error of ours (or a solution), never numpy's warnings."""
    from roughsense.sim.contact import ContactNotConverged, solve_periodic_many

    x = np.linspace(0.0, 4.0, 400, endpoint=False)
    height = np.where(x % 2.0 < 1.0, 0.5, 0.0)  # rect:2 mm, 0.5 mm deep
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any numpy RuntimeWarning fails the test
        try:
            solve_periodic_many(height, 4.0, [2622.0], modulus_pa)
        except ContactNotConverged as exc:
            assert f"overflowed at iteration 1: a contact modulus of {modulus_pa:g} Pa" in str(exc)
        else:
            assert modulus_pa > 1  # an infinitely stiff pad is a solution: only the soft one overflows


def capture_args(video, out):
    return ("capture", "--source", video, "--out", out, "--specimen", "R3", "--pad", "fp", "--roi", "auto",
            "--shape", "rectangular", "--wavelength-mm", "3", "--repetitions", "1")


def test_capture_skips_a_damaged_frame_with_one_warning_and_no_ffmpeg_lines(tmp_path, monkeypatch, capfd):
    import io

    from roughsense.cli import main
    from roughsense.io.study import read_study

    video = write_damaged_video(tmp_path / "camera.avi", frame=1)
    clean = decoded_frames(write_video(tmp_path / "clean.avi"))
    monkeypatch.setattr("sys.stdin", io.StringIO("\n\n\n"))
    code = main([str(a) for a in capture_args(video, tmp_path / "study")])
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


# --------------------------------------------------------------------------- item 15: every error names its file


def test_a_camera_scale_below_nyquist_names_study_toml_and_the_key(run_cli, study, tmp_path):
    root = shutil.copytree(study, tmp_path / "study")
    toml = root / "study.toml"
    toml.write_text(toml.read_text().replace("px_per_mm = 34.9\n", "px_per_mm = 1.5\n", 1))
    code, _, err = run_cli("study", "--study", root, "--out", tmp_path / "report")
    assert error_line(code, err) == (
        f"roughsense: error: {toml}: [sensor] px_per_mm 1.5 is too coarse: its Nyquist frequency 0.75 mm^-1 is not "
        "above the band's f_max 1 mm^-1 (it must be above 2 px/mm)")


def test_a_full_disk_names_the_file_being_written(tmp_path, monkeypatch):
    from roughsense._util import atomic

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.os, "fsync", full)
    target = tmp_path / "out" / "summary.csv"
    with pytest.raises(RoughsenseError) as info:
        atomic.write_text(target, "a,b\n1,2\n")
    assert str(info.value) == f"{target}: cannot write: No space left on device"
    assert not target.exists() and list(target.parent.iterdir()) == []  # no temporary left behind


def test_a_full_disk_is_one_line_from_the_cli(run_cli, tmp_path, monkeypatch):
    from roughsense._util import atomic

    real_open = atomic.os.fdopen

    class Full:
        def __init__(self, handle):
            self.handle = handle

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.handle.close()

        def write(self, data):
            raise OSError(errno.ENOSPC, "No space left on device")

        def __getattr__(self, name):
            return getattr(self.handle, name)

    monkeypatch.setattr(atomic.os, "fdopen", lambda *a, **k: Full(real_open(*a, **k)))
    ratings = tmp_path / "ratings.csv"
    pd.DataFrame({"participant": ["P01", "P01"], "session": [1, 1], "specimen": ["R2", "R4"],
                  "rating": ["1.0", "0.5"]}).to_csv(ratings, index=False)
    out = tmp_path / "agg.csv"
    code, _, err = run_cli("ratings", ratings, "--out", out)
    assert error_line(code, err) == f"roughsense: error: {out}: cannot write: No space left on device"
