"""One writer per output folder: a command that writes ``--out`` holds a lock on it for its whole run.

Two runs into one folder each write whole files, yet leave a folder that is neither's (an explore folder holding
the cells of two sweeps under one sweep.toml, a capture's frames beside a simulation's). So the second run is
refused at once, with one line naming the first (its PID, host and start time).

The lock is a file *beside* the folder, ``.NAME.roughsense-lock``, not inside it: simulate, study and example swap
the whole folder, which would carry a lock inside along with it. Who holds it is the kernel's answer, not the
file's: the holder keeps an ``flock`` on the file, which the OS drops however the process ends (even kill -9),
so a lock file that nobody holds is a dead run's and is taken over, with a warning naming it. The file's text
(PID, host, start time) only tells the refused run whom it waits for. Where a file system has no ``flock``, a
lock whose PID is not alive on this host counts as dead.
"""
from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import socket
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from ..errors import RoughsenseError, RoughsenseWarning
from .atomic import LOCK_TAG, _pid_alive

_ATTEMPTS = 20  # a holder releasing between our open and our flock: try again on the new file
_READ_WAIT_S = 1.0  # a holder that has just taken the file writes its PID within milliseconds
_NO_FLOCK = (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL)
_HELD: dict[Path, int] = {}  # lock files this process holds: a command's library call may take its CLI's lock again


class OutputBusyError(RoughsenseError):
    """Another run is writing the same output folder."""


@dataclass(frozen=True)
class Holder:
    """What a lock file says about the run that made it."""

    pid: int | None
    host: str = "?"
    started: str = "?"
    command: str = "roughsense"

    def describe(self) -> str:
        if self.pid is None:
            return self.command
        return f"{self.command}, PID {self.pid} on {self.host}, started {self.started}"


def lock_path(out: str | os.PathLike[str]) -> Path:
    """The lock file of ``out``: beside the real folder, so every spelling of one folder shares one lock."""
    real = Path(os.path.realpath(os.path.abspath(out)))
    return real.parent / f".{real.name}{LOCK_TAG}"


def _parse(text: bytes) -> Holder | None:
    try:
        data = json.loads(text.decode("utf-8"))
        pid = data.get("pid")
        return Holder(pid if isinstance(pid, int) and not isinstance(pid, bool) and pid > 0 else None,
                      str(data.get("host", "?"))[:100], str(data.get("started", "?"))[:40],
                      str(data.get("command", "roughsense"))[:60])
    except (ValueError, AttributeError, UnicodeDecodeError, RecursionError):
        return None


def _read(fd: int) -> Holder | None:
    return _parse(os.pread(fd, 4096, 0)) if os.fstat(fd).st_size else None


