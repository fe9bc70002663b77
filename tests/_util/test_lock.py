"""One writer per output: every command that writes a folder holds a lock on ``--out``; a second run is one line.

The lock's holder is a real second process wherever it matters (flock is per process): a helper process holds the
lock while each command is tried, and two real ``explore`` runs race for one folder. A dead run's lock is made by
hand with the PID of a process that has ended.
"""
from __future__ import annotations

import errno
import json
import os
import signal
import socket
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as hs

from roughsense._util import atomic
from roughsense._util import lock as lock_module
from roughsense._util.lock import OutputBusyError, lock_path, output_lock
from tests.cli.test_input_contract import one_error
from tests.commands import HANG_GUARD_S
from tests.sweeps import small_sweep
from tests.videos import write_video

SRC = str(Path(__file__).resolve().parents[2] / "src")
ENV = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
SWEEP = small_sweep(range(4))
_HOLD = """
import signal, sys, time
from roughsense._util.lock import output_lock
signal.signal(signal.SIGTERM, signal.default_int_handler)  # as roughsense's own entry point does
with output_lock(sys.argv[1], command="explore"):
    print("held", flush=True)
    time.sleep(600)  # stopped by the test: it holds the lock for as long as the test runs, however slowly
"""
_TINY_SIM = ("--pads", "smooth", "--specimens", "R2", "--forces-n", "2", "--repetitions", "1", "--jobs", "1")


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _stop(process: subprocess.Popen, timeout_s: float = 60.0) -> None:
    """``kill``, as a user stops a run: the lock must go with it. SIGTERM, not SIGINT: a process started in the
    background (``make test &``, nohup, a script) inherits SIGINT ignored and would never stop (issue 28)."""
    process.send_signal(signal.SIGTERM)
    try:
        process.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
        raise


