"""One writer per output folder: a command that writes ``--out`` holds a lock on it for its whole run.

Two runs into one folder each write whole files, yet leave a folder that is neither's (an explore folder holding
the cells of two sweeps under one sweep.toml, a capture's frames beside a simulation's). So the second run is
refused at once, with one line naming the first (its PID, host and start time).

The lock lives *beside* the folder, not inside it: simulate, study and example swap the whole folder, which would
carry a lock inside along with it. Two files: ``filelock`` holds the kernel's lock on
``.NAME.roughsense-lock.flock`` (an ``flock`` the OS drops however the process ends, even kill -9; on a file system
without one, filelock's marker file, broken when its PID is gone), and ``.NAME.roughsense-lock`` records who holds
it (PID, host, start time) so a refused run can say whom it waits for. The record is kept apart because filelock
owns its file's content. A record found when the lock is free is a dead run's: it is taken over, with a warning
naming it.
"""
from __future__ import annotations

import contextlib
import json
import os
import socket
import stat
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import filelock

from ..errors import RoughsenseError, RoughsenseWarning
from .atomic import FLOCK_SUFFIX, LOCK_TAG
from .files import kind_of

_READ_WAIT_S = 1.0  # a holder that has just taken the lock writes its record within milliseconds
_RETRY_S = 0.2  # a lock file removed by a run letting go as we took it: filelock tries again on the new one
_SHARED_MODE = 0o666  # the lock file any user may lock: two users writing one shared folder wait for each other
_HELD: dict[Path, int] = {}  # locks this process holds: a command's library call may take its CLI's lock again


class OutputBusyError(RoughsenseError):
    """Another run is writing the same output folder."""


@dataclass(frozen=True)
class Holder:
    """What a lock's record says about the run that made it."""

    pid: int | None
    host: str = "?"
    started: str = "?"
    command: str = "roughsense"

    def describe(self) -> str:
        if self.pid is None:
            return self.command
        return f"{self.command}, PID {self.pid} on {self.host}, started {self.started}"


def lock_path(out: str | os.PathLike[str]) -> Path:
    """The lock's record of ``out``: beside the real folder, so every spelling of one folder shares one lock."""
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


