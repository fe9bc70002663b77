"""Review of issue 36's fixes (branch h-36r): variants of its attacks that still worked. Each test names what it
covers and fails on the merge of h-36 (75c83ab)."""
from __future__ import annotations

import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

HANG_GUARD_S = 300  # not a timing check: without the fix the child never ends, and the suite must


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


def test_a_sweep_of_few_but_long_cells_needs_yes_too(tmp_path):
    """36.11: the confirmation counted cells only, and a cell may render 20,000 frames: 30 cells of 19,500 frames
    (about 2.6 core-hours, more than 1000 paper-sized cells) started with no estimate."""
    from roughsense.errors import ConfigError
    from roughsense.explore.sweep import CELL_SECONDS_PER_FRAME, CONFIRM_CELLS, check_size_confirmed, read_sweep

    path = tmp_path / "sweep.toml"
    path.write_text(f"[sweep]\nseeds = {list(range(30))}\nrepetitions = 1300\n"
                    "specimens = ['R2', 'R3', 'R4', 'C3', 'rect:1.5']\nimage_size_px = [480, 160]\n[axes]\npad = ['smooth']\n")
    sweep = read_sweep(path)
    hours = 30 * 5 * 3 * 1300 * CELL_SECONDS_PER_FRAME / 3600
    assert len(sweep.cells) == 30 and hours > CONFIRM_CELLS * 420 * CELL_SECONDS_PER_FRAME / 3600
    with pytest.raises(ConfigError) as info:
        check_size_confirmed(sweep, yes=False, workers=2)
    assert str(info.value) == (f"{path}: 30 cells, about {hours:.1f} core-hours ({hours / 2:.1f} h on 2 workers): a sweep "
                               "of more than 1.9 core-hours (as long as 1000 paper-sized cells) runs only with --yes")
    estimate = f"30 cells, about {hours:.1f} core-hours ({hours / 2:.1f} h on 2 workers)"
    assert check_size_confirmed(sweep, yes=True, workers=2) == estimate


AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
from tests.as_user import NOBODY  # noqa: E402 (beside the tests that plant as another user)


@pytest.mark.skipif(not AS_ROOT, reason="a file of another user's needs root to make")
def test_a_cache_entry_swapped_after_its_check_is_not_trusted(tmp_path, monkeypatch):
    """36.4, the window the lstat checks leave: an entry that another user swaps in between ``foreign_reason``'s
    lstat and the read (through a cache root whose parent they can write) was read as results."""
    import pandas as pd

    from roughsense._util import cache

    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    mine, theirs = pd.DataFrame({"image": ["a.png"], "x": [1.0]}), pd.DataFrame({"image": ["a.png"], "x": [99.0]})
    cache.cached_frame("other", lambda: theirs)  # a well-formed entry, its checksum right, to plant as "mine"
    root = cache.usable_cache_dir()
    planted = tmp_path / "planted.csv"
    planted.write_bytes((root / "features" / "other.csv").read_bytes())
    os.chown(planted, NOBODY, NOBODY)
    cache.cached_frame("mine", lambda: mine)
    checked = cache.foreign_reason

    def check_then_swap(path, *, folder):
        reason = checked(path, folder=folder)
        if not folder and path.name == "mine.csv":
            os.replace(planted, path)  # the swap lands just after the check
        return reason

    monkeypatch.setattr(cache, "foreign_reason", check_then_swap)
    frame, was_cached = cache.cached_frame("mine", lambda: mine)
    assert not was_cached and frame["x"].tolist() == [1.0]


def test_a_cache_in_a_folder_others_may_write_without_the_sticky_bit_is_bypassed(tmp_path, monkeypatch):
    """36.4: the cache folder was checked, not the folder it lies in; where others may write that one (a shared
    project folder, mode 0777), they can rename the cache away and put their own in its place between two looks
    (the built-in study then built into, and read from, their folder)."""
    from roughsense._util import cache
    from roughsense.errors import RoughsenseWarning

    shared = tmp_path / "shared"
    shared.mkdir()
    os.chmod(shared, 0o777)
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(shared / "cache"))
    with pytest.warns(RoughsenseWarning, match=f"lies in {shared}, which other users can write without the sticky"):
        assert cache.usable_cache_dir() is None
    os.chmod(shared, 0o1777)  # as /tmp: only an entry's owner may rename it
    assert cache.usable_cache_dir() == shared / "cache"


