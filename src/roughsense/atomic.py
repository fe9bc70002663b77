"""Atomic writes: a failed run must never leave a partial file behind.

Everything is written to a temporary file in the destination folder and then renamed over the
target with :func:`os.replace`, which is atomic on POSIX within one file system.
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from .errors import OutputExistsError, RoughsenseError


def _default_file_mode() -> int:
    """The mode ``open()`` would give a new file (0666 minus the umask); mkstemp alone gives 0600."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def check_can_write(path: str | os.PathLike[str], *, force: bool = False) -> Path:
    """Refuse to replace an existing file unless ``force``: user data is never overwritten silently."""
    target = Path(path)
    if target.exists() and not force:
        raise OutputExistsError("already exists; pass --force to replace it", path=target)
    if target.exists() and target.is_dir():
        raise OutputExistsError("is a folder, expected a file path", path=target)
    return target


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w", **kwargs) -> Iterator[IO]:
    """Open a temporary sibling of ``path``; on clean exit fsync and rename it into place."""
    if mode not in ("w", "wb"):
        raise ValueError("atomic_open only writes whole files ('w' or 'wb')")
    target = Path(path)
    parent = target.parent if str(target.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=parent)
    except OSError as exc:
        raise RoughsenseError(f"cannot write: {exc.strerror or exc}", path=target) from exc
    tmp = Path(tmp_name)
    try:
        os.chmod(tmp, _default_file_mode())
        if "b" in mode:
            handle = os.fdopen(fd, mode)
        else:
            kwargs.setdefault("encoding", "utf-8")
            kwargs.setdefault("newline", "")
            handle = os.fdopen(fd, mode, **kwargs)
        with handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    with atomic_open(path, "wb") as handle:
        handle.write(data)
    return Path(path)


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    with atomic_open(path, "w", newline="\n") as handle:
        handle.write(text)
    return Path(path)


def write_csv(path: str | os.PathLike[str], frame, **to_csv_kwargs) -> Path:
    """Write a pandas DataFrame as CSV atomically (no index unless asked)."""
    to_csv_kwargs.setdefault("index", False)
    to_csv_kwargs.setdefault("lineterminator", "\n")
    with atomic_open(path, "w") as handle:
        frame.to_csv(handle, **to_csv_kwargs)
    return Path(path)
