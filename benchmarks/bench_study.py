"""Benchmark the main job, ``roughsense study``, from an empty cache and with the cache warm.

Budgets (issue 6): the whole study from an empty cache <= 120 s; with the cache warm <= 30 s.
The peer measured in the same run is the part of the job that is not roughsense's analysis: plain
decoding (cv2.imread) of every image of the study, which any analysis of these images must pay.
Each run is a fresh process, as a user would run it; peak RSS covers the process and its children.

The cold run also reports the simulated study's size on disk (issue 12: <= 40 s cold on 2 cores, <= 400 MB).
``--peer-src DIR`` runs the same cold study with another checkout's sources (e.g. the code before issue 12) in the
same run, as the peer of this one, each in its own empty cache.

What the second model family costs (issue 19: the peak law adds <= 10 s to a warm study, controls included): the
warm analysis (features from the cache, 199 permutations, LOO and nested LOSO, as ``study`` runs it) with the paper's
PLS alone and with every family, alternated, median of ``--model-repeats`` each (after one untimed run of each, so
neither pays the first call's imports and worker start-up). ``--models-only`` measures just that, in ``--keep-cache``
(default: roughsense's own cache), simulating the built-in study there first if it is missing.

Cold against earlier code (issue 37: a cold ``make study`` <= 60 % of e1630a3's): ``--cold-only --cold-peer OLD/src``
(repeatable) runs the cold study with this checkout's sources and each peer's, alternated round by round (the order
rotated each round), each run in its own empty cache; it prints each one's median, its stage times (the CLI's stage
lines) and this / peer.

Run: .venv/bin/python benchmarks/bench_study.py [--warm-repeats 3] [--cold-repeats 3] [--keep-cache DIR] [--peer-src OLD/src]
     [--model-repeats 3] [--models-only] [--cold-only --cold-peer OLD/src [--cold-peer OLDER/src]]
"""
from __future__ import annotations

import argparse
import os
import platform
import re
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


STAGE = re.compile(r"roughsense: ([a-z][a-z -]*?)(?:,[^.]*?)?(?: \(\d+\))? \.\.\. done in ([\d.]+) s")


def cold_study(scratch: Path, src: Path | None) -> dict[str, float]:
    """One study from an empty cache (``src``: another checkout's sources): wall time and the CLI's stage times."""
    cache = scratch / "cold-cache"
    shutil.rmtree(cache, ignore_errors=True)
    env = dict(os.environ, ROUGHSENSE_CACHE_DIR=str(cache))
    if src is not None:
        env["PYTHONPATH"] = str(src.resolve())
    started, before = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run([sys.executable, "-m", "roughsense.cli", "study", "--out", str(scratch / "report"), "--force"],
                          env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall, after = time.perf_counter() - started, resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)  # the process tree, workers too
    shutil.rmtree(cache, ignore_errors=True)
    return {"wall": wall, "cpu": cpu, **{name: float(seconds) for name, seconds in STAGE.findall(done.stderr)}}


def report_cold_peers(peers: list[Path], repeats: int) -> None:
    """This checkout's cold study against each peer's, alternated (the order rotated every round)."""
    names = ["this", *(str(p) for p in peers)]
    sources: list[Path | None] = [None, *peers]
    runs: dict[str, list[dict[str, float]]] = {name: [] for name in names}
    scratch = Path(tempfile.mkdtemp(prefix="roughsense-bench-cold-"))
    try:
        for round_ in range(repeats):
            order = list(range(len(names)))[round_ % len(names):] + list(range(len(names)))[:round_ % len(names)]
            for i in order:
                runs[names[i]].append(cold_study(scratch, sources[i]))
                print(f"  round {round_ + 1}: {names[i]} {runs[names[i]][-1]['wall']:.1f} s "
                      f"(load {os.getloadavg()[0]:.1f})", flush=True)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    this = statistics.median(r["wall"] for r in runs["this"])
    this_cpu = statistics.median(r["cpu"] for r in runs["this"])
    for name in names:
        stages = sorted({stage for run in runs[name] for stage in run if stage not in ("wall", "cpu")})
        median, cpu = (statistics.median(r[key] for r in runs[name]) for key in ("wall", "cpu"))
        parts = ", ".join(f"{stage} {statistics.median(r.get(stage, 0.0) for r in runs[name]):.1f} s" for stage in stages)
        walls = ", ".join(f"{r['wall']:.1f}" for r in runs[name])
        print(f"  {name}: cold study median {median:.1f} s (runs: {walls}), CPU {cpu:.1f} s; {parts}"
              + ("" if name == "this" else f"; this / peer = {this / median:.2f} (CPU {this_cpu / cpu:.2f})"))


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