@pytest.fixture
def holder(tmp_path):
    """Another process holding the lock of tmp_path/out (an existing folder with a file in it)."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    process = subprocess.Popen([sys.executable, "-c", _HOLD, str(out)], env=ENV, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
    assert process.stdout.readline().strip() == b"held", process.stderr.read()
    yield out, process
    if process.poll() is None:
        _stop(process)
    assert not lock_path(out).exists()  # released when the run is stopped


def test_every_command_that_writes_a_folder_is_refused_naming_the_holder(holder, tmp_path, run_cli, monkeypatch):
    import io

    out, process = holder
    before = _files(out)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP)
    video = write_video(tmp_path / "camera.avi")
    monkeypatch.setattr("sys.stdin", io.StringIO("\n" * 10))
    commands = {
        "simulate": ("simulate", "--out", out, "--force", *_TINY_SIM),
        "capture": ("capture", "--source", video, "--out", out, "--specimen", "R3", "--pad", "fp", "--roi", "auto"),
        "study": ("study", "--study", tmp_path / "no-such-study", "--out", out, "--force"),
        "example": ("example", "my-study", "--out", out, "--force"),
        "explore": ("explore", sweep, "--out", out, "--force"),
    }
    for name, args in commands.items():
        code, stdout, err = run_cli(*args)
        line = one_error(code, err)
        assert "started " in line, (name, line)
        assert line == (f"roughsense: error: {out}: another run is writing this folder (roughsense explore, PID "
                        f"{process.pid} on {socket.gethostname()}, started {line.split('started ')[1]}"), name
        assert line.endswith("UTC); wait for it to end, or stop it"), name
        assert stdout == "" and process.poll() is None, name  # refused while the holder still runs
    assert _files(out) == before and process.poll() is None  # nothing written, the holder untouched


def test_a_symlinked_spelling_of_the_folder_shares_its_lock(holder, tmp_path, run_cli):
    out, process = holder
    link = tmp_path / "link"
    link.symlink_to(out)
    code, _, err = run_cli("simulate", "--out", link / ".." / "out", "--force", *_TINY_SIM)
    assert f"PID {process.pid}" in one_error(code, err)
    code, _, err = run_cli("simulate", "--out", link, "--force", *_TINY_SIM)
    assert f"PID {process.pid}" in one_error(code, err)


@pytest.mark.slow
def test_two_explore_runs_on_one_folder_the_second_is_refused_at_once(tmp_path):
    """The race of issue 22: a second sweep (with --force) into the folder a first sweep is computing."""
    first_sweep, second_sweep = tmp_path / "first.toml", tmp_path / "second.toml"
    long_sweep = small_sweep(range(60))  # minutes of cells: still computing when the second run, however slow, ends
    first_sweep.write_text(long_sweep)
    second_sweep.write_text(small_sweep([7]))
    out = tmp_path / "out"
    first = subprocess.Popen([sys.executable, "-m", "roughsense.cli", "explore", str(first_sweep), "--out", str(out),
                              "--jobs", "1"], env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 300  # a hang guard: importing roughsense on a busy machine takes a while
        while not (lock_path(out).exists() and lock_path(out).stat().st_size):
            assert first.poll() is None, first.stderr.read().decode()
            assert time.monotonic() < deadline, "the first run never took the lock"
            time.sleep(0.05)
        assert json.loads(lock_path(out).read_text())["pid"] == first.pid
        second = subprocess.run([sys.executable, "-m", "roughsense.cli", "explore", str(second_sweep), "--out",
                                 str(out), "--force"], env=ENV, capture_output=True, text=True, timeout=600)
        # "at once": refused while the first is still computing, not after waiting for it (how long the refusal takes
        # is benchmarks/bench_refusals.py's to measure)
        assert first.poll() is None
        line = one_error(second.returncode, second.stderr)
        assert f"{out}: another run is writing this folder (roughsense explore, PID {first.pid} on" in line
        assert first.poll() is None  # the first run goes on
    finally:
        _stop(first)
    assert not lock_path(out).exists()
    sweep_copy = out / "sweep.toml"
    assert not sweep_copy.exists() or sweep_copy.read_text() == long_sweep  # never the second sweep's


def test_a_dead_runs_lock_is_taken_over_and_said(tmp_path, run_cli):
    out = tmp_path / "sim"
    dead = _dead_pid()
    lock_path(out).write_text(json.dumps({"pid": dead, "host": socket.gethostname(), "started": "2025-01-01 10:00:00 UTC",
                                          "command": "roughsense simulate"}))
    code, _, err = run_cli("simulate", "--out", out, *_TINY_SIM)
    assert code == 0, err
    warnings = [line for line in err.splitlines() if line.startswith("roughsense: warning: ")]
    assert warnings == [f"roughsense: warning: {out}: took over the lock of a run that has ended (roughsense simulate, "
                        f"PID {dead} on {socket.gethostname()}, started 2025-01-01 10:00:00 UTC); a folder it was "
                        "writing is checked as usual"]
    assert (out / "manifest.csv").is_file() and not lock_path(out).exists()


@given(hs.binary(max_size=300) | hs.text(max_size=300).map(str.encode))
def test_any_leftover_lock_file_is_taken_over_never_a_crash(tmp_path_factory, content):
    import warnings

    out = tmp_path_factory.mktemp("lock") / "out"
    lock_path(out).write_bytes(content)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with output_lock(out, command="simulate"):
            held = json.loads(lock_path(out).read_text())
            assert held["pid"] == os.getpid() and held["command"] == "roughsense simulate"
    assert not lock_path(out).exists()
    assert len(caught) == (1 if content else 0)
    if content:
        assert str(caught[0].message).startswith(f"{out}: took over the lock of")


def test_released_on_error_and_on_ctrl_c(tmp_path, run_cli):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    code, _, err = run_cli("simulate", "--out", out, *_TINY_SIM)  # refused: a folder of someone's files
    assert "not empty" in one_error(code, err) and not lock_path(out).exists()
    with pytest.raises(KeyboardInterrupt), output_lock(out):
        assert lock_path(out).exists()
        raise KeyboardInterrupt
    assert not lock_path(out).exists()
    with output_lock(out), output_lock(out):  # the CLI's lock around the library's: the same run, not a second one
        pass
    assert not lock_path(out).exists()
    assert [p.name for p in tmp_path.iterdir()] == ["mine"]  # nothing of the lock's is left beside the folder


def _no_flock(*args):
    raise OSError(errno.ENOSYS, "Function not implemented")


_HOLD_WITHOUT_FLOCK = """
import errno, fcntl
def no_flock(*args):
    raise OSError(errno.ENOSYS, "Function not implemented")
