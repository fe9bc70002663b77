"""Benchmark the parallel plumbing on joblib against the hand-written pools it replaced, in the same run.

* Simulation: ``simulate_study`` of a small study (``--full``: the default 840 images) with 2 jobs through
  ``_util.workers.process_pool`` (loky's executor, forked workers) against loky's reusable executor (spawned
  workers), the former pool (``ProcessPoolExecutor`` with forked workers and the same die-with-parent initializer)
  and 1 job (not with ``--full``). The images must be the same bytes.
* Pool start: a pool of 2 from its making to two tasks done, each needing the modules of the report's figure
  drawing (imported in this process first, as ``roughsense study`` has them when it draws): loky against fork.
* Decoding: ``SpatialSpectrum(n_jobs=2).transform`` of the study's PNGs through ``_util.workers.thread_map``
  (joblib's threads) against the former bounded deque over a ``ThreadPoolExecutor``. The spectra must be equal.

* With ``--report STUDY``: the report of that study (analysed once, 19 shufflings) rendered with its figures drawn in
  2 loky workers, 2 spawned loky workers, 2 forked workers and in this process; the files must be the same bytes.

Medians over repeats, alternating the peers; the machine is shared, so only the ratios mean much.

Run: .venv/bin/python benchmarks/bench_workers.py [--repeats 3] [--decode-repeats 7] [--full] [--report STUDY]
"""
from __future__ import annotations

import argparse
import hashlib
import importlib
import multiprocessing
import os
import platform
import statistics
import tempfile
import time
from collections import deque
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

import numpy as np

import roughsense.sensor.spectrum as spectrum_module
import roughsense.sim.simulate as simulate_module
from roughsense._util.workers import die_with_parent
from roughsense.sensor.spectrum import SpatialSpectrum
from roughsense.sim import SimulationConfig


def fork_pool(max_workers: int) -> ProcessPoolExecutor:
    """The pool before joblib: forked workers, tied to this process by the same initializer."""
    return ProcessPoolExecutor(max_workers=max_workers, mp_context=multiprocessing.get_context("fork"),
                               initializer=die_with_parent, initargs=(os.getpid(),))


def spawned_pool(max_workers: int):
    """loky's reusable executor, its workers spawned (loky refuses fork there): the pool issue 38 first tried."""
    from joblib.externals.loky import get_reusable_executor

    return get_reusable_executor(max_workers=max_workers, initializer=die_with_parent, initargs=(os.getpid(),))


