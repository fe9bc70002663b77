"""The one parallel module (``_util/workers.py``, on joblib): the thread map gives what a plain loop gives, in the
same order and with the same first error; cores are joblib's count; loky's workers compute what this process does."""
from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roughsense._util import workers

SRC = str(Path(__file__).resolve().parents[2] / "src")


def _square(x: int) -> int:
    return x * x


@settings(max_examples=40, deadline=None)
@given(items=st.lists(st.integers(-1000, 1000), max_size=40), n_jobs=st.integers(1, 4))
def test_thread_map_is_map_in_order(items, n_jobs):
    assert list(workers.thread_map(_square, items, n_jobs)) == list(map(_square, items))


def test_thread_map_takes_a_generator_and_numpy_work():
    rows = list(workers.thread_map(lambda seed: np.random.default_rng(seed).normal(size=5).sum(), (s for s in range(9)), 3))
    assert rows == [np.random.default_rng(s).normal(size=5).sum() for s in range(9)]


def test_the_first_failing_item_raises_after_every_item_before_it():
    later_failed = threading.Event()

    def job(i: int) -> int:
        if i == 4:
            later_failed.set()
            raise ValueError("item 4")
        if i == 2:
            later_failed.wait(timeout=30)  # item 4 has failed first: a plain loop would still name item 2
            raise ValueError("item 2")
        return i

    seen = []
    with pytest.raises(ValueError, match="item 2"):
        for value in workers.thread_map(job, range(6), 4):
            seen.append(value)
    assert seen == [0, 1]


def test_usable_cores_is_joblibs_count_within_this_process_affinity():
    import joblib

    assert workers.usable_cores() == max(1, joblib.cpu_count())
    if hasattr(os, "sched_getaffinity"):
        assert 1 <= workers.usable_cores() <= len(os.sched_getaffinity(0))


def _spectrum_of(seed: int) -> bytes:
    rng = np.random.default_rng(seed)
    return np.abs(np.fft.rfft(rng.normal(size=4096))).tobytes()


def test_loky_workers_give_the_bytes_this_process_gives():
    with workers.process_pool(2) as pool:
        remote = list(pool.map(_spectrum_of, range(4)))
    assert remote == [_spectrum_of(s) for s in range(4)]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
@pytest.mark.parametrize("stops_on_sigint", [False, True])
def test_a_spawned_worker_is_told_whether_ctrl_c_is_its_parents(stops_on_sigint):
    code = ("import os, signal, sys; sys.path.insert(0, sys.argv[1]); from roughsense._util.workers import "
            f"die_with_parent; die_with_parent(os.getppid(), {stops_on_sigint}); "
            "print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN)")
    done = subprocess.run([sys.executable, "-c", code, SRC], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == str(stops_on_sigint)


def _warn_and_return(value: int) -> int:
    import warnings

    from roughsense.errors import RoughsenseWarning

    warnings.warn(RoughsenseWarning(f"figure {value} drawn smaller"), stacklevel=1)
    return value


def test_a_worker_warns_under_the_filters_and_hook_in_force_when_the_pool_was_made(monkeypatch, capfd):
    """As a forked worker did: the CLI's one-line hook says a task's warning, and an 'error' filter raises it."""
    import warnings

    from roughsense.cli import _show_warning
    from roughsense.errors import RoughsenseWarning

    monkeypatch.setattr(warnings, "showwarning", _show_warning)
    with warnings.catch_warnings():
        warnings.simplefilter("always", RoughsenseWarning)
        with workers.process_pool(2) as pool:
            assert list(pool.map(_warn_and_return, [1, 2])) == [1, 2]
    assert sorted(capfd.readouterr().err.splitlines()) == [
        "roughsense: warning: figure 1 drawn smaller", "roughsense: warning: figure 2 drawn smaller"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RoughsenseWarning)
        with workers.process_pool(2) as pool, pytest.raises(RoughsenseWarning, match="figure 3"):
            pool.submit(_warn_and_return, 3).result()


def test_thread_map_stays_on_threads_under_a_callers_process_backend():
    import joblib

    with joblib.parallel_config(backend="loky"):
        ids = set(workers.thread_map(lambda _: os.getpid(), range(6), 2))  # a closure: no process could take it
    assert ids == {os.getpid()}


@pytest.mark.parametrize("stop", ["error", "break"])
def test_stopping_takes_no_further_item_and_warns_nothing(stop):
    """Items from 4 on wait (a guard of 2 s, not a timing): when the consumer stops at item 3, joblib has handed out
    at most 2 x n_jobs items past those done, and no more is taken once it stops."""
    import warnings

    called: list[int] = []
    gate = threading.Event()

    def job(i: int) -> int:
        called.append(i)
        if i >= 4:
            gate.wait(timeout=2)
        if stop == "error" and i == 3:
            raise ValueError("item 3")
        return i

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # joblib's "tasks ... have been cancelled" warning would fail here
        items = workers.thread_map(job, range(1000), 2)
        if stop == "error":
            with pytest.raises(ValueError, match="item 3"):
                list(items)
        else:
            assert [next(items) for _ in range(4)] == [0, 1, 2, 3]
            items.close()
    assert sorted(called) == list(range(len(called))) and len(called) <= 4 + 2 * 2
