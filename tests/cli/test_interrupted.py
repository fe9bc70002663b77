"""Killed, interrupted or replaced runs never leave a mixed folder, stale files, orphans or a blocked rerun.

The whole-folder swap (``atomic.FolderSwap``) is checked on its own, then through ``simulate`` and ``study``
killed with SIGKILL in a subprocess, as a user's Ctrl-\\ or an out-of-memory kill would.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from roughsense._util import atomic
from roughsense._util.lock import lock_path
from roughsense.errors import InputError, OutputExistsError
from roughsense.io.study import COMPLETE_MARKER, read_study
from roughsense.sim.config import SimulationConfig
from roughsense.sim.optics import Camera
from roughsense.sim.simulate import simulate_study

SRC = str(Path(__file__).resolve().parents[2] / "src")
LINUX = sys.platform.startswith("linux")
#: Not a timing check: how long a wait for a child's next step (or its end) may last before the test fails instead
#: of hanging; a machine busy with other work can take many times the usual few seconds.
HANG_GUARD_S = 300


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def _siblings(target: Path) -> list[str]:
    return sorted(p.name for p in target.parent.iterdir() if p.name.startswith(f".{target.name}."))


# --------------------------------------------------------------------------- the mechanism


@pytest.mark.parametrize("exchange", [True, False], ids=["renameat2", "two-renames"])
def test_swap_replaces_the_folder_whole_and_keeps_the_users_files(tmp_path, monkeypatch, exchange):
    if not exchange:
        monkeypatch.setattr(atomic, "_exchange", lambda a, b: False)
    out = tmp_path / "out"
    (out / "sub").mkdir(parents=True)
    (out / "old.csv").write_text("old")
    (out / "shared.csv").write_text("old")
    (out / "notes.txt").write_text("mine")
    (out / "sub" / "data.txt").write_text("mine too")
    (out / "keep-empty").mkdir()
    def owned(rel):
        return rel.name.endswith(".csv")

    with atomic.staged_folder(out, owned=owned) as staging:
        assert staging.parent == out.parent and atomic.PARTIAL_TAG in staging.name
        (staging / "shared.csv").write_text("new")
        (staging / "fresh.csv").write_text("new")
        assert _files(out)["old.csv"] == b"old"  # nothing changes at the target until the swap
    assert _files(out) == {"shared.csv": b"new", "fresh.csv": b"new", "notes.txt": b"mine",
                           "sub/data.txt": b"mine too"}
    assert (out / "keep-empty").is_dir()
    assert _siblings(out) == []  # neither the staging nor the old folder remains


def test_an_exception_changes_nothing(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.csv").write_text("old")
    with pytest.raises(RuntimeError), atomic.staged_folder(out) as staging:
        (staging / "a.csv").write_text("new")
        raise RuntimeError("analysis failed")
    assert _files(out) == {"a.csv": b"old"} and _siblings(out) == []
    with pytest.raises(RuntimeError), atomic.staged_folder(tmp_path / "new"):
        raise RuntimeError("analysis failed")
    assert not (tmp_path / "new").exists() and _siblings(tmp_path / "new") == []


def test_leftovers_of_dead_runs_are_cleaned_and_a_live_runs_are_not(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.csv").write_text("current")
    dead = tmp_path / f".out{atomic.PARTIAL_TAG}{_dead_pid()}-abcd"
    live = tmp_path / f".out{atomic.PARTIAL_TAG}{os.getppid()}-efgh"  # pytest's parent: alive
    for folder in (dead, live):
        folder.mkdir()
        (folder / "a.csv").write_text("partial")
    (tmp_path / ".out.a.csv.x1y2z3w4.tmp").write_text("not a folder leftover of out: left alone")
    assert atomic.leftovers(out) == [dead]
    with atomic.staged_folder(out) as staging:
        (staging / "a.csv").write_text("new")
    assert not dead.exists() and live.is_dir()
    assert _files(out) == {"a.csv": b"new"}


def test_a_run_killed_between_the_two_renames_gets_its_old_folder_back(tmp_path):
    out = tmp_path / "out"
    retired = tmp_path / f".out{atomic.RETIRED_TAG}{_dead_pid()}-abcd"
    retired.mkdir()
    (retired / "a.csv").write_text("previous")
    atomic.clean_leftovers(out)
    assert _files(out) == {"a.csv": b"previous"} and not retired.exists()


def test_the_swap_refuses_places_it_must_not_replace(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputExistsError, match="not a folder"):
        atomic.FolderSwap(tmp_path / "file")
    work = tmp_path / "work"
    (work / "inner").mkdir(parents=True)
    monkeypatch.chdir(work / "inner")
    with pytest.raises(OutputExistsError, match="folder you are working in"):
        atomic.FolderSwap(work)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(atomic, "MAX_CARRIED_FILES", 3)
    for i in range(4):
        (work / f"user{i}.txt").write_text("mine")
    with pytest.raises(OutputExistsError, match="holds 5 files that roughsense did not write"):
        atomic.FolderSwap(work, owned=lambda rel: False)  # 4 files and the empty folder 'inner'
    assert _siblings(work) == []


@pytest.mark.skipif(not LINUX, reason="/proc is Linux's")
def test_an_unwritable_place_fails_when_the_swap_is_prepared(tmp_path):
    (tmp_path / "file").write_text("x")
    for target in (tmp_path / "file" / "report", Path("/proc/roughsense-report")):
        with pytest.raises(atomic.RoughsenseError, match="cannot write here"):
            atomic.FolderSwap(target)


# --------------------------------------------------------------------------- simulate


def _config(seed: int, repetitions: int = 1) -> SimulationConfig:
    return SimulationConfig(pads=("smooth",), specimens=("R2", "R3"), forces_n=(1.0, 2.0), repetitions=repetitions,
                            seed=seed, camera=Camera(width_px=400, height_px=300), participants=3, sessions=1)


def _python(code: str, *args: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.Popen([sys.executable, "-c", code, *args], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)


_SIMULATE = """
import sys
from roughsense.sim.config import SimulationConfig
from roughsense.sim.simulate import simulate_study
from roughsense.sim.optics import Camera
config = SimulationConfig(pads=("smooth",), specimens=("R2", "R3"), forces_n=(1.0, 2.0), repetitions=int(sys.argv[3]),
                          seed=int(sys.argv[2]), camera=Camera(width_px=400, height_px=300), participants=3, sessions=1)
