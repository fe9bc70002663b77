"""explore/runner.py: a sweep's run ends in one "interrupted" line on Ctrl-C or SIGTERM, and a killed run's
Dask scratch folder is removed by the next."""
from __future__ import annotations

import os
import subprocess

import pytest

from roughsense._util import atomic
from tests.commands import HANG_GUARD_S, ROUGHSENSE, dead_pid
from tests.foreground import sigint_as_in_a_terminal
from tests.sweeps import big_sweep


@pytest.mark.parametrize("how", ["Ctrl-C", "kill"])
def test_ctrl_c_during_explore_is_one_interrupted_line_and_no_dask_traceback(tmp_path, how):
    """36.13: Ctrl-C (SIGINT to the whole process group, as a terminal sends it) printed a 30-line Dask traceback
    and no "interrupted" line; SIGTERM to roughsense alone let its workers log their heartbeats' failure. The window
    is forced: the signal is sent once a cell has been written."""
    import signal
    import time

    sweep = big_sweep(tmp_path, 60)
    out = tmp_path / "out"
    run = subprocess.Popen([ROUGHSENSE, "explore", str(sweep), "--out", str(out), "--jobs", "1"],
                           stderr=subprocess.PIPE, text=True, start_new_session=True,
                           preexec_fn=sigint_as_in_a_terminal,  # a terminal's job, however pytest was started
                           env={**os.environ, "ROUGHSENSE_CACHE_DIR": str(tmp_path / "cache")})
    try:
        deadline = time.monotonic() + HANG_GUARD_S  # a guard against a hang, not a timing check
        while not any((out / "results").glob("*.parquet")) and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        if how == "Ctrl-C":
            os.killpg(run.pid, signal.SIGINT)
        else:
            os.kill(run.pid, signal.SIGTERM)
        _, err = run.communicate(timeout=HANG_GUARD_S)
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    assert run.returncode == (130 if how == "Ctrl-C" else 143), err
    assert "Traceback" not in err and "distributed" not in err
    assert [line for line in err.splitlines() if "interrupted" in line] == ["roughsense: interrupted"]
    assert not list(out.glob(".dask-scratch.*"))


def test_a_killed_sweeps_scratch_folder_is_removed_by_the_next_run(tmp_path):
    """36.15: after kill -9 and a resumed explore, ``.dask-scratch.*.tmp/`` stayed in the finished folder."""
    from roughsense.explore import runner

    out = tmp_path / "out"
    dead = out / f".dask-scratch.{dead_pid()}.abcd1234.tmp"
    legacy = out / ".dask-scratch.abcd1234.tmp"  # named before the PID was in it
    live = out / f".dask-scratch.{os.getppid()}.efgh5678.tmp"
    for folder in (dead, legacy, live):
        (folder / "worker-x").mkdir(parents=True)
    fresh = runner._scratch(out)
    assert fresh.name.startswith(f".dask-scratch.{os.getpid()}.") and atomic.is_temporary(fresh)
    assert sorted(p.name for p in out.iterdir()) == sorted([live.name, fresh.name])