def _flock(fd: int) -> bool | None:
    """True: the lock is ours; False: a live process holds it; None: this file system has no flock."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError as exc:
        if exc.errno in _NO_FLOCK:
            return None
        raise
    return True


def _same_file(fd: int, path: Path) -> bool:
    """Is the file we locked still the one at ``path``? (A releasing holder unlinks it before letting go.)"""
    try:
        here, ours = os.stat(path, follow_symlinks=False), os.fstat(fd)
    except FileNotFoundError:
        return False
    return (here.st_dev, here.st_ino) == (ours.st_dev, ours.st_ino)


class OutputLock:
    """``with OutputLock(out, command="explore"):`` -- the run's claim on ``out``, released on any exit."""

    def __init__(self, out: str | os.PathLike[str], *, command: str = "") -> None:
        self.out = Path(out)
        self.path = lock_path(out)
        self.command = command
        self._fd: int | None = None
        self._owner = os.getpid()
        self._nested = False

    def __enter__(self) -> OutputLock:
        self.acquire()
        return self

    def __exit__(self, *exc_info) -> None:
        self.release()

    def acquire(self) -> None:
        if self.path in _HELD and _HELD[self.path] == os.getpid():
            self._nested = True  # this process already holds it (the CLI around the library): nothing to take
            return
        for _ in range(_ATTEMPTS):
            fd = self._open()
            try:
                taken = _flock(fd)
                if taken is False:
                    raise self._busy(self._wait_for_holder(fd))
                if taken is None:
                    self._check_without_flock(fd)
                if taken and not _same_file(fd, self.path):
                    os.close(fd)
                    continue
                self._take(fd)
                return
            except BaseException:
                if self._fd != fd:
                    with contextlib.suppress(OSError):
                        os.close(fd)
                raise
        raise OutputBusyError("another run keeps taking and releasing this folder's lock; try again", path=self.out)

    def _open(self) -> int:
        flags = os.O_NOFOLLOW | os.O_CLOEXEC
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            try:
                return os.open(self.path, os.O_RDWR | os.O_CREAT | flags, 0o666)
            except PermissionError:  # another user's lock file: reading it is enough to name its holder
                if not self.path.exists():
                    raise PermissionError(errno.EACCES, os.strerror(errno.EACCES)) from None
                return os.open(self.path, os.O_RDONLY | flags)
        except PermissionError:
            raise RoughsenseError(
                f"cannot create the lock file {self.path.name} beside it in {self.path.parent}: permission denied "
                "(a run locks its output from the parent folder; choose an --out whose parent you can write)",
                path=self.out) from None
        except OSError as exc:
            raise RoughsenseError(f"cannot write here: {exc.strerror or exc}", path=self.out) from None

    def _wait_for_holder(self, fd: int) -> Holder | None:
        """The holder's details; a holder that took the file a moment ago may not have written them yet."""
        deadline = time.monotonic() + _READ_WAIT_S
        while (holder := _read(fd)) is None and time.monotonic() < deadline:
            time.sleep(0.02)
        return holder

    def _busy(self, holder: Holder | None) -> OutputBusyError:
        who = holder.describe() if holder is not None else "its PID not yet written"
        return OutputBusyError(f"another run is writing this folder ({who}); wait for it to end, or stop it",
                               path=self.out)

    def _check_without_flock(self, fd: int) -> None:
        """No flock here: a PID alive on this host (or any PID on another host, which cannot be asked) holds it."""
        holder = _read(fd)
        if holder is None or holder.pid is None:
            return
        if holder.host != socket.gethostname():
            raise OutputBusyError(f"another run may be writing this folder ({holder.describe()}); if it is not "
                                  f"running, delete {self.path}", path=self.out)
        if _pid_alive(holder.pid) and holder.pid != os.getpid():
            raise self._busy(holder)

    def _take(self, fd: int) -> None:
        """Write our details over a dead run's (saying so), and keep the file open: the flock lives with it."""
        if os.fstat(fd).st_size:  # a dead run's file (a live run's is held, a released one removed)
            stale = _read(fd) or Holder(None, command=f"its lock file {self.path.name} did not read back")
            warnings.warn(RoughsenseWarning(
                f"{self.out}: took over the lock of a run that has ended ({stale.describe()}); a folder it was "
                "writing is checked as usual"), stacklevel=4)
        started = datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
        text = json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "started": started,
                           "command": f"roughsense {self.command}".strip()})
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, (text + "\n").encode("utf-8"), 0)
        except OSError as exc:
            raise RoughsenseError(f"cannot write here: {exc.strerror or exc} (the lock file {self.path} of a run "
                                  "that has ended; delete it)", path=self.out) from None
        self._fd = fd
        _HELD[self.path] = os.getpid()

    def release(self) -> None:
        """Remove the file, then let go (in that order, so a waiting run never locks a file already removed)."""
        fd, self._fd = self._fd, None
        if fd is None or os.getpid() != self._owner:
            return
        _HELD.pop(self.path, None)
        try:
            if _same_file(fd, self.path):
                with contextlib.suppress(OSError):
                    os.unlink(self.path)
        finally:
            os.close(fd)


@contextlib.contextmanager
def output_lock(out: str | os.PathLike[str], *, command: str = "") -> Iterator[OutputLock]:
    """Hold ``out``'s lock for the ``with`` block: a second run into ``out`` is refused with one line naming this one."""
    lock = OutputLock(out, command=command)
    lock.acquire()
    try:
        yield lock
    finally:
        lock.release()
