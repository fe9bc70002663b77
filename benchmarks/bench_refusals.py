"""Benchmark how quickly the CLI refuses what it must refuse (issue 37: the suite asserts no wall-clock bound).

The tests check that each of these is refused, with one line and no output; how long the refusal takes is measured
here, each a fresh ``roughsense`` process, against the peer every command pays: ``roughsense --version`` (the
interpreter, typer and the lazy package). The ratios are the robust part on a shared machine.

- ``silent port``: explore against a TCP port that accepts and says nothing (the scheduler probe's timeout);
- ``unreachable``: explore against a closed port;
- ``huge grid``: a sweep of 1000 x 1000 cells, counted and refused, never built;
- ``protocol``: a rating schedule of 1.3 million trials, refused before any id is made;
- ``locked``: a second explore into a folder a first explore is computing (the lock's refusal).

Run: .venv/bin/python benchmarks/bench_refusals.py [--repeats 5]
"""
from __future__ import annotations

import argparse
import os
import platform
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

TINY = """
[sweep]
seeds = [0]
repetitions = 2
specimens = ["R2", "R3", "R4", "C3", "rect:1.5"]
image_size_px = [480, 160]
max_components = 3
[axes]
pad = ["smooth"]
"""
GRID = TINY.replace('pad = ["smooth"]', 'pad = ["fingerprint"]\nfingerprint_period_mm = ['
                    + ", ".join(f"{1 + i / 1000:.4f}" for i in range(1000)) + "]\nridge_height_mm = ["
                    + ", ".join(f"{0.1 + i / 10000:.4f}" for i in range(1000)) + "]")
BIG = TINY.replace("seeds = [0]", f"seeds = {list(range(400))}")  # busy for the whole benchmark; killed at its end


def cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "roughsense.cli", *args]


def timed(command: list[str]) -> tuple[float, int]:
    started = time.perf_counter()
    result = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    return time.perf_counter() - started, result.returncode


def silent_port() -> int:
    """A listener that accepts connections and never answers (in a daemon thread)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(16)
    held = []
    threading.Thread(target=lambda: [held.append(server.accept()) for _ in iter(int, 1)], daemon=True).start()
    return server.getsockname()[1]


def locked_case(folder: Path, sweep: Path) -> list[str]:
    """Start a first explore that holds ``folder/out``; the command of the second one."""
    first = subprocess.Popen(cli("explore", str(sweep), "--out", str(folder / "out"), "--jobs", "1"),
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    from roughsense._util.lock import lock_path

    lock = lock_path(folder / "out")
    while not (lock.exists() and lock.stat().st_size) and first.poll() is None:
        time.sleep(0.05)
    locked_case.first = first
    return cli("explore", str(sweep), "--out", str(folder / "out"), "--force")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="bench-refusals-"))
    (folder / "tiny.toml").write_text(TINY)
    (folder / "grid.toml").write_text(GRID)
    (folder / "big.toml").write_text(BIG)
    port = silent_port()
    cases = {
        "peer: --version": cli("--version"),
        "silent port": cli("explore", str(folder / "tiny.toml"), "--out", str(folder / "a"), "--scheduler",
                           f"tcp://127.0.0.1:{port}"),
        "unreachable": cli("explore", str(folder / "tiny.toml"), "--out", str(folder / "b"), "--scheduler",
                           "tcp://127.0.0.1:9"),
        "huge grid": cli("explore", str(folder / "grid.toml"), "--out", str(folder / "c")),
        "protocol": cli("protocol", "--out", str(folder / "s.csv"), "--participants", "1000", "--sessions", "100"),
        "locked": locked_case(folder, folder / "big.toml"),
    }
    times: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(args.repeats):  # round by round, so a load change hits every case alike
        for name, command in cases.items():
            seconds, code = timed(command)
            if code != (0 if name.startswith("peer") else 2):
                raise SystemExit(f"{name}: exit {code}, expected a refusal")
            times[name].append(seconds)
    locked_case.first.terminate()
    locked_case.first.wait(timeout=60)
    peer = statistics.median(times["peer: --version"])
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; "
          f"median of {args.repeats}")
    for name, values in times.items():
        median = statistics.median(values)
        print(f"{name:18s} {median:6.2f} s  x{median / peer:5.2f} the peer  (max {max(values):.2f} s)")


if __name__ == "__main__":
    main()
