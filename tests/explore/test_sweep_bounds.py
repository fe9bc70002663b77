"""Issue 22, runaway inputs of explore and protocol: every count and size is bounded before any work, every
scheduler address that is not a Dask scheduler is one line within 10 s, and a sweep streams its cells."""
from __future__ import annotations

import http.server
import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import pytest

from roughsense.explore import runner
from roughsense.explore.runner import run_sweep
from roughsense.explore.sweep import read_sweep

SPECIMENS = '["R2", "R3", "R4", "C3", "rect:1.5"]'
TINY = f"""
[sweep]
seeds = [0]
repetitions = 2
specimens = {SPECIMENS}
image_size_px = [480, 160]
max_components = 4
[axes]
pad = ["smooth"]
"""


def _sweep_file(tmp_path: Path, text: str = TINY) -> Path:
    path = tmp_path / "sweep.toml"
    path.write_text(text)
    return path


def _one_error(result, *names: str) -> str:
    code, out, err = result
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("roughsense: error: "), (code, err)
    assert "Traceback" not in err and "internal error" not in err
    for name in names:
        assert name in lines[0], (name, lines[0])
    return lines[0]


# --------------------------------------------------------------------------- item 7: addresses that answer


@pytest.fixture
def silent_port():
    """A TCP socket on 127.0.0.1 that accepts connections and never sends a byte."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    accepted, stop = [], threading.Event()

    def accept():
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                accepted.append(server.accept()[0])
            except OSError:
                continue

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    yield server.getsockname()[1]
    stop.set()
    thread.join(timeout=5)
    for conn in accepted:
        conn.close()
    server.close()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    """Answers like any web server, but keeps its request log off the stderr the test reads."""

    def log_message(self, format, *args):
        pass


@pytest.fixture
def http_port():
    """An HTTP server on 127.0.0.1 in a thread (it answers requests, and says nothing until asked)."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _QuietHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server.server_address[1]
    server.shutdown()
    server.server_close()


@pytest.mark.parametrize("listener", ["silent_port", "http_port"])
def test_a_port_that_is_not_a_dask_scheduler_is_one_line(tmp_path, run_cli, request, listener):
    # The probe's time is measured by benchmarks/bench_refusals.py (a test asserts no wall-clock bound).
    port = request.getfixturevalue(listener)
    result = run_cli("explore", _sweep_file(tmp_path), "--out", tmp_path / "out", "--scheduler",
                     f"tcp://127.0.0.1:{port}")
    _one_error(result, "--scheduler", f"127.0.0.1:{port}", "cannot reach the Dask scheduler")
    assert not (tmp_path / "out" / "results").exists()


@pytest.mark.parametrize("name, content, message", [
    ("plain.txt", "hello\n", "is not a Dask scheduler file"),
    ("missing.json", None, "no such scheduler file"),
    ("garbage.json", "{\"not\": 1}", 'no "address"'),
    ("broken.json", "nonsense {", "is not a Dask scheduler file"),
    ("list.json", "[1, 2]", 'no "address"'),
])
def test_a_scheduler_file_that_is_not_one_is_one_line_naming_it(tmp_path, run_cli, name, content, message):
    path = tmp_path / name
    if content is not None:
        path.write_text(content)
    _one_error(run_cli("explore", _sweep_file(tmp_path), "--out", tmp_path / "out", "--scheduler", path),
               str(path), "--scheduler", message)
    assert not (tmp_path / "out" / "results").exists()


@pytest.mark.parametrize("value, message", [
    ("", "--scheduler is empty"),
    ("   ", "--scheduler is empty"),
    ("nowhere", "neither a scheduler file (.json) nor an address"),
    ("tcp://127.0.0.1:99999", "neither a scheduler file"),
    ("tls://127.0.0.1:8786", "only tcp:// addresses"),
])
def test_an_empty_or_malformed_address_is_refused_not_a_local_cluster(tmp_path, run_cli, monkeypatch, value, message):
    def no_cluster(*args, **kwargs):
        raise AssertionError("a local cluster was started")

    monkeypatch.setattr("distributed.LocalCluster", no_cluster)
    _one_error(run_cli("explore", _sweep_file(tmp_path), "--out", tmp_path / "out", "--scheduler", value),
               "--scheduler", message)


