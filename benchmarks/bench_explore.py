"""Benchmark ``roughsense explore`` (issue 13).

1. One paper-sized cell (one pad, 14 specimens, 3 forces, 10 repetitions) computed in memory on one core, against
   the same cell through the files path a user would otherwise take: ``roughsense simulate --jobs 1`` then
   ``roughsense study`` on that folder (bar: the cell <= 10 s).
2. A sweep of cells on a LocalCluster with 1 and with 2 workers, started by the sweep and already running
   (bar: 2 workers >= 1.7x faster than 1).

    .venv/bin/python benchmarks/bench_explore.py [--repetitions 10] [--cells 4] [--repeats 1] [--skip-files]
        [--pads smooth,fingerprint]

Run it on a quiet machine: both parts are wall-clock ratios, and part 2 needs two idle cores.
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _one_core() -> None:
    """Pin this process (and its children) to one core, and keep BLAS single-threaded."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})


def _sweep(path: Path, *, pads: list[str], repetitions: int, seeds: list[int]) -> Path:
    path.write_text(
        "[sweep]\n"
        f"seeds = {seeds}\nrepetitions = {repetitions}\nspecimens = \"paper\"\n"
        "[axes]\n"
        f"pad = {pads}\n"
    )
    return path


def bench_cell(repetitions: int, repeats: int, skip_files: bool, pad: str = "smooth") -> None:
    from roughsense.explore.cell import run_cell
    from roughsense.explore.sweep import read_sweep

    tmp = Path(tempfile.mkdtemp(prefix="bench-explore-"))
    try:
        sweep = read_sweep(_sweep(tmp / "cell.toml", pads=[pad], repetitions=repetitions, seeds=[0]))
        cell = sweep.cells[0]
        small = read_sweep(_sweep(tmp / "warm.toml", pads=[pad], repetitions=2, seeds=[0])).cells[0]
        run_cell(small)  # first use: the panel calibration and imports, paid once per worker process
        times = []
        for _ in range(repeats):
            started = time.perf_counter()
            result = run_cell(cell)
            times.append(time.perf_counter() - started)
            assert result["error"] is None, result["error"]
        cell_s = statistics.median(times)
        trials = len(cell.specimens) * len(cell.forces_n) * cell.repetitions
        print(f"one cell in memory ({pad} pad, {len(cell.specimens)} specimens x 3 forces x {repetitions} reps = "
              f"{trials} frames), one core: {cell_s:.2f} s (median of {repeats}); bar 10 s at 10 repetitions")
        if skip_files:
            return
        env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "ROUGHSENSE_CACHE_DIR": str(tmp / "cache")}
        cli = [sys.executable, "-m", "roughsense.cli"]
        started = time.perf_counter()
        subprocess.run([*cli, "simulate", "--out", str(tmp / "study"), "--pads", pad, "--repetitions",
                        str(repetitions), "--jobs", "1"], check=True, env=env, stdout=subprocess.DEVNULL)
        simulated = time.perf_counter() - started
        # --permutations 0: the cell runs no permutation controls either, so both paths do the same analysis
        subprocess.run([*cli, "study", "--study", str(tmp / "study"), "--out", str(tmp / "report"), "--jobs", "1",
                        "--permutations", "0"],
                       check=True, env=env, stdout=subprocess.DEVNULL)
        files_s = time.perf_counter() - started
        print(f"same cell through files: simulate {simulated:.2f} s + study {files_s - simulated:.2f} s = "
              f"{files_s:.2f} s (one core)")
        print(f"ratio files path / in-memory cell: {files_s / cell_s:.2f}x")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def bench_workers(cells: int, repetitions: int) -> None:
    import logging

    from distributed import LocalCluster

    from roughsense.explore.runner import run_sweep
    from roughsense.explore.sweep import read_sweep

    tmp = Path(tempfile.mkdtemp(prefix="bench-explore-"))
    try:
        sweep = read_sweep(_sweep(tmp / "sweep.toml", pads=["smooth"], repetitions=repetitions,
                                  seeds=list(range(cells))))
        timings, running = {}, {}
        for workers in (1, 2):
            started = time.perf_counter()
            outcome = run_sweep(sweep, tmp / f"out{workers}", n_jobs=workers)
            timings[workers] = time.perf_counter() - started
            assert outcome.computed == cells and not outcome.failures
            # The same sweep on a cluster that is already up (as with --scheduler): the sweeping alone.
            with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                              silence_logs=logging.ERROR) as cluster:
                started = time.perf_counter()
                outcome = run_sweep(sweep, tmp / f"running{workers}", scheduler=cluster.scheduler_address)
                running[workers] = time.perf_counter() - started
                assert outcome.computed == cells and not outcome.failures
        print(f"sweep of {cells} cells ({repetitions} reps each), LocalCluster incl. start-up: "
              f"1 worker {timings[1]:.1f} s, 2 workers {timings[2]:.1f} s; speed-up {timings[1] / timings[2]:.2f}x")
        print(f"the same on a running LocalCluster: 1 worker {running[1]:.1f} s, 2 workers {running[2]:.1f} s; "
              f"speed-up {running[1] / running[2]:.2f}x (bar >= 1.7x)")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repetitions", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cells", type=int, default=8)
    parser.add_argument("--sweep-repetitions", type=int, default=10)
    parser.add_argument("--skip-files", action="store_true")
    parser.add_argument("--pads", default="smooth,fingerprint", help="Pads to time a cell of, comma-separated.")
    parser.add_argument("--skip-workers", action="store_true")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT / "src"))
    print(f"load average at start: {os.getloadavg()[0]:.2f}")
    if not args.skip_workers:
        bench_workers(args.cells, args.sweep_repetitions)  # before pinning: needs two cores
    _one_core()
    for pad in args.pads.split(","):
        bench_cell(args.repetitions, args.repeats, args.skip_files, pad.strip())
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
