"""_util/files.py: only regular files are read; a FIFO or a device is refused at once, by its kind, naming the file."""
from __future__ import annotations

import os
import subprocess

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.commands import HANG_GUARD_S, LEGACY_MODEL, ROUGHSENSE, error_line, grating_png
from tests.fuzzing import EXAMPLES, FUZZ


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


@pytest.mark.slow
@settings(FUZZ, max_examples=max(40, EXAMPLES // 2))
@given(kind=st.sampled_from(("regular", "empty", "folder", "fifo", "link to fifo", "device", "socket")),
       reader=st.sampled_from(("image", "table", "model", "sweep")))
def test_only_regular_files_are_read_and_nothing_waits(tmp_path_factory, kind, reader):
    """36.6: images, tables, model and sweep files are read only as regular files; a FIFO, a device or a socket is
    one error naming its type, at once (a FIFO without a writer would block an ordinary open)."""
    import socket

    from roughsense.errors import RoughsenseError
    from roughsense.explore.sweep import read_sweep
    from roughsense.io.csv_read import read_table
    from roughsense.io.images import read_image
    from roughsense.model.modelfile import load_model

    root = tmp_path_factory.mktemp("kinds")
    path = root / "thing"
    keep = None
    if kind in ("regular", "empty"):
        path.write_bytes(b"" if kind == "empty" else b"c0\n1\n")
    elif kind == "folder":
        path.mkdir()
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "link to fifo":
        os.mkfifo(root / "pipe")
        path.symlink_to(root / "pipe")
    elif kind == "device":
        path.symlink_to("/dev/null")
    else:
        keep = socket.socket(socket.AF_UNIX)
        keep.bind(str(path))
    read = {"image": read_image, "table": lambda p: read_table(p, []), "model": load_model, "sweep": read_sweep}[reader]
    try:
        read(path)
    except RoughsenseError as exc:
        if kind not in ("regular", "empty"):
            words = {"folder": "a folder", "fifo": "FIFO", "link to fifo": "FIFO", "device": "a device",
                     "socket": "a socket"}[kind]
            assert words in str(exc), str(exc)
    finally:
        if keep is not None:
            keep.close()


def test_a_files_kind_is_named_from_its_mode_and_only_a_regular_files_bytes_are_read(tmp_path):
    """The kind in words is lstat's, never the link target's; read_regular returns the file's bytes, up to a limit."""
    import stat

    from roughsense._util.files import foreign_reason, kind_of, read_regular
    from roughsense.errors import InputError

    regular = tmp_path / "a.csv"
    regular.write_bytes(b"x,y\n1,2\n")
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "link").symlink_to(regular)
    assert kind_of(os.lstat(tmp_path / "pipe").st_mode) == "a FIFO (named pipe)"
    assert kind_of(os.lstat(tmp_path / "link").st_mode) == "a symbolic link"
    assert kind_of(os.lstat(tmp_path).st_mode) == "a folder" and kind_of(stat.S_IFREG) == "a file"
    assert foreign_reason(regular, folder=False) is None and foreign_reason(tmp_path / "gone", folder=True) is None
    assert foreign_reason(tmp_path / "link", folder=False) == "is a symbolic link, not a file"
    assert read_regular(regular) == b"x,y\n1,2\n" and read_regular(regular, limit=3) == b"x,y"
    with pytest.raises(InputError, match="is a FIFO \\(named pipe\\), not a regular table; give the table itself"):
        read_regular(tmp_path / "pipe", what="table")