def _read(path: Path) -> bytes:
    """The record's bytes (at most 4 kB); empty if there is none. Only a regular file is read (opened without
    blocking or following a link): a FIFO planted under the record's name would otherwise hang the run."""
    _refuse_planted(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return b""
    with os.fdopen(fd, "rb") as handle:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # swapped in after the lstat
            _refuse_planted(path, os.fstat(fd).st_mode)
        return handle.read(4096)


def _refuse_planted(path: Path, mode: int | None = None) -> None:
    """A lock file that is not a regular file (a link, a FIFO) was not made by roughsense: refused, naming it."""
    if mode is None:
        try:
            mode = os.lstat(path).st_mode
        except OSError:
            return
    if not stat.S_ISREG(mode):
        raise RoughsenseError(f"the lock file {path} is {kind_of(mode)}, not a file a roughsense run made; delete "
                              "it if no run is writing this folder", path=path.parent)


class OutputLock:
    """``with OutputLock(out, command="explore"):`` -- the run's claim on ``out``, released on any exit."""

    def __init__(self, out: str | os.PathLike[str], *, command: str = "") -> None:
        self.out = Path(out)
        self.path = lock_path(out)
        self.command = command
        self._lock: filelock.BaseFileLock | None = None
        self._owner = os.getpid()

    def __enter__(self) -> OutputLock:
        self.acquire()
        return self

    def __exit__(self, *exc_info) -> None:
        self.release()

    def acquire(self) -> None:
        if _HELD.get(self.path) == os.getpid():
            return  # this process already holds it (the CLI around the library): nothing to take
        _refuse_planted(_flock_path(self.path))  # filelock would follow a link, or fail with the OS's bare words
        lock = filelock.FileLock(_flock_path(self.path), timeout=_RETRY_S, mode=_SHARED_MODE)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # filelock's note when it falls back to a marker file: the record says who
                lock.acquire()
        except filelock.Timeout:
            if not os.path.lexists(lock.lock_file):  # no run holds a file there: the place would not let one be made
                self._refuse_place(lock.lock_file)
            raise self._busy(self._wait_for_holder()) from None
        except PermissionError as exc:
            if not os.path.lexists(lock.lock_file):
                self._refuse_place(lock.lock_file, exc)
            raise self._foreign(lock.lock_file) from None
        except OSError as exc:
            self._refuse_place(lock.lock_file, exc)
        try:
            self._take()
        except BaseException:
            lock.release()
            _remove_if_free(_flock_path(self.path))
            raise
        self._lock = lock
        _HELD[self.path] = os.getpid()

    def _refuse_place(self, path: str, exc: OSError | None = None) -> None:
        """The lock file cannot be made beside ``out``: one line with the OS's reason (asked again if not known)."""
        if exc is None:
            try:
                os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o666))
                os.unlink(path)
            except OSError as error:
                exc = error
            else:  # it can be made after all: a run was letting go as we looked
                raise self._busy(self._wait_for_holder())
        if isinstance(exc, PermissionError):
            raise RoughsenseError(
                f"cannot create the lock file {self.path.name} beside it in {self.path.parent}: permission denied "
                "(a run locks its output from the parent folder; choose an --out whose parent you can write)",
                path=self.out) from None
        raise RoughsenseError(f"cannot write here: {exc.strerror or exc}", path=self.out) from None

    def _foreign(self, flock_file: str) -> RoughsenseError:
        """Another user's lock file we may not open: their run, if its record says so, else one that has ended."""
        holder = _parse(_read(self.path))
        if holder is not None:
            return self._busy(holder)
        return RoughsenseError(f"cannot lock it: {flock_file} beside it belongs to another user and is not writable "
                               "by you; if no run is writing this folder, delete that file", path=self.out)

    def _wait_for_holder(self) -> Holder | None:
        """The holder's record; a holder that took the lock a moment ago may not have written it yet."""
        deadline = time.monotonic() + _READ_WAIT_S
        while (holder := _parse(_read(self.path))) is None and time.monotonic() < deadline:
            time.sleep(0.02)
        return holder

    def _busy(self, holder: Holder | None) -> OutputBusyError:
        who = holder.describe() if holder is not None else "its PID not yet written"
        return OutputBusyError(f"another run is writing this folder ({who}); wait for it to end, or stop it",
                               path=self.out)

    def _take(self) -> None:
        """Write our record over a dead run's (saying so): with the lock ours, any record left is from a run that ended."""
        if stale_text := _read(self.path):
            stale = _parse(stale_text) or Holder(None, command=f"its lock file {self.path.name} did not read back")
            warnings.warn(RoughsenseWarning(
                f"{self.out}: took over the lock of a run that has ended ({stale.describe()}); a folder it was "
                "writing is checked as usual"), stacklevel=4)
        started = datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
        text = json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "started": started,
                           "command": f"roughsense {self.command}".strip()})
        try:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.path)  # another user's record cannot be rewritten in place, but can be replaced
            fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o666)
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                handle.write(text + "\n")
        except OSError as exc:
            raise RoughsenseError(f"cannot write here: {exc.strerror or exc} (the lock file {self.path} of a run "
                                  "that has ended; delete it)", path=self.out) from None

    def release(self) -> None:
        """Remove the record, then let go (in that order, so the next run never finds our record and takes it for
        a dead run's)."""
        lock, self._lock = self._lock, None
        if lock is None or os.getpid() != self._owner:
            return
        _HELD.pop(self.path, None)
        try:
            with contextlib.suppress(OSError):
                os.unlink(self.path)
        finally:
            lock.release()
            _remove_if_free(_flock_path(self.path))


def _flock_path(record: Path) -> Path:
    return record.with_name(record.name + FLOCK_SUFFIX)


def _remove_if_free(path: Path) -> None:
    """Delete filelock's file (which it keeps) when no run holds it, so a finished run leaves nothing beside ``out``.

    It is taken again and unlinked while held: a run that opened it a moment before locks a file that is gone,
    which filelock notices and retries on a new one (within ``_RETRY_S``).
    """
    probe = filelock.FileLock(path, timeout=0, mode=_SHARED_MODE)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            probe.acquire()
    except (filelock.Timeout, OSError):
        return  # another run has it now
    try:
        with contextlib.suppress(OSError):
            os.unlink(path)
    finally:
        probe.release()


@contextlib.contextmanager
def output_lock(out: str | os.PathLike[str], *, command: str = "") -> Iterator[OutputLock]:
    """Hold ``out``'s lock for the ``with`` block: a second run into ``out`` is refused with one line naming this one."""
    lock = OutputLock(out, command=command)
    lock.acquire()
    try:
        yield lock
    finally:
        lock.release()