simulate_study(sys.argv[1], config, force=True, jobs=int(sys.argv[4]))
"""


def _kill_when(process: subprocess.Popen, ready) -> None:
    deadline = time.monotonic() + HANG_GUARD_S
    while not ready():
        if process.poll() is not None:
            raise AssertionError(f"finished before it could be killed: {process.stderr.read().decode()}")
        if time.monotonic() > deadline:
            process.kill()
            raise AssertionError("never got ready")
        time.sleep(0.02)
    process.send_signal(signal.SIGKILL)
    process.wait(timeout=HANG_GUARD_S)


def _staged_images(out: Path) -> int:
    return sum(len(list((p / "images").glob("*.png"))) for p in out.parent.glob(f".{out.name}{atomic.PARTIAL_TAG}*"))


def test_simulate_force_replaces_the_whole_study_and_keeps_the_users_files(tmp_path):
    out = simulate_study(tmp_path / "sim", _config(seed=1), jobs=1)
    (out / "notes.txt").write_text("mine")
    (out / "images" / "my-photo.jpg").write_bytes(b"\xff\xd8 not the simulator's")
    smaller = SimulationConfig(pads=("smooth",), specimens=("R2",), forces_n=(2.0,), repetitions=1, seed=5,
                               camera=Camera(width_px=400, height_px=300), participants=3, sessions=1)
    simulate_study(out, smaller, force=True, jobs=1)
    study = read_study(out)
    assert sorted(p.name for p in (out / "images").iterdir()) == ["my-photo.jpg", "smooth_R2_2N_r01.png"]
    assert list(study.manifest["image"]) == ["images/smooth_R2_2N_r01.png"]
    assert set(study.ratings["specimen"]) == {"R2"} and study.extra["simulation"]["seed"] == 5
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "images" / "my-photo.jpg").read_bytes() == b"\xff\xd8 not the simulator's"


_TINY = ("--pads", "smooth", "--specimens", "R2", "--forces-n", "2", "--repetitions", "1", "--jobs", "1")


@pytest.mark.slow
def test_simulate_force_killed_midway_leaves_the_old_study_whole(tmp_path, run_cli):
    out = tmp_path / "sim"
    code, _, err = run_cli("simulate", "--out", out, *_TINY, "--seed", "1")
    assert code == 0, err
    before = _files(out)
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    run = subprocess.Popen([sys.executable, "-m", "roughsense.cli", "simulate", "--out", str(out), "--force",
                            "--seed", "2", "--pads", "smooth", "--specimens", "R2,R3,C3", "--forces-n", "1,2,3",
                            "--repetitions", "3", "--jobs", "1"],
                           env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _kill_when(run, lambda: _staged_images(out) >= 2)  # killed after its first images
    assert _files(out) == before  # the old study, complete, not one new file in it
    assert read_study(out, require_ratings=True).extra["simulation"]["seed"] == 1
    assert len(atomic.leftovers(out)) == 1
    assert json.loads(lock_path(out).read_text())["pid"] == run.pid  # kill -9 leaves its lock file, not its lock
    # the next run takes the lock over (saying whose it was), removes the dead run's partial folder and swaps in a
    # complete new study
    code, _, err = run_cli("simulate", "--out", out, *_TINY, "--seed", "2", "--force")
    assert code == 0, err
    assert f"roughsense: warning: {out}: took over the lock of a run that has ended (roughsense simulate, PID {run.pid} " \
           "on " in err
    assert atomic.leftovers(out) == [] and _siblings(out) == [] and not lock_path(out).exists()
    assert read_study(out).extra["simulation"]["seed"] == 2 and (out / COMPLETE_MARKER).is_file()


def test_a_killed_first_simulation_leaves_no_study_and_blocks_nothing(tmp_path, run_cli):
    out = tmp_path / "sim"
    run = _python(_SIMULATE, str(out), "2", "30", "1")
    _kill_when(run, lambda: _staged_images(out) >= 1)
    assert not out.exists() and len(atomic.leftovers(out)) == 1
    code, _, err = run_cli("simulate", "--out", out, "--pads", "smooth", "--specimens", "R2", "--forces-n", "2",
                           "--repetitions", "1", "--jobs", "1")  # no --force needed
    assert code == 0, err
    assert len(read_study(out).manifest) == 1 and _siblings(out) == []


def test_readers_refuse_an_interrupted_simulation(tmp_path, run_cli):
    out = simulate_study(tmp_path / "sim", _config(seed=1), jobs=1)
    (out / COMPLETE_MARKER).unlink()
    with pytest.raises(InputError, match="simulated study is incomplete"):
        read_study(out)
    hint = f"rerun `roughsense simulate --out {out} --force`"
    for args in (("study", "--study", out, "--out", tmp_path / "report"),
                 ("fit", "--study", out, "--pad", "smooth", "--condition", "1N", "--out", tmp_path / "m.json"),
                 ("features", "--study", out, "--out", tmp_path / "f.csv")):
        code, _, err = run_cli(*args)
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert f"{out}: simulated study is incomplete" in err and hint in err
    assert not (tmp_path / "report").exists() and not (tmp_path / "f.csv").exists()
    # an interrupted simulation is roughsense's own: replaced without --force, a user's file in it kept
    (out / "notes.txt").write_text("mine")
    code, _, err = run_cli("simulate", "--out", out, "--pads", "smooth", "--specimens", "R2", "--forces-n", "2",
                           "--repetitions", "1", "--jobs", "1")
    assert code == 0, err
    assert (out / "notes.txt").read_text() == "mine" and len(read_study(out).manifest) == 1
    assert not (out / "images" / "smooth_R3_1N_r01.png").exists()  # the old run's images went with it


def test_predict_refuses_an_interrupted_simulation(tmp_path, run_cli, tiny_study):
    model = tmp_path / "m.json"
    code, _, err = run_cli("fit", "--study", tiny_study, "--pad", "fingerprint", "--condition", "1N",
                           "--max-components", "1", "--model", "pls", "--out", model)
    assert code == 0, err
    out = simulate_study(tmp_path / "sim", _config(seed=1), jobs=1)
    (out / COMPLETE_MARKER).unlink()
    code, _, err = run_cli("predict", model, "--study", out)
    assert code == 2 and "simulated study is incomplete" in err and len(err.strip().splitlines()) == 1


def _children(pid: int) -> list[int]:
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")  # a zombie has ended; only its exit status waits to be collected


def _survivors(workers: list[int]) -> list[int]:
    """The workers still alive once they have all ended, or once :data:`HANG_GUARD_S` has passed: a guard against
    workers that never end, not a bound on how soon they do. Survivors are killed, so a failing test leaves none."""
    deadline = time.monotonic() + HANG_GUARD_S
    while any(_alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    survivors = [w for w in workers if _alive(w)]
    for w in survivors:
        os.kill(w, signal.SIGKILL)
    return survivors


@pytest.mark.slow
@pytest.mark.skipif(not LINUX, reason="reads /proc")
def test_workers_end_when_simulate_is_killed(tmp_path):
    out = tmp_path / "sim"
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    run = subprocess.Popen([sys.executable, "-m", "roughsense.cli", "simulate", "--out", str(out), "--pads", "smooth",
                            "--specimens", "R2,R3,C3", "--forces-n", "1,2,3", "--repetitions", "4", "--jobs", "2"],
                           env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    workers: list[int] = []

    def ready() -> bool:
        workers[:] = _children(run.pid)
        return len(workers) >= 2 and _staged_images(out) >= 1

    _kill_when(run, ready)
    survivors = _survivors(workers)
    assert survivors == [], f"workers {survivors} outlived their parent"
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.skipif(not LINUX, reason="reads /proc")
def test_study_killed_while_it_simulates_leaves_no_cache_entry_and_no_worker(tmp_path):
    cache = tmp_path / "cache"
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", ""),
           "ROUGHSENSE_CACHE_DIR": str(cache)}
    run = subprocess.Popen([sys.executable, "-m", "roughsense.cli", "study", "--out", str(tmp_path / "report"),
                            "--jobs", "2", "--seed", "7"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    workers: list[int] = []

    def staged() -> int:
        return sum(len(list(p.glob("images/*.png"))) for p in cache.glob(f".simulated-study-*{atomic.PARTIAL_TAG}*"))

    def ready() -> bool:
        workers[:] = _children(run.pid)
        return len(workers) >= 2 and staged() >= 1

    _kill_when(run, ready)
    assert _survivors(workers) == []
    # no cache entry a later run would trust: only the dead run's partial folder, which that run removes
    assert [p.name for p in cache.iterdir() if not p.name.startswith(".")] == []
    partial = [p for p in cache.iterdir() if atomic.PARTIAL_TAG in p.name]
    assert len(partial) == 1
    entry = cache / partial[0].name[1:].split(atomic.PARTIAL_TAG)[0]
    assert atomic.leftovers(entry) == partial
    assert not (tmp_path / "report").exists() and atomic.leftovers(tmp_path / "report") != []


def test_a_worker_whose_parent_is_already_gone_exits_at_once():
    from roughsense._util import workers

    code = ("import os, sys; sys.path.insert(0, sys.argv[1]); from roughsense._util.workers import die_with_parent;"
            " die_with_parent(os.getppid() + 1 if os.getppid() != 1 else 2); print('survived')")
    done = subprocess.run([sys.executable, "-c", code, SRC], capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and "survived" not in done.stdout
    assert workers.PARENT_POLL_S <= 1.0


# --------------------------------------------------------------------------- the report


_STUDY = """
import sys
from roughsense.cli import main
sys.exit(main(["study", "--study", sys.argv[1], "--out", sys.argv[2], "--max-components", "2", "--no-loso",
              "--permutations", "0"]))  # killed while it writes the report: the controls are not what is checked
