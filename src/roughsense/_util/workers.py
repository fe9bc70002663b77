"""How many workers this process may run, and worker processes that die with the process that started them.

Cores are counted once, here (:func:`usable_cores`): the share of the machine this process may run on (a container's
or taskset's CPU affinity), which ``os.cpu_count()`` ignores.

A ``kill -9`` of ``roughsense simulate`` gives its pool no chance to shut down: without help, the workers keep
rendering into the folder, then idle for ever. Each worker therefore ties its life to its parent's: on Linux the
kernel sends it SIGKILL when the parent dies (``prctl(PR_SET_PDEATHSIG)``); elsewhere a daemon thread polls the
parent id. Both check that the parent is still the one that started the worker, since it may have died before
the worker got that far.

Linux delivers the signal when the *thread* that forked the worker ends, so a pool must be used from a thread
that outlives it (the CLI uses it from the main thread; ``ProcessPoolExecutor`` forks its workers in the thread
that submits the first task).
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import time
from typing import TYPE_CHECKING

from . import interrupt

if TYPE_CHECKING:  # imported where a pool is made: counting cores (the CLI's --jobs) stays light
    from concurrent.futures import ProcessPoolExecutor

PARENT_POLL_S = 0.5
_PR_SET_PDEATHSIG = 1


def usable_cores() -> int:
    """The cores this process may run on (a container's or taskset's share, not the machine's)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _arm_parent_death_signal() -> bool:
    """Ask Linux to SIGKILL this process when its parent dies; False where that is not available."""
    if not sys.platform.startswith("linux"):
        return False
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(PARENT_POLL_S)
        if os.getppid() != parent_pid:
            os._exit(1)


def die_with_parent(parent_pid: int) -> None:
    """Pool initializer: end this worker as soon as ``parent_pid`` is no longer its parent."""
    interrupt.reset_in_worker()
    armed = _arm_parent_death_signal()
    if os.getppid() != parent_pid:  # the parent died before the signal was armed (or we were re-parented)
        os._exit(1)
    if not armed:
        threading.Thread(target=_watch_parent, args=(parent_pid,), name="roughsense-parent-watch", daemon=True).start()


def process_pool(max_workers: int) -> ProcessPoolExecutor:
    """A ``ProcessPoolExecutor`` whose workers end within about a second of this process's death."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    # fork (Linux) or spawn: either way the worker's parent is this process, which the initializer checks.
    method = "fork" if sys.platform.startswith("linux") else "spawn"
    return ProcessPoolExecutor(max_workers=max_workers, mp_context=multiprocessing.get_context(method),
                               initializer=die_with_parent, initargs=(os.getpid(),))
