"""What a run may trust on disk: its own leftovers, and regular files to read.

In a folder other users can write (``/tmp``, a shared project folder), a name roughsense would recognise as its
own (a retired folder, a lock record, a cache entry) can be planted by someone else: a symbolic link to the
victim's private folder, a FIFO that blocks the first ``open``, a file of the attacker's. So a leftover is used
only when ``lstat`` shows it is of the expected type and owned by the running user (:func:`foreign_reason`), and
a file is read only when it is a regular file, opened without blocking and checked with ``fstat`` on the open
descriptor (:func:`open_regular`): the check and the read are about the same file, even if the name is swapped
between them.
"""
from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from ..errors import InputError

_KINDS = {stat.S_IFDIR: "a folder", stat.S_IFREG: "a file", stat.S_IFLNK: "a symbolic link",
          stat.S_IFIFO: "a FIFO (named pipe)", stat.S_IFSOCK: "a socket", stat.S_IFCHR: "a device",
          stat.S_IFBLK: "a device"}


def kind_of(mode: int) -> str:
    """A file type in words, for a message: "a FIFO (named pipe)", "a symbolic link"."""
    return _KINDS.get(stat.S_IFMT(mode), "not a regular file")


def foreign_reason(path: str | os.PathLike[str], *, folder: bool) -> str | None:
    """Why ``path`` cannot be a leftover of this user's runs (a folder if ``folder``, else a regular file), or None.

    ``lstat`` does not follow a link, so a planted link is seen as a link, never as what it points to.
    """
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return None
    want = stat.S_IFDIR if folder else stat.S_IFREG
    if stat.S_IFMT(info.st_mode) != want:
        return f"is {kind_of(info.st_mode)}, not {_KINDS[want]}"
    if info.st_uid != os.geteuid():
        return f"belongs to another user (uid {info.st_uid})"
    return None


def open_regular(path: str | os.PathLike[str], *, what: str = "file", own: bool = False) -> int:
    """A read-only descriptor of ``path`` if it is a regular file, else :class:`InputError` naming its type.

    Opened with ``O_NONBLOCK``, so a FIFO returns at once instead of waiting for a writer; the type is checked on
    the descriptor (``fstat``), then blocking mode is restored for the read. With ``own``, a file of another user's
    is refused too, on the descriptor: what an earlier ``lstat`` saw may have been swapped since.
    """
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        if exc.errno not in (errno.ENXIO, errno.EOPNOTSUPP):  # a socket cannot be opened at all: name it as one
            raise
        raise _not_regular(path, os.stat(path).st_mode, what) from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise _not_regular(path, info.st_mode, what)
        if own and info.st_uid != os.geteuid():
            raise InputError(f"belongs to another user (uid {info.st_uid}), not a {what} of yours", path=Path(path))
        os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd


def _not_regular(path, mode: int, what: str) -> InputError:
    return InputError(f"is {kind_of(mode)}, not a regular {what}; give the {what} itself", path=Path(path))


def read_regular(path: str | os.PathLike[str], *, limit: int | None = None, what: str = "file",
                 own: bool = False) -> bytes:
    """The bytes of the regular file ``path`` (at most ``limit``), by :func:`open_regular`."""
    with os.fdopen(open_regular(path, what=what, own=own), "rb") as handle:
        return handle.read() if limit is None else handle.read(limit)
