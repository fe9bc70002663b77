"""_util/files.py: only regular files are read; a FIFO or a device is refused at once, by its kind, naming the file."""
from __future__ import annotations

import os
import subprocess

import pytest

from tests.commands import HANG_GUARD_S, LEGACY_MODEL, ROUGHSENSE, error_line, grating_png


@pytest.mark.parametrize("command", ["predict", "features", "predict-model"])
def test_a_fifo_given_as_an_image_or_a_model_is_refused_at_once(tmp_path, command):
    """36.6: a FIFO as an image hung predict and features (one SIGTERM did not end it)."""
    fifo = tmp_path / ("m.json" if command == "predict-model" else "in.png")
    os.mkfifo(fifo)
    image = fifo if command != "predict-model" else grating_png(tmp_path / "in.png")
    args = {"predict": ["predict", LEGACY_MODEL, image], "features": ["features", image, "-o", tmp_path / "x.csv"],
            "predict-model": ["predict", fifo, image]}[command]
    done = subprocess.run([ROUGHSENSE, *map(str, args)], capture_output=True, text=True, timeout=HANG_GUARD_S,
                          env={**os.environ, "ROUGHSENSE_CACHE_DIR": str(tmp_path / "cache")})
    assert done.returncode == 2
    assert error_line(done.stderr) == f"roughsense: error: {fifo}: is a FIFO (named pipe), not a regular " + (
        "model file; give the model file itself" if command == "predict-model" else
        "image file; give the image file itself")


def test_a_link_to_a_device_is_named_as_a_device(run_cli, tmp_path):
    """Also seen: a symlink to /dev/zero was "image file is empty"."""
    link = tmp_path / "zero.png"
    link.symlink_to("/dev/zero")
    code, _, err = run_cli("features", link, "-o", tmp_path / "x.csv")
    assert code == 2 and error_line(err).endswith(f"{link}: is a device, not a regular image file; give the image "
                                                  "file itself")