def test_the_client_that_will_not_close_is_a_warning_not_a_traceback():
    class Stuck:
        def close(self, timeout=None):
            raise TimeoutError("timed out after 10 s.")

    with pytest.warns(Warning, match="did not close cleanly"):
        runner._close(Stuck())


# --------------------------------------------------------------------------- items 8 and 10: counts of options


def test_workers_beyond_the_bound_are_refused_before_any_work(tmp_path, run_cli, monkeypatch):
    monkeypatch.setattr(runner, "default_workers", lambda: 2)  # the bound is 4 per usable core
    for workers in ("100000", "9", "0"):
        line = _one_error(run_cli("explore", tmp_path / "absent.toml", "--out", tmp_path / "out", "--jobs", workers),
                          "--jobs", "from 1 to 8")
        assert "absent.toml" not in line  # refused before the sweep file is even read
    assert not (tmp_path / "out").exists()
    with pytest.raises(Exception, match="--jobs must be from 1 to 8"):
        run_sweep(read_sweep(_sweep_file(tmp_path)), tmp_path / "out", n_jobs=100000)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args, message", [
    (["--participants", "10000000"], "--participants must be at most 1000, got 10000000"),
    (["--sessions", "1000000000"], "--sessions must be at most 100, got 1000000000"),
    (["--participants", "1000", "--sessions", "100"], "1300000 trials, above the limit of 1000000"),
])
def test_protocol_sizes_are_bounded_before_any_work(tmp_path, run_cli, args, message):
    _one_error(run_cli("protocol", "--out", tmp_path / "schedule.csv", "--seed", "1", *args), message)
    assert not (tmp_path / "schedule.csv").exists()


def test_the_schedule_function_refuses_before_making_ids():
    import numpy as np

    from roughsense.analysis.magnitude_estimation import MAX_PARTICIPANTS, make_schedule
    from roughsense.errors import ConfigError

    with pytest.raises(ConfigError, match="participants must be at most 1000"):
        make_schedule(["R2", "R3", "R4"], 10**12, 3, rng=np.random.default_rng(0))
    schedule = make_schedule(["R2", "R3", "R4"], MAX_PARTICIPANTS, 1, rng=np.random.default_rng(0))
    assert len(schedule) == MAX_PARTICIPANTS * 2  # the bound itself is accepted


# --------------------------------------------------------------------------- item 9: the sweep file


GRID = TINY.replace('pad = ["smooth"]', 'pad = ["fingerprint"]\nfingerprint_period_mm = ['
                    + ", ".join(f"{1 + i / 1000:.4f}" for i in range(1000)) + "]\nridge_height_mm = ["
                    + ", ".join(f"{0.1 + i / 10000:.4f}" for i in range(1000)) + "]")


