"""Benchmark the controls and the report of ``roughsense study`` (issue 37), each a fresh process.

- Ratio: the warm built-in study with 199 shufflings against the same study with ``--permutations 0``, alternated
  round by round (goal <= 1.3x); the peak RSS of each process (goal <= 400 MB); the report stage as a share of the
  ``--permutations 0`` study (goal <= 25 %). ``--peer-src OLD/src`` runs the same pair with another checkout's
  sources in the same rounds (before/after in one run).
- Growth (``--growth``): a smooth-pad study of the 14 gratings at 10 and 20 repetitions (simulated once into a
  scratch folder, features cached by an untimed first run); the controls stage's time and the peak RSS with 199
  shufflings (goals: time at 20 <= 2.2x time at 10; RSS at 20 <= 500 MB).

Stage times are the CLI's own stage lines (``roughsense: controls, ... done in 12.3 s``; a stage under 2 s prints
none). Peak RSS is ``wait4``'s of the study process.

Run: .venv/bin/python benchmarks/bench_issue37.py [--repeats 3] [--peer-src OLD/src] [--growth | --report-only]
(ROUGHSENSE_CACHE_DIR selects the cache; the built-in study is simulated there on first use.)
"""
from __future__ import annotations

import argparse
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

STAGE = re.compile(r"roughsense: ([a-z][a-z -]*?)(?:,[^.]*?)?(?: \(\d+\))? \.\.\. done in ([\d.]+) s")


def study(out: Path, permutations: int, *, src: Path | None = None, data: Path | None = None) -> dict:
    """One fresh ``roughsense study``: wall time, peak RSS (MiB) and its stage times."""
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = str(src.resolve())
    command = [sys.executable, "-m", "roughsense.cli", "study", "--out", str(out), "--force",
               "--permutations", str(permutations)] + ([] if data is None else ["--data", str(data)])
    started = time.perf_counter()
    process = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - started
    err = process.stderr.read()
    process.returncode = os.waitstatus_to_exitcode(status)
    if process.returncode:
        raise SystemExit(f"study failed ({process.returncode}): {err}")
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime, "rss": usage.ru_maxrss / 1024,
            **{name: float(s) for name, s in STAGE.findall(err)}}


def median(runs: list[dict], key: str) -> float:
    values = [run.get(key, float("nan")) for run in runs]
    return statistics.median(values)


def ratio(args, scratch: Path) -> None:
    peers = {"this": None} | ({"peer": args.peer_src} if args.peer_src else {})
    for src in peers.values():  # untimed: the features cache, the first imports
        study(scratch / "warm", 0, src=src)
    shufflings = (0,) if args.report_only else (0, 199)
    runs = {(name, b): [] for name in peers for b in shufflings}
    for _ in range(args.repeats):
        for name, src in peers.items():
            for b in shufflings:
                runs[(name, b)].append(study(scratch / f"{name}-{b}", b, src=src))
    def walls(some: list[dict]) -> str:
        return ", ".join(f"{r['wall']:.1f}" for r in some)

    for name in peers:
        off = runs[(name, 0)]
        if args.report_only:
            report = median(off, "writing the report")
            print(f"{name}: --permutations 0: {median(off, 'wall'):5.1f} s (CPU {median(off, 'cpu'):5.1f} s), report "
                  f"{report:4.1f} s ({report / median(off, 'wall'):.0%} of the study; runs: {walls(off)}; report: "
                  f"{', '.join(str(r.get('writing the report')) for r in off)})")
            continue
        on = runs[(name, 199)]
        print(f"{name}: --permutations 0: {median(off, 'wall'):5.1f} s, {median(off, 'rss'):4.0f} MiB, report "
              f"{median(off, 'writing the report'):4.1f} s ({median(off, 'writing the report') / median(off, 'wall'):.0%} "
              f"of the study); 199: {median(on, 'wall'):5.1f} s, {median(on, 'rss'):4.0f} MiB, controls "
              f"{median(on, 'controls'):4.1f} s -> 199 / 0 = {median(on, 'wall') / median(off, 'wall'):.2f} "
              f"(runs 0: {walls(off)}; 199: {walls(on)})")


def growth(args, scratch: Path) -> None:
    specimens = "R2,R2.5,R3,R3.5,R4,R4.5,R5,C2,C2.5,C3,C3.5,C4,C4.5,C5"
    results = {}
    for repetitions in (10, 20):
        folder = scratch / f"smooth-{repetitions}"
        subprocess.run([sys.executable, "-m", "roughsense.cli", "simulate", "--out", str(folder), "--seed", "0",
                        "--pads", "smooth", "--specimens", specimens, "--repetitions", str(repetitions)],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        study(scratch / "warm", 0, data=folder)  # features into the cache
        results[repetitions] = [study(scratch / f"g{repetitions}", 199, data=folder) for _ in range(args.repeats)]
        off = study(scratch / f"g{repetitions}-0", 0, data=folder)
        on = results[repetitions]
        print(f"{repetitions} repetitions ({14 * 3 * repetitions} images): 199 shufflings {median(on, 'wall'):5.1f} s, "
              f"controls {median(on, 'controls'):5.1f} s, peak {median(on, 'rss'):4.0f} MiB; "
              f"--permutations 0 {off['wall']:5.1f} s, {off['rss']:4.0f} MiB")
    print(f"controls at 20 / at 10 = {median(results[20], 'controls') / median(results[10], 'controls'):.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--peer-src", type=Path, default=None)
    parser.add_argument("--growth", action="store_true", help="Only the growth at 10 and 20 repetitions.")
    parser.add_argument("--report-only", action="store_true",
                        help="Only the --permutations 0 study: the report stage's share (and the study's CPU).")
    args = parser.parse_args()
    print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f} at start")
    scratch = Path(tempfile.mkdtemp(prefix="roughsense-bench-issue37-"))
    (growth if args.growth else ratio)(args, scratch)
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
