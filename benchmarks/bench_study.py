"""Benchmark the main job, ``roughsense study``, from an empty cache and with the cache warm.

Budgets (issue 6): the whole study from an empty cache <= 120 s; with the cache warm <= 30 s.
The peer measured in the same run is the part of the job that is not roughsense's analysis: plain
decoding (cv2.imread) of every image of the study, which any analysis of these images must pay.
Each run is a fresh process, as a user would run it; peak RSS covers the process and its children.

Run: .venv/bin/python benchmarks/bench_study.py [--warm-repeats 3] [--keep-cache DIR]
"""
from __future__ import annotations

import argparse
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def run_study(cache: Path, out: Path) -> float:
    env = dict(os.environ, ROUGHSENSE_CACHE_DIR=str(cache))
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "roughsense.cli", "study", "--out", str(out), "--force"],
                   env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - started


def decode_all(study: Path) -> float:
    import cv2
    import pandas as pd

    images = pd.read_csv(study / "manifest.csv")["image"]
    started = time.perf_counter()
    for image in images:
        cv2.imread(str(study / image), cv2.IMREAD_UNCHANGED)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--warm-repeats", type=int, default=3)
    parser.add_argument("--keep-cache", type=Path, default=None, help="Use (and keep) this cache folder.")
    args = parser.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="roughsense-bench-study-"))
    cache = args.keep_cache or scratch / "cache"
    if cache.exists() and args.keep_cache is None:
        shutil.rmtree(cache)
    try:
        load = os.getloadavg()[0]
        print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
              f"load average {load:.1f} at start")
        cold = run_study(cache, scratch / "report")
        warm = [run_study(cache, scratch / "report") for _ in range(args.warm_repeats)]
        study = next(cache.glob("simulated-study-*"))
        decode = decode_all(study)
        peak_mib = max(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, 0) / 1024
        warm_median = statistics.median(warm)
        print(f"  empty cache (simulate 840 images + features + analysis + report): {cold:6.1f} s  "
              f"budget 120 s -> {cold / 120:.2f} of budget")
        print(f"  warm cache (median of {len(warm)}):                                {warm_median:6.1f} s  "
              f"budget  30 s -> {warm_median / 30:.2f} of budget")
        print(f"  peer: plain cv2.imread of the study's {len(list((study / 'images').iterdir()))} images: {decode:6.1f} s "
              f"-> warm study / plain decoding = {warm_median / decode:.2f}")
        print(f"  cold / warm = {cold / warm_median:.1f}; peak RSS of one study process: {peak_mib:.0f} MiB")
        print(f"  load average at the end: {os.getloadavg()[0]:.1f}")
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    main()
