"""Ctrl-C (SIGINT) and ``kill`` (SIGTERM) as a request to stop, honoured at the next safe point.

Python's own handling raises ``KeyboardInterrupt`` wherever the main thread happens to be: inside a weakref
callback or a ``__del__`` it is printed as "Exception ignored" and swallowed, and the run goes on to write its
report and exit 0. So the handler only records the signal. The run looks at the record at safe points (each item
of a progress loop, each stage, and just before anything is committed: a file renamed into place, a folder
swapped in) and raises :class:`Interrupted` there; nothing is committed once a signal is recorded. A second
signal stops the run at once (``KeyboardInterrupt``), for a run stuck where no safe point comes.

Only the CLI installs the handler (:func:`install`); a library caller keeps Python's default behaviour.
"""
from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

_received: list[int] = []  # the signals recorded since install(), first first
_immediate: list[bool] = []  # non-empty while the main thread waits on a person or a device (see immediate())


class Interrupted(KeyboardInterrupt):
    """The run stopped at a safe point because of ``signum``; its exit code is 128 + ``signum``."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _record(signum: int, frame) -> None:
    _received.append(signum)
    if len(_received) > 1 or _immediate:  # asked twice, or waiting where nothing is being committed: stop now
        raise Interrupted(_received[0])


def install() -> None:
    """Record SIGTERM and SIGINT instead of raising; a SIGINT already ignored (a background run) stays ignored."""
    _received.clear()
    signal.signal(signal.SIGTERM, _record)
    if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        signal.signal(signal.SIGINT, _record)


def installed() -> bool:
    """Whether this process records signals (:func:`install`): a spawned worker is told, since it inherits nothing."""
    return signal.getsignal(signal.SIGTERM) is _record


def reset_in_worker() -> None:
    """In a forked worker of a run that installed the handler: the parent decides when to stop, so Ctrl-C (sent
    to the whole process group) is ignored, and SIGTERM ends the worker as usual."""
    if not installed():
        return
    _received.clear()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def requested() -> int | None:
    """The first signal recorded, or None."""
    return _received[0] if _received else None


def check() -> None:
    """A safe point: raise :class:`Interrupted` if a signal has been recorded."""
    if _received:
        raise Interrupted(_received[0])


def exit_code(default: int = 130) -> int:
    """The shell's code for a run ended by the recorded signal (130 for SIGINT, 143 for SIGTERM)."""
    return 128 + _received[0] if _received else default


@contextlib.contextmanager
def children_ignore_sigint() -> Iterator[None]:
    """While worker processes are started (a Dask cluster): Ctrl-C reaches the whole process group, and each worker
    would die printing its own traceback. A child started while SIGINT is ignored keeps it ignored (across exec
    too), so the stop is this process's alone: it closes them. A Ctrl-C in that moment is not seen; SIGTERM is."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) is not _record:
        yield
        return
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, _record)


@contextlib.contextmanager
def immediate() -> Iterator[None]:
    """A wait on a person or a device (an operator's answer, a scale, a camera's next frame), where nothing is being
    committed: a signal stops it at once, as Python's own Ctrl-C would, instead of at the next safe point."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    check()
    _immediate.append(True)
    try:
        yield
    finally:
        _immediate.pop()


def forget_sigint() -> None:
    """Ctrl-C was the expected way to end what just ended (a live display): not a stop request any more. A SIGTERM
    stays recorded."""
    if _received and _received[0] == signal.SIGINT:
        _received.clear()
