"""Benchmark the main job, ``roughsense study``, from an empty cache and with the cache warm.

Budgets (issue 6): the whole study from an empty cache <= 120 s; with the cache warm <= 30 s.
The peer measured in the same run is the part of the job that is not roughsense's analysis: plain
decoding (cv2.imread) of every image of the study, which any analysis of these images must pay.
Each run is a fresh process, as a user would run it; peak RSS covers the process and its children.

The cold run also reports the simulated study's size on disk (issue 12: <= 40 s cold on 2 cores, <= 400 MB).
``--peer-src DIR`` runs the same cold study with another checkout's sources (e.g. the code before issue 12) in the
same run, as the peer of this one, each in its own empty cache.

Run: .venv/bin/python benchmarks/bench_study.py [--warm-repeats 3] [--cold-repeats 3] [--keep-cache DIR] [--peer-src OLD/src]
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


def run_study(cache: Path, out: Path, src: Path | None = None) -> float:
    env = dict(os.environ, ROUGHSENSE_CACHE_DIR=str(cache))
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(src.resolve()), *filter(None, [os.environ.get("PYTHONPATH")])])
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


def study_size(cache: Path) -> tuple[int, int]:
    """Bytes and number of the cached study's files (images and tables)."""
    files = [p for p in next(cache.glob("simulated-study-*")).rglob("*") if p.is_file()]
    return sum(p.stat().st_size for p in files), len(files)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--warm-repeats", type=int, default=3)
    parser.add_argument("--cold-repeats", type=int, default=1, help="Empty-cache runs (the median is quoted).")
    parser.add_argument("--keep-cache", type=Path, default=None, help="Use (and keep) this cache folder.")
    parser.add_argument("--peer-src", type=Path, default=None,
                        help="Also run the cold study with these sources (another checkout's src/) as the peer.")
    args = parser.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="roughsense-bench-study-"))
    cache = args.keep_cache or scratch / "cache"
    if cache.exists() and args.keep_cache is None:
        shutil.rmtree(cache)
    try:
        load = os.getloadavg()[0]
        print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
              f"load average {load:.1f} at start")
        colds = []
        for repeat in range(max(args.cold_repeats, 1)):
            if repeat and args.keep_cache is None:  # never empty a folder the caller gave us
                shutil.rmtree(cache, ignore_errors=True)
            elif repeat:
                break
            colds.append(run_study(cache, scratch / "report"))
        cold = statistics.median(colds)
        size, files = study_size(cache)
        warm = [run_study(cache, scratch / "report") for _ in range(args.warm_repeats)]
        study = next(cache.glob("simulated-study-*"))
        decode = decode_all(study)
        peak_mib = max(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, 0) / 1024
        warm_median = statistics.median(warm)
        print(f"  empty cache (simulate 840 images + features + analysis + report), median of {len(colds)}: "
              f"{cold:6.1f} s  (runs: {', '.join(f'{c:.1f}' for c in colds)})  "
              f"budget 120 s -> {cold / 120:.2f} of budget")
        print(f"  simulated study on disk: {size / 1e6:6.0f} MB in {files} files      budget 400 MB -> "
              f"{size / 400e6:.2f} of budget; cold budget 40 s -> {cold / 40:.2f}")
        if args.peer_src is not None:
            peer_cache = scratch / "peer-cache"
            peer_cold = run_study(peer_cache, scratch / "peer-report", src=args.peer_src)
            peer_size, _ = study_size(peer_cache)
            shutil.rmtree(peer_cache, ignore_errors=True)
            print(f"  peer {args.peer_src}: empty cache {peer_cold:6.1f} s, study {peer_size / 1e6:6.0f} MB -> "
                  f"this / peer: time {cold / peer_cold:.2f}, size {size / peer_size:.2f}")
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