@pytest.mark.parametrize("text, key, message", [
    (TINY.replace("repetitions = 2", "repetitions = 1000000000"), "[sweep] repetitions", "from 2 to 10000"),
    (TINY.replace("[axes]", "forces_n = [1e300]\n[axes]"), "[sweep] forces_n", "up to 100"),
    (TINY + "forces_n = [[1, 2], [1e300]]\n", "[axes] forces_n", "up to 100"),
    (TINY.replace('"rect:1.5"', '"rect:1e300"'), "[sweep] specimens", "wavelength must be from 0.02 to 50 mm"),
    (TINY.replace('"rect:1.5"', '"rect:1.5:1e300"'), "[sweep] specimens", "groove depth must be above 0 and at most 10"),
    (TINY.replace('"rect:1.5"', '"sin:1.5:1e300"'), "[sweep] specimens", "amplitude"),
    (TINY.replace("[axes]", "field_length_mm = 1e7\n[axes]"), "[sweep] field_length_mm", "above the limit of 100 Mpx"),
    (TINY.replace("[axes]", "field_length_mm = 1e308\n[axes]"), "[sweep] field_length_mm", "above the limit of 100 Mpx"),
    (TINY + "field_length_mm = [20, 1e308]\n", "[axes] field_length_mm", "above the limit of 100 Mpx"),
    (TINY.replace('pad = ["smooth"]', 'pad = ["fingerprint"]\nfingerprint_period_mm = [1e-6]'),
     "[axes] fingerprint_period_mm", "from 0.02 to 50 mm"),
    (TINY.replace("[axes]", "ridge_height_mm = 1e300\n[axes]"), "[sweep] ridge_height_mm", "at most 10 mm"),
    (TINY.replace("[axes]", "pad_modulus_mpa = 1e300\n[axes]"), "[sweep] pad_modulus_mpa", "from 0.001 to 1000 MPa"),
    (TINY.replace("[axes]", "participants = 200000\n[axes]"), "[sweep] participants", "from 2 to 1000"),
    (TINY.replace("[axes]", "sessions = 1000000\n[axes]"), "[sweep] sessions", "from 1 to 100"),
    (TINY.replace("[axes]", "participants = 1000\nsessions = 100\n[axes]"), "[sweep] participants x [sweep] sessions",
     "above the simulated panel's limit of 2000"),
    (TINY.replace("repetitions = 2", "repetitions = 10000").replace("[axes]", "forces_n = [1, 2, 3]\n[axes]"),
     "[sweep] repetitions", "150000 frames, above the limit of 20000"),
    (GRID, "[axes]", "1000000 cells, above the limit of 100000"),
    (TINY + "field_length_mm = [55.0, 55.01]\n", "[axes] field_length_mm", "55 and 55.01 mm make the same frame"),
])
def test_sweep_counts_and_sizes_are_bounded_naming_the_file_and_key(tmp_path, run_cli, monkeypatch, text, key, message):
    from roughsense.explore import cell

    def no_cell(*args, **kwargs):
        raise AssertionError("a cell ran")

    monkeypatch.setattr(cell, "cell_rows", no_cell)
    path = _sweep_file(tmp_path, text)
    _one_error(run_cli("explore", path, "--out", tmp_path / "out"), str(path), key, message)  # no cell ran (no_cell)
    assert not (tmp_path / "out").exists()


def test_a_sweep_file_above_the_size_limit_is_refused_unparsed(tmp_path, run_cli):
    from roughsense.explore.sweep import MAX_SWEEP_BYTES

    path = _sweep_file(tmp_path, TINY + "#" * MAX_SWEEP_BYTES + "\n")
    _one_error(run_cli("explore", path, "--out", tmp_path / "out"), str(path), f"above the limit of {MAX_SWEEP_BYTES}")


def test_the_bounds_themselves_are_accepted(tmp_path):
    from roughsense.explore.sweep_cells import MAX_CELLS

    text = TINY.replace("seeds = [0]", f"seeds = {list(range(MAX_CELLS // 2))}").replace(
        'pad = ["smooth"]', 'pad = ["smooth"]\nfield_length_mm = [55.0, 55.05]')  # 1922 and 1924 px: two frames
    sweep = read_sweep(_sweep_file(tmp_path, text))
    assert len(sweep.cells) == MAX_CELLS == len({c.id for c in sweep.cells})


# --------------------------------------------------------------------------- streaming and scratch space


def no_op_cell(cell):
    """A cell that fails at once (nothing is written): the stream is what the test watches."""
    return {"cell": cell, "results": None, "specimens": None, "error": f"skipped {cell.seed}"}