def deque_map(fn, items, n_jobs: int):
    """The decoding map before joblib: a bounded deque of futures over a thread pool."""
    if n_jobs == 1:
        yield from map(fn, items)
        return
    pool = ThreadPoolExecutor(max_workers=n_jobs)
    pending: deque = deque()
    try:
        for item in items:
            pending.append(pool.submit(fn, item))
            if len(pending) >= 2 * n_jobs:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def images_digest(folder: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted((folder / "images").glob("*.png")):
        digest.update(path.name.encode() + path.read_bytes())
    return digest.hexdigest()


def simulate_once(out: Path, config: SimulationConfig, jobs: int, pool) -> tuple[float, str]:
    simulate_module.process_pool = pool
    start = time.perf_counter()
    simulate_module.simulate_study(out, config, jobs=jobs, force=True)
    return time.perf_counter() - start, images_digest(out)


def bench_simulation(root: Path, repeats: int, full: bool) -> Path:
    config = SimulationConfig(seed=3) if full else SimulationConfig(
        pads=("smooth", "fingerprint"), specimens=("R2", "R3", "C3", "C4"), forces_n=(1.0, 2.0, 3.0), repetitions=2,
        seed=3)
    loky_pool = simulate_module.process_pool
    peers = {"loky (2 jobs)": (2, loky_pool), "loky spawned": (2, spawned_pool), "fork (2 jobs)": (2, fork_pool)}
    if not full:
        peers["serial (1 job)"] = (1, loky_pool)
    times: dict[str, list[float]] = {name: [] for name in peers}
    digests: dict[str, set[str]] = {name: set() for name in peers}
    for _ in range(repeats):
        for name, (jobs, pool) in peers.items():
            seconds, digest = simulate_once(root / "sim", config, jobs, pool)
            times[name].append(seconds)
            digests[name].add(digest)
    simulate_module.process_pool = loky_pool
    print(f"simulation: {len(list((root / 'sim' / 'images').glob('*.png')))} images, median of {repeats}")
    base = statistics.median(times["fork (2 jobs)"])
    for name, values in times.items():
        print(f"  {name:16s} {statistics.median(values):7.2f} s   {statistics.median(values) / base:5.2f}x fork")
    same = len(set().union(*digests.values())) == 1
    print(f"  images identical across pools and repeats: {same}")
    return root / "sim"


def imported(name: str) -> int:
    importlib.import_module(name)
    return os.getpid()


def bench_pool_start(repeats: int) -> None:
    importlib.import_module("roughsense.report.html")
    peers = {"loky": simulate_module.process_pool, "loky spawned": spawned_pool, "fork": fork_pool}
    times: dict[str, list[float]] = {name: [] for name in peers}
    for _ in range(repeats):
        for name, pool_of in peers.items():
            start = time.perf_counter()
            with pool_of(2) as pool:
                list(pool.map(imported, ["roughsense.report.html"] * 2))
            times[name].append(time.perf_counter() - start)
    print(f"pool start (2 workers, the report's modules), median of {repeats}")
    for name, values in times.items():
        print(f"  {name:16s} {statistics.median(values):7.2f} s")


def bench_decoding(study: Path, repeats: int) -> None:
    paths = [str(p) for p in sorted((study / "images").glob("*.png"))]
    spectrum = SpatialSpectrum(n_jobs=2).fit()
    joblib_map = spectrum_module.thread_map
    peers = {"joblib threads": joblib_map, "deque + pool": deque_map}
    times: dict[str, list[float]] = {name: [] for name in peers}
    results = {}
    for _ in range(repeats):
        for name, mapper in peers.items():
            spectrum_module.thread_map = mapper
            start = time.perf_counter()
            results[name] = spectrum.transform(paths)
            times[name].append(time.perf_counter() - start)
    spectrum_module.thread_map = joblib_map
    base = statistics.median(times["deque + pool"])
    print(f"decoding: {len(paths)} PNGs, 2 threads, median of {repeats}")
    for name, values in times.items():
        rate = len(paths) / statistics.median(values)
        print(f"  {name:16s} {rate:7.1f} images/s   {statistics.median(values) / base:5.2f}x the former pool's time")
    print(f"  spectra equal: {np.array_equal(results['joblib threads'], results['deque + pool'])}")


def bench_report(study_path: str, repeats: int) -> None:
    import roughsense.report.html as html
    from roughsense.analysis.study_analysis import analyse_study
    from roughsense.io.study import read_study

    analysis = analyse_study(read_study(study_path, require_ratings=True), n_permutations=19, n_jobs=2)
    peers = {"loky (2 jobs)": (2, html.process_pool), "loky spawned": (2, spawned_pool),
             "fork (2 jobs)": (2, fork_pool), "serial (1 job)": (1, html.process_pool)}
    loky_pool = html.process_pool
    times: dict[str, list[float]] = {name: [] for name in peers}
    files = set()
    for _ in range(repeats):
        for name, (jobs, pool) in peers.items():
            html.process_pool = pool
            start = time.perf_counter()
            report = html.render_report(analysis, n_jobs=jobs, meta={"generated": "fixed"})  # no clock in the page
            times[name].append(time.perf_counter() - start)
            files.add(tuple(sorted((k, hashlib.sha256(v).hexdigest()) for k, v in report.items())))
    html.process_pool = loky_pool
    base = statistics.median(times["fork (2 jobs)"])
    print(f"report of {study_path}, median of {repeats}")
    for name, values in times.items():
        print(f"  {name:16s} {statistics.median(values):7.2f} s   {statistics.median(values) / base:5.2f}x fork")
    renders = [dict(f) for f in files]
    differing = sorted(k for k in renders[0] if len({r.get(k) for r in renders}) > 1)
    print(f"  report files identical across pools and repeats: {len(files) == 1}; differing: {differing}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--decode-repeats", type=int, default=7)
    parser.add_argument("--full", action="store_true", help="simulate the default 840-image study (no serial peer)")
    parser.add_argument("--report", metavar="STUDY", help="also time drawing this study's report's figures")
    args = parser.parse_args()
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory() as folder:
        study = bench_simulation(Path(folder), args.repeats, args.full)
        bench_decoding(study, args.decode_repeats)
    bench_pool_start(args.repeats)
    if args.report:
        bench_report(args.report, args.repeats)
    print(f"load at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