def _study_with_an_image_outside_images(tmp_path):
    from .test_dataset import make_study

    root = make_study(tmp_path / "study", pads=("smooth",), repetitions=1)
    first = sorted((root / "images").iterdir())[0]
    (root / "raw").mkdir()
    moved = root / "raw" / first.name
    first.rename(moved)
    manifest = root / "manifest.csv"
    manifest.write_text(manifest.read_text().replace(f"images/{first.name}", f"raw/{first.name}"))
    return root, moved


@pytest.mark.parametrize("command", ["features", "predict", "fit", "study"])
def test_no_output_may_be_an_image_the_manifest_lists_outside_images(run_cli, tmp_path, command):
    """36.2/36.3's rule, "every path a run writes is checked against every path it reads": the inputs of --study
    were its four tables and images/, so `features --study S -o S/raw/x.png --force` replaced a study image that
    the manifest lists at raw/x.png (manifest paths are relative to the folder, anywhere in it)."""
    from .commands import LEGACY_MODEL, error_line

    root, image = _study_with_an_image_outside_images(tmp_path)
    before = image.read_bytes()
    out = image.parent if command == "study" else image
    args = {"features": ["features", "--study", root, "-o", out],
            "predict": ["predict", LEGACY_MODEL, "--study", root, "-o", out],
            "fit": ["fit", "--study", root, "--pad", "smooth", "--condition", "2N", "-o", out],
            "study": ["study", "--study", root, "--out", out]}[command]
    code, _, err = run_cli(*args, "--force")
    assert code == 2 and image.read_bytes() == before
    line = error_line(err)
    assert line.startswith(f"roughsense: error: --out {out} is ") and f"{image}; choose another path" in line


def test_a_stop_while_features_draws_its_plot_leaves_no_csv_behind(run_cli, tmp_path, monkeypatch):
    """36.5's "never commits after it" for a run of several outputs: features wrote its CSV and grid file, then drew
    --plot, so a SIGTERM (or a failure) while drawing left the CSV without the plot it was asked for."""
    import signal

    from roughsense._util import interrupt
    from roughsense.report import figures

    from .commands import grating_png

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    interrupt.install()
    real = figures.figure_bytes

    def signalled(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)  # arrives while the figure is drawn
        return real(*args, **kwargs)

    monkeypatch.setattr(figures, "figure_bytes", signalled)
    image = grating_png(tmp_path / "in.png")
    try:
        code, _, err = run_cli("features", image, "-o", tmp_path / "x.csv", "--plot", tmp_path / "plot.png")
    finally:
        for number, handler in saved.items():
            signal.signal(number, handler)
        interrupt._received.clear()
    assert code == 143 and err == "roughsense: interrupted\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png"]


def test_simulate_force_over_a_folder_whose_manifest_is_a_fifo_does_not_hang(tmp_path):
    """36.6's rule for the readers that inspect an output folder before replacing it (sim/overwrite.py,
    io/writer.py): `simulate --out S --force` opened S/manifest.csv by name, so a FIFO there hung the run before any
    safe point, and one SIGTERM did not end it."""
    roughsense = os.path.join(os.path.dirname(sys.executable), "roughsense")
    args = [roughsense, "simulate", "--out", str(tmp_path / "s"), "--pads", "smooth", "--specimens", "R2,R3",
            "--forces-n", "1", "--repetitions", "2", "--jobs", "1"]
    env = {**os.environ, "ROUGHSENSE_CACHE_DIR": str(tmp_path / "cache")}
    assert subprocess.run(args, capture_output=True, env=env, timeout=HANG_GUARD_S).returncode == 0
    manifest = tmp_path / "s" / "manifest.csv"
    manifest.unlink()
    os.mkfifo(manifest)
    done = subprocess.run([*args, "--force"], capture_output=True, text=True, env=env, timeout=HANG_GUARD_S)
    assert done.returncode == 0 and "Traceback" not in done.stderr
    assert manifest.is_file() and manifest.read_text().startswith("image,specimen,pad,force_n")
