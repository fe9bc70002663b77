"""Benchmark how long ``roughsense study`` takes to end after SIGTERM (or Ctrl-C) while it writes the report's figures.

A small simulated study (both pads, the paper's 14 specimens and 3 forces, 2 repetitions: the report's figures are
as many as the full study's) is analysed with ``--permutations 0`` into a report, its figures at 1200 dpi so that
they take long enough to be stopped while they draw. Each repeat starts the command,
waits until its log says "writing the report" (announced 2 s into that stage, so figures are rendering), sends the
signal and times the exit. The report folder must be absent afterwards (nothing half-written), and no worker left.

Run: .venv/bin/python benchmarks/bench_interrupt.py [--repeats 3] [--signal TERM|INT] [--study DIR]
"""
from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _study(folder: Path) -> Path:
    from roughsense.sim.config import SimulationConfig
    from roughsense.sim.simulate import simulate_study

    simulate_study(folder, SimulationConfig(repetitions=2, seed=3), jobs=2)
    return folder


def _one(study: Path, out: Path, signum: int) -> tuple[float, int, bool]:
    command = [sys.executable, "-m", "roughsense.cli", "study", "--study", str(study), "--out", str(out),
               "--permutations", "0", "--no-loso", "--jobs", "2", "--dpi", "1200"]  # figures slow to draw
    run = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, start_new_session=True)
    seen = ""
    while "writing the report" not in seen:
        char = run.stderr.read(1)
        if not char:
            raise SystemExit(f"the run ended before its report: {seen}")
        seen += char
    time.sleep(0.5)  # figures are rendering in the workers
    sent = time.perf_counter()
    os.killpg(run.pid, signum) if signum == signal.SIGINT else run.send_signal(signum)
    run.wait(timeout=120)
    seconds = time.perf_counter() - sent
    run.stderr.close()
    return seconds, run.returncode, out.exists()


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--signal", choices=("TERM", "INT"), default="TERM")
    parser.add_argument("--study", type=Path)
    args = parser.parse_args()
    signum = getattr(signal, f"SIG{args.signal}")
    with tempfile.TemporaryDirectory() as tmp:
        study = args.study or _study(Path(tmp) / "study")
        subprocess.run([sys.executable, "-m", "roughsense.cli", "study", "--study", str(study), "--out",
                        str(Path(tmp) / "warm"), "--permutations", "0", "--no-loso", "--jobs", "2"], check=True,
                       capture_output=True)  # features cached: each repeat reaches the report quickly
        times = []
        for i in range(args.repeats):
            seconds, code, left = _one(study, Path(tmp) / f"report{i}", signum)
            times.append(seconds)
            print(f"SIG{args.signal} -> exit {code} in {seconds:.2f} s; report folder left: {left}")
        print(f"median {statistics.median(times):.2f} s, max {max(times):.2f} s over {args.repeats} "
              f"(load {os.getloadavg()[0]:.1f})")


if __name__ == "__main__":
    main()