def model_cost(cache: Path, repeats: int, jobs: int = 2) -> dict[tuple[str, ...], list[float]]:
    """Seconds of the warm analysis of the built-in study (seed 0) per set of model families, alternated."""
    os.environ["ROUGHSENSE_CACHE_DIR"] = str(cache)
    from roughsense._util import cache as features_cache
    from roughsense.analysis import dataset
    from roughsense.analysis.study_analysis import analyse_study
    from roughsense.cli._studies import builtin_study
    from roughsense.io.study import read_study
    from roughsense.model.registry import MODEL_FAMILIES, PLS

    study = read_study(builtin_study(0, jobs), require_ratings=True)
    definition = dataset.spectrum_for(study).feature_definition()
    features, _ = features_cache.cached_frame(features_cache.features_key(study, definition),
                                              lambda: dataset.study_features(study, n_jobs=jobs))
    times: dict[tuple[str, ...], list[float]] = {(PLS,): [], tuple(MODEL_FAMILIES): []}
    for repeat in range(repeats + 1):  # the first round is untimed (imports, worker start-up)
        for models in (times if repeat % 2 else reversed(list(times))):  # alternate which goes first
            started = time.perf_counter()
            analyse_study(study, features=features, n_jobs=jobs, seed=0, models=models)
            if repeat:
                times[models].append(time.perf_counter() - started)
    return times


def report_model_cost(cache: Path, repeats: int) -> None:
    times = model_cost(cache, max(repeats, 1))
    (pls, pls_runs), (every, every_runs) = times.items()
    base, both = statistics.median(pls_runs), statistics.median(every_runs)
    print(f"  warm analysis (features cached, controls included), median of {len(pls_runs)}, alternated:")
    print(f"    models={pls}: {base:6.1f} s  (runs: {', '.join(f'{t:.1f}' for t in pls_runs)})")
    print(f"    models={every}: {both:6.1f} s  (runs: {', '.join(f'{t:.1f}' for t in every_runs)})")
    print(f"    the new model adds {both - base:+.1f} s (x{both / base:.2f}); budget 10 s -> "
          f"{(both - base) / 10:.2f} of budget")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--warm-repeats", type=int, default=3)
    parser.add_argument("--cold-repeats", type=int, default=1, help="Empty-cache runs (the median is quoted).")
    parser.add_argument("--keep-cache", type=Path, default=None, help="Use (and keep) this cache folder.")
    parser.add_argument("--peer-src", type=Path, default=None,
                        help="Also run the cold study with these sources (another checkout's src/) as the peer.")
    parser.add_argument("--model-repeats", type=int, default=3,
                        help="Timed warm analyses per set of model families (0: skip that measurement).")
    parser.add_argument("--models-only", action="store_true",
                        help="Only measure what the new model family adds, in --keep-cache (default: roughsense's).")
    parser.add_argument("--cold-only", action="store_true",
                        help="Only the cold study, against every --cold-peer, alternated --cold-repeats rounds.")
    parser.add_argument("--cold-peer", type=Path, action="append", default=[],
                        help="Another checkout's src/ to run the cold study with (repeatable; with --cold-only).")
    args = parser.parse_args()
    if args.cold_only:
        print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
              f"load average {os.getloadavg()[0]:.1f} at start")
        report_cold_peers(args.cold_peer, max(args.cold_repeats, 1))
        print(f"  load average at the end: {os.getloadavg()[0]:.1f}")
        return
    if args.models_only:
        from roughsense._util.cache import cache_dir

        print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
              f"load average {os.getloadavg()[0]:.1f} at start")
        report_model_cost(args.keep_cache or cache_dir(), args.model_repeats)
        print(f"  load average at the end: {os.getloadavg()[0]:.1f}")
        return
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
        if args.model_repeats > 0:
            report_model_cost(cache, args.model_repeats)
        print(f"  load average at the end: {os.getloadavg()[0]:.1f}")
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    main()