def test_a_large_sweep_streams_its_cells_and_shows_progress_from_the_first(tmp_path, monkeypatch):
    """A window of cells in flight (2 per worker thread here), the next submitted as one finishes, never one graph;
    on a real scheduler reached by its address (which therefore passes the probe)."""
    from distributed import Client, LocalCluster

    monkeypatch.setattr(runner, "MIN_WINDOW", 1)
    sweep = read_sweep(_sweep_file(tmp_path, TINY.replace("seeds = [0]", f"seeds = {list(range(12))}")))
    submitted: list[str] = []
    original = Client.submit

    def counting(self, *args, **kwargs):
        submitted.append(kwargs["key"])
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Client, "submit", counting)
    seen: list[int] = []

    def progress(stream, total, description):
        for item in stream:
            seen.append(len(submitted))
            yield item

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp", dashboard_address=None,
                      host="127.0.0.1") as cluster:
        outcome = run_sweep(sweep, tmp_path / "out", scheduler=cluster.scheduler_address, progress=progress,
                            task=no_op_cell)
    assert len(outcome.failures) == 12 and sorted(f["seed"] for f in outcome.failures) == list(range(12))
    assert len(seen) == 12 and seen[0] <= 3  # the first cell is reported with at most a window (+1) submitted
    assert len(submitted) == len(set(submitted)) == 12


def test_local_workers_keep_their_scratch_space_under_out_and_remove_it(tmp_path):
    """A LocalCluster run in a fresh interpreter with its own TMPDIR: nothing is left there nor under --out."""
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    out = tmp_path / "out"
    script = ("import sys\n"
              "from roughsense.explore.runner import run_sweep\n"
              "from roughsense.explore.sweep import read_sweep\n"
              "from tests.explore.test_sweep_bounds import no_op_cell\n"
              f"outcome = run_sweep(read_sweep({str(_sweep_file(tmp_path))!r}), {str(out)!r}, n_jobs=1, "
              "task=no_op_cell)\n"
              "print(len(outcome.failures))\n")
    root = Path(__file__).parents[2]
    env = {**os.environ, "TMPDIR": str(tmpdir),
           "PYTHONPATH": os.pathsep.join([str(root), str(root / "src"), *sys.path])}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120,
                          cwd=root)
    assert done.returncode == 0 and done.stdout.split() == ["1"], done.stderr[-2000:]
    assert list(tmpdir.iterdir()) == []  # no dask-scratch-space in $TMPDIR
    assert not [p.name for p in out.iterdir() if "scratch" in p.name]
    assert tempfile.gettempdir() != str(tmpdir)


def test_scheduler_file_of_a_real_scheduler_is_followed(tmp_path):
    """The file's address is read by roughsense, then probed as an address is."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, protocol="tcp", dashboard_address=None,
                      host="127.0.0.1") as cluster:
        path = tmp_path / "scheduler.json"
        path.write_text(json.dumps({"address": cluster.scheduler_address, "type": "Scheduler"}))
        assert runner.scheduler_address(str(path)) == cluster.scheduler_address


@pytest.mark.parametrize("args, message", [
    (["--specimens", "R2,R3,R4,rect:1e300"], "--specimens: specimen 'rect_1e300': the wavelength must be from 0.02"),
    (["--specimens", "R2,R3,R4,sin:2:1e300"], "the amplitude must be above 0 and at most 10 mm"),
    (["--pads", "fingerprint", "--ridge-height-mm", "1e300"], "--ridge-height-mm must be above 0 and at most 10 mm"),
])
def test_simulate_states_the_same_bounds_of_the_twin(tmp_path, run_cli, args, message):
    """The sibling of the sweep's bounds: the same design through `simulate` (was an internal ValueError)."""
    _one_error(run_cli("simulate", "--out", tmp_path / "study", "--repetitions", "1", *args), message)
    assert not (tmp_path / "study").exists()
