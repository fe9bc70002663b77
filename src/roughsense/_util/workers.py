"""The one home of parallel work inside a process: how many workers it may run, a thread map, and worker processes
that die with the process that started them -- all on joblib and its loky executor.

Cores are counted by ``joblib.cpu_count()``: the share of the machine this process may run on (CPU affinity and a
container's cgroup quota), which the standard library's count of the machine's CPUs ignores.

A ``kill -9`` of ``roughsense simulate`` gives its pool no chance to shut down, and loky promises no quick end to
orphaned workers: without help they keep rendering into the folder. Each worker therefore ties its life to its
parent's: on Linux the kernel sends it SIGKILL when the parent dies (``prctl(PR_SET_PDEATHSIG)``); elsewhere a
daemon thread polls the parent id. Both check that the parent is still the one that started the worker, since it may
have died before the worker got that far. Linux delivers the signal when the *thread* that started the worker ends;
loky starts them in the thread that submits first (or its manager thread, which lives as long as the pool), so a pool
is used from a thread that outlives it (the CLI's main thread).

loky's workers are spawned, not forked: they inherit no signal handler, warning filter or module global. What a task
needs travels in its arguments or is set up by the modules it imports (matplotlib's backend is chosen by
``report/figures.py`` on import). What a fork passed on and a run relies on is handed to the initializer: whether
Ctrl-C is the parent's to honour, and the warning filters and display hook in force when the pool is made (the CLI's
one-line warnings, a warning a task raises said as the parent would say it).
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING, TypeVar

from . import interrupt

if TYPE_CHECKING:  # imported where a pool is made: counting cores (the CLI's --jobs) stays light (joblib imports NumPy)
    from concurrent.futures import Executor

PARENT_POLL_S = 0.5
_PR_SET_PDEATHSIG = 1

T = TypeVar("T")
R = TypeVar("R")


#: ``--jobs`` (``n_jobs`` in Python) above this many per usable core only queues work (and simulate would fork that
#: many processes at once).
MAX_JOBS_PER_CORE = 4


def usable_cores() -> int:
    """The cores this process may run on (its affinity and cgroup quota, not the machine's)."""
    from joblib import cpu_count

    return max(1, cpu_count())


class _Raised:
    """An exception a task raised, carried back as its result so that :func:`thread_map` raises it in item order."""

    __slots__ = ("error",)

    def __init__(self, error: BaseException) -> None:
        self.error = error


def _caught(fn: Callable[[T], R]) -> Callable[[T], R | _Raised]:
    def call(item: T) -> R | _Raised:
        try:
            return fn(item)
        except Exception as error:  # raised in the caller's thread, in order, as a plain loop would
            return _Raised(error)
    return call


def thread_map(fn: Callable[[T], R], items: Iterable[T], n_jobs: int) -> Iterator[R]:
    """``map(fn, items)`` over ``n_jobs`` threads: results in item order, at most 2 x ``n_jobs`` items handed out
    beyond those finished (joblib's ``pre_dispatch``; finished results wait for a slower consumer, their inputs do not).

    For work that releases the GIL (decoding, NumPy). The first failing item raises its own exception once every item
    before it has been yielded, whichever thread finished first, so the error named is the one a plain loop names.
    joblib takes items after the first 2 x ``n_jobs`` from its threads: ``items`` must not depend on the thread that
    advances it (a list, or a generator of independent objects). Stopping the iteration takes no further item and
    waits for the items already handed to a thread.
    """
    if n_jobs == 1:
        yield from map(fn, items)
        return
    from joblib import Parallel, delayed

    call, stop = _caught(fn), threading.Event()
    # require="sharedmem": threads even inside a caller's joblib.parallel_config(backend="loky"), which would
    # otherwise overrule the preference (and ``fn`` may be a closure no process can receive).
    results = Parallel(n_jobs=n_jobs, prefer="threads", require="sharedmem", return_as="generator",
                       pre_dispatch="2*n_jobs", batch_size=1)(delayed(call)(item) for item in _until(stop, items))
    try:
        for result in results:
            if isinstance(result, _Raised):
                raise result.error
            yield result
    finally:
        stop.set()  # no item is taken any more; those handed out finish (joblib warns when its generator is cut short)
        for _ in results:
            pass


def _until(stop: threading.Event, items: Iterable[T]) -> Iterator[T]:
    for item in items:
        if stop.is_set():
            return
        yield item


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


def _parent_warnings() -> tuple[list, object]:
    """The warning filters and display hook in force here, as a worker can take them (a hook that cannot be sent by
    reference, such as a test's recorder, stays behind: the worker keeps Python's own)."""
    import pickle
    import warnings

    filters, hook = list(warnings.filters), warnings.showwarning
    try:
        pickle.dumps(filters)
    except Exception:
        filters = []
    try:
        pickle.dumps(hook)
    except Exception:
        hook = None
    return filters, hook


def _take_warnings(filters: list, hook) -> None:
    import re
    import warnings

    def pattern(match) -> str:  # None matches all, a text exactly (Python's own defaults), a regex as it is
        return "" if match is None else re.escape(match) + r"\Z" if isinstance(match, str) else match.pattern

    if filters:
        warnings.resetwarnings()
        for action, message, category, module, lineno in filters:  # in order, each appended: the same precedence
            warnings.filterwarnings(action, pattern(message), category, pattern(module), lineno, append=True)
    if hook is not None:
        warnings.showwarning = hook


def die_with_parent(parent_pid: int, parent_stops_on_sigint: bool = False, parent_warnings: tuple = ([], None)) -> None:
    """Pool initializer: end this worker as soon as ``parent_pid`` is no longer its parent.

    ``parent_stops_on_sigint``: the parent records Ctrl-C and stops at a safe point (:mod:`.interrupt`), so the
    worker, which the terminal's Ctrl-C reaches too, ignores it rather than fail the task it is running.
    ``parent_warnings``: the parent's warning filters and display hook (:func:`_parent_warnings`).
    """
    interrupt.reset_in_worker()  # a forked worker: the parent's handler is inherited and undone here
    if parent_stops_on_sigint:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    _take_warnings(*parent_warnings)
    armed = _arm_parent_death_signal()
    if os.getppid() != parent_pid:  # the parent died before the signal was armed (or we were re-parented)
        os._exit(1)
    if not armed:
        threading.Thread(target=_watch_parent, args=(parent_pid,), name="roughsense-parent-watch", daemon=True).start()


def process_pool(max_workers: int) -> Executor:
    """A loky process pool whose workers end within about a second of this process's death.

    Use it as ``with process_pool(n) as pool: pool.submit/map``; leaving the block shuts it down. Its workers are
    forked on Linux (they start with the parent's imports: a spawned worker re-imports NumPy and
    matplotlib, which cost a warm ``roughsense study`` 3.6 s of its 21, BENCHMARKS.md), else spawned; either way
    they take the parent's Ctrl-C handling and warning filters (:func:`die_with_parent`).
    """
    import multiprocessing

    from joblib.externals.loky import ProcessPoolExecutor

    # Linux only: macOS lists fork too, but its system libraries are not safe to use in a forked child.
    # loky refuses fork only for its reusable executor.
    context = multiprocessing.get_context("fork") if sys.platform.startswith("linux") else None
    return ProcessPoolExecutor(max_workers, context=context, initializer=die_with_parent,
                               initargs=(os.getpid(), interrupt.installed(), _parent_warnings()))


#: How often a wait on worker processes looks for a stop request (:func:`results_in_order`).
STOP_POLL_S = 0.1


def results_in_order(futures: list) -> list:
    """Every future's result, in order, waiting at a safe point (:func:`interrupt.check`) every :data:`STOP_POLL_S`:
    a Ctrl-C or SIGTERM recorded while workers compute is honoured at once, not after the last of them finishes (a
    report's figures took 12-18 s to drain, beyond a container's 10 s grace period)."""
    from concurrent.futures import FIRST_EXCEPTION, wait

    waiting = set(futures)
    while waiting:
        interrupt.check()
        done, waiting = wait(waiting, timeout=STOP_POLL_S, return_when=FIRST_EXCEPTION)
        if any(not f.cancelled() and f.exception() is not None for f in done):
            break  # raised below, in order
    interrupt.check()
    return [future.result() for future in futures]


def stop_pool(pool) -> None:
    """End a :func:`process_pool` now: its worker processes killed, not waited for (what they were computing is not
    wanted any more; nothing of theirs is committed), and every task not done failed by loky's shutdown. Its futures
    are not cancelled here: loky's manager thread sets each pending one's exception, and a cancelled one raises
    there, killing that thread before it kills the workers. The tasks not yet handed to a worker are taken off
    loky's queue of work ids first: its manager thread would look each up after the shutdown dropped it (a KeyError
    printed as a traceback, joblib 1.4)."""
    import queue

    ids = getattr(pool, "_work_ids", None)
    while ids is not None:
        try:
            ids.get_nowait()
        except queue.Empty:
            break
    pool.shutdown(wait=False, kill_workers=True)