"""


@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory):
    from tests.analysis.test_dataset import make_study

    return make_study(tmp_path_factory.mktemp("tiny") / "study", repetitions=2)


@pytest.mark.slow
def test_study_force_leaves_no_stale_report_file_and_keeps_the_users(tmp_path, run_cli, tiny_study, monkeypatch,
                                                                    quick_figures):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "report"
    quick = ("--max-components", "2", "--permutations", "0")  # which files the second run leaves, not the controls
    code, _, err = run_cli("study", "--study", tiny_study, "--out", out, *quick)
    assert code == 0, err
    assert (out / "results_loso.csv").is_file() and (out / "predicted_vs_perceived_loso.png").is_file()
    (out / "my-notes.md").write_text("mine")
    code, _, err = run_cli("study", "--study", tiny_study, "--out", out, *quick, "--no-loso", "--force")
    assert code == 0, err
    names = sorted(p.name for p in out.iterdir())
    assert "results_loso.csv" not in names and "predicted_vs_perceived_loso.png" not in names
    assert {"index.html", "results.csv", "my-notes.md", "predicted_vs_perceived_loo.png"} <= set(names)
    assert (out / "my-notes.md").read_text() == "mine" and _siblings(out) == []
    assert set(pd.read_csv(out / "cv.csv")["cv"]) == {"loo"}  # the tables are the new run's alone


@pytest.mark.slow
def test_a_killed_study_blocks_no_rerun(tmp_path, run_cli, tiny_study, monkeypatch, quick_figures):
    monkeypatch.setenv("ROUGHSENSE_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "report"
    run = _python(_STUDY, str(tiny_study), str(out))
    _kill_when(run, lambda: any(tmp_path.glob(f".report{atomic.PARTIAL_TAG}*")))
    assert not out.exists() and len(atomic.leftovers(out)) == 1
    # an older roughsense killed mid-write left temporary files, and an unfinished report, in the folder itself
    out.mkdir()
    (out / ".results.csv.k2j4h6g8.tmp").write_text("half")
    (out / "cv.csv").write_text("half")
    code, _, err = run_cli("study", "--study", tiny_study, "--out", out, "--max-components", "2", "--no-loso",
                           "--permutations", "0")
    assert code == 0, err  # roughsense's own incomplete output needs no --force
    assert (out / "index.html").is_file() and not (out / ".results.csv.k2j4h6g8.tmp").exists()
    assert _siblings(out) == []


def test_a_finished_report_still_needs_force(tmp_path, run_cli, tiny_study):
    out = tmp_path / "report"
    out.mkdir()
    (out / "index.html").write_text("<html>an earlier report</html>")
    code, _, err = run_cli("study", "--study", tiny_study, "--out", out)
    assert code == 2 and "--force" in err and (out / "index.html").read_text() == "<html>an earlier report</html>"


@pytest.mark.skipif(not LINUX, reason="/proc is Linux's")
def test_study_out_on_an_unwritable_place_fails_before_the_analysis(tmp_path, run_cli):
    (tmp_path / "file").write_text("x")
    for out in (tmp_path / "file" / "report", Path("/proc/roughsense-report")):
        code, stdout, err = run_cli("study", "--study", tmp_path / "no-such-study", "--out", out)
        assert code == 2 and len(err.strip().splitlines()) == 1
        assert f"{out}: cannot write here" in err and "no-such-study" not in err  # --out is checked first
        assert stdout == ""


def test_a_killed_writer_leaves_no_temporary_file_for_long(tmp_path):
    target = tmp_path / "model.json"
    dead = tmp_path / f".model.json.{_dead_pid()}.abcd1234.tmp"
    live = tmp_path / f".model.json.{os.getppid()}.efgh5678.tmp"
    legacy = tmp_path / ".model.json.ijkl9012.tmp"  # no process id: nobody can tell whose it is, so it stays
    for path in (dead, live, legacy):
        path.write_text("half")
        assert atomic.is_temporary(path)
    atomic.write_text(target, "whole")
    assert target.read_text() == "whole"
    assert not dead.exists() and live.exists() and legacy.exists()


def _slow_figure(marker: str, seconds: float):
    """A figure that takes ``seconds`` to draw and leaves ``marker`` once drawn (a worker that was waited for)."""
    time.sleep(seconds)
    Path(marker).write_text("drawn")
    import matplotlib.figure

    return matplotlib.figure.Figure(figsize=(1, 1))


@pytest.mark.skipif(not LINUX, reason="fork context")
@pytest.mark.filterwarnings("error::pytest.PytestUnhandledThreadExceptionWarning")  # loky's manager thread ends well
def test_a_stop_while_figures_render_kills_their_workers_instead_of_waiting(tmp_path, monkeypatch):
    """A stop during the report ended only once every figure already rendering was drawn (12-18 s on the paper's
    study, beyond a container's 10 s grace): now the wait honours it, pending figures are cancelled and the worker
    processes killed. The figures here take HANG_GUARD_S to draw, so a waited-for one would leave its marker."""
    from roughsense._util import interrupt, workers
    from roughsense.report import html

    pools = []

    def recorded(n):
        pools.append(workers.process_pool(n))
        return pools[-1]

    monkeypatch.setattr(html, "process_pool", recorded)
    analysis = type("Analysis", (), {"provenance": None})()
    monkeypatch.setattr(html.source, "figure_stamp", lambda provenance: None)
    markers = [tmp_path / f"figure{i}" for i in range(4)]
    jobs = [html.FigureJob(f"f{i}", _slow_figure, (str(m), HANG_GUARD_S), {}, "") for i, m in enumerate(markers)]
    with pytest.raises(interrupt.Interrupted):
        with html._figure_renderer(analysis, jobs, html.FigureStyle(), 2) as rendered:
            time.sleep(1.0)  # two figures are drawing, two wait for a worker
            processes = list(pools[0]._processes.values())
            interrupt._received.append(signal.SIGTERM)
            try:
                rendered()
            finally:
                interrupt._received.clear()
    assert len(pools) == 1 and len(processes) == 2
    for process in processes:
        process.join(HANG_GUARD_S)
        assert not process.is_alive()
    assert not any(m.exists() for m in markers)  # nothing drawn: killed, not waited for