fcntl.flock = no_flock
""" + _HOLD


def test_without_flock_a_live_run_holds_the_lock_and_a_killed_one_does_not(tmp_path, monkeypatch):
    """A file system without flock: filelock's marker file stands in, and a killed run's marker is taken over."""
    import fcntl

    monkeypatch.setattr(fcntl, "flock", _no_flock)
    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, "-c", _HOLD_WITHOUT_FLOCK, str(out)], env=ENV, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
    try:
        assert process.stdout.readline().strip() == b"held", process.stderr.read()
        with pytest.raises(OutputBusyError, match=f"PID {process.pid} on {socket.gethostname()}"):
            output_lock(out).__enter__()
        assert json.loads(lock_path(out).read_text())["pid"] == process.pid  # left as it was
    finally:
        process.kill()  # kill -9: nothing is cleaned up
        process.wait()
    assert lock_path(out).exists()
    with pytest.warns(UserWarning, match=f"took over the lock of a run that has ended .*PID {process.pid}"), \
            output_lock(out):
        pass
    assert not lock_path(out).exists()


def test_a_killed_runs_lock_is_taken_over(tmp_path):
    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, "-c", _HOLD, str(out)], env=ENV, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
    assert process.stdout.readline().strip() == b"held", process.stderr.read()
    process.kill()
    process.wait()
    with pytest.warns(UserWarning, match=f"PID {process.pid}"), output_lock(out):
        pass
    assert not lock_path(out).exists()


def test_the_lock_files_are_roughsense_own():
    assert atomic.is_temporary(lock_path("some/out")) and lock_path("some/out").name == ".out.roughsense-lock"
    assert atomic.is_temporary(Path("some/.out.roughsense-lock.flock"))


def test_a_parent_folder_one_cannot_write_is_named_with_what_to_do(tmp_path, monkeypatch):
    """The lock lives beside --out; where the parent is not writable (another user's folder) the line says so,
    instead of the misleading 'No such file or directory' of the read-only fallback."""
    from roughsense.errors import RoughsenseError

    real_open = os.open

    def refuse_creation(path, flags, *args):
        if flags & os.O_CREAT:
            raise PermissionError(13, "Permission denied")
        return real_open(path, flags, *args)

    monkeypatch.setattr(lock_module.os, "open", refuse_creation)
    (tmp_path / "out").mkdir()
    with pytest.raises(RoughsenseError) as info, lock_module.OutputLock(tmp_path / "out", command="test"):
        pass
    message = str(info.value)
    assert "permission denied" in message and "choose an --out whose parent you can write" in message
    assert str(tmp_path / "out") in message


def _try_as_nobody(out: Path) -> str:
    """As user nobody: what taking ``out``'s lock gives (the error, or "got it")."""
    from tests.as_user import as_nobody

    def take() -> str:
        with warnings.catch_warnings(), output_lock(out, command="other"):
            warnings.simplefilter("ignore")  # the take-over's warning: the parent checks the outcome
            return "got it"

    return as_nobody(take)


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0, reason="switching user needs root")
def test_another_user_in_a_shared_folder_is_told_who_holds_it_and_takes_over_a_dead_run():
    import shutil
    import tempfile

    shared = Path(tempfile.mkdtemp(prefix="roughsense-shared-", dir="/tmp"))  # pytest's tmp_path is root's alone
    os.chmod(shared, 0o777)
    out = shared / "out"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom roughsense._util.lock import output_lock\n"
         f"with output_lock({str(out)!r}, command='simulate'):\n    print('held', flush=True); time.sleep(600)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        busy = _try_as_nobody(out)
        assert busy.startswith("OutputBusyError") and "roughsense simulate, PID" in busy
        holder.kill()
        holder.wait()
        assert _try_as_nobody(out) == "got it"  # a dead run's lock is taken over (with a warning), not refused
    finally:
        holder.kill()
        holder.wait()
        shutil.rmtree(shared, ignore_errors=True)


@pytest.mark.parametrize("planted", ["record-fifo", "record-link-to-fifo", "flock-link", "flock-fifo"])
def test_a_planted_lock_file_is_refused_by_name_without_waiting(tmp_path, planted):
    """36.7: a FIFO as ``.NAME.roughsense-lock`` hung the run (and left a 0666 .flock); a symlinked .flock was
    refused with "Too many levels of symbolic links", naming neither the file nor the fix."""
    from roughsense._util.lock import OutputLock, lock_path
    from roughsense.errors import RoughsenseError

    out = tmp_path / "out"
    record = lock_path(out)
    flock = record.with_name(record.name + atomic.FLOCK_SUFFIX)
    target = {"record-fifo": record, "record-link-to-fifo": record, "flock-link": flock, "flock-fifo": flock}[planted]
    if planted.endswith("link"):
        target.symlink_to(tmp_path / "elsewhere")
    elif planted.endswith("link-to-fifo"):
        os.mkfifo(tmp_path / "pipe")
        target.symlink_to(tmp_path / "pipe")
    else:
        os.mkfifo(target)
    # on e1630a3 the record's FIFO blocks here forever: a thread keeps the suite from hanging with it
    import threading

    outcome: list[BaseException | None] = []

    def take() -> None:
        try:
            with OutputLock(out, command="test"):
                outcome.append(None)
        except BaseException as exc:
            outcome.append(exc)

    worker = threading.Thread(target=take, daemon=True)
    worker.start()
    worker.join(HANG_GUARD_S)
    assert outcome and isinstance(outcome[0], RoughsenseError), outcome
    message = str(outcome[0])
    assert f"the lock file {target} is" in message and "delete it" in message
    left = sorted(p.name for p in tmp_path.iterdir())
    assert flock.name not in left or planted.startswith("flock")  # nothing of ours left behind
