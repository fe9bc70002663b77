"""Benchmark the controls and the report of ``roughsense study`` (issue 37), each a fresh process.

- Ratio: the warm built-in study with 199 shufflings against the same study with ``--permutations 0``, alternated
  round by round (goal <= 1.3x); the peak RSS of each process (goal <= 400 MB); the report stage as a share of the
  ``--permutations 0`` study (goal <= 25 %). ``--peer-src OLD/src`` runs the same pair with another checkout's
  sources in the same rounds (before/after in one run).
- Growth (``--growth``): a smooth-pad study of the 14 gratings at 10 and 20 repetitions (simulated once into a
  scratch folder, features cached by an untimed first run); the controls stage's time and the peak RSS with 199
  shufflings (goals: time at 20 <= 2.2x time at 10; RSS at 20 <= 500 MB).

- Kinds (``--kinds``): the CPU of the built-in study's 32 control jobs on one thread, summed per kind (PLS and the
  peak law, each LOO and nested LOSO; 8 models each), this checkout and ``--peer-src`` alternated in fresh processes.

- Chunks (``--chunks``): the controls alone (``run_controls``, 2 threads, the built-in study's 32 jobs) in fresh
  processes for chunk sizes of the law's shufflings (``peak_law_family.LAW_CHUNK_CELLS``) and of PLS's targets
  (``pls_cv._BATCH_BYTES``): CPU and peak RSS above the process's own before the controls.

Stage times are the CLI's own stage lines (``roughsense: controls, ... done in 12.3 s``; a stage under 2 s prints
none). Peak RSS is ``wait4``'s of the study process.

Run: .venv/bin/python benchmarks/bench_issue37.py [--repeats 3] [--peer-src OLD/src [--peer-cache DIR]]
     [--growth | --chunks | --kinds | --report-only]
(ROUGHSENSE_CACHE_DIR selects the cache; the built-in study is simulated there on first use. The peer keeps its
own, ``--peer-cache``: a simulator that differs keys the built-in study differently.)
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


def study(out: Path, permutations: int, *, src: Path | None = None, data: Path | None = None,
          cache: Path | None = None) -> dict:
    """One fresh ``roughsense study``: wall time, peak RSS (MiB) and its stage times; ``cache``: its own cache folder
    (a peer whose simulator differs keys the built-in study differently, and a cache keeps one version of it)."""
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = str(src.resolve())
    if cache is not None:
        env["ROUGHSENSE_CACHE_DIR"] = str(cache)
    command = [sys.executable, "-m", "roughsense.cli", "study", "--out", str(out), "--force",
               "--permutations", str(permutations)] + ([] if data is None else ["--study", str(data)])
    started = time.perf_counter()
    process = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - started
    err = process.stderr.read()
    process.returncode = os.waitstatus_to_exitcode(status)
    if process.returncode:
        raise SystemExit(f"study failed ({process.returncode}): {err}")
    return {"wall": wall, "rss": usage.ru_maxrss / 1024, "cpu": usage.ru_utime + usage.ru_stime,
            **{name: float(s) for name, s in STAGE.findall(err)}}


def median(runs: list[dict], key: str) -> float:
    values = [run.get(key, float("nan")) for run in runs]
    return statistics.median(values)


def ratio(args, scratch: Path) -> None:
    peers = {"this": None} | ({"peer": args.peer_src} if args.peer_src else {})
    caches = {"this": None, "peer": args.peer_cache or scratch / "peer-cache"}
    for name, src in peers.items():  # untimed: the features cache, the first imports
        study(scratch / "warm", 0, src=src, cache=caches[name])
    shufflings = (0,) if args.report_only else (0, 199)
    runs = {(name, b): [] for name in peers for b in shufflings}
    for _ in range(args.repeats):
        for name, src in peers.items():
            for b in shufflings:
                runs[(name, b)].append(study(scratch / f"{name}-{b}", b, src=src, cache=caches[name]))
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
              f"(runs 0: {walls(off)}; 199: {walls(on)}); CPU 0: {median(off, 'cpu'):.1f} s, 199: "
              f"{median(on, 'cpu'):.1f} s -> {median(on, 'cpu') / median(off, 'cpu'):.2f}")


def growth(args, scratch: Path) -> None:
    specimens = "R2,R2.5,R3,R3.5,R4,R4.5,R5,C2,C2.5,C3,C3.5,C4,C4.5,C5"
    results, extra_cpu = {}, {}
    for repetitions in (10, 20):
        folder = scratch / f"smooth-{repetitions}"
        if not (folder / "ratings.csv").is_file():  # a --scratch of an earlier run keeps its simulated studies
            subprocess.run([sys.executable, "-m", "roughsense.cli", "simulate", "--out", str(folder), "--seed", "0",
                            "--pads", "smooth", "--specimens", specimens, "--repetitions", str(repetitions)],
                           check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        study(scratch / "warm", 0, data=folder)  # features into the cache
        results[repetitions] = [study(scratch / f"g{repetitions}", 199, data=folder) for _ in range(args.repeats)]
        off = study(scratch / f"g{repetitions}-0", 0, data=folder)
        on = results[repetitions]
        print(f"{repetitions} repetitions ({14 * 3 * repetitions} images): 199 shufflings {median(on, 'wall'):5.1f} s, "
              f"controls {median(on, 'controls'):5.1f} s, peak {median(on, 'rss'):4.0f} MiB, CPU {median(on, 'cpu'):.1f} s; "
              f"--permutations 0 {off['wall']:5.1f} s, {off['rss']:4.0f} MiB, CPU {off['cpu']:.1f} s")
        extra_cpu[repetitions] = median(on, "cpu") - off["cpu"]
    print(f"controls at 20 / at 10 = {median(results[20], 'controls') / median(results[10], 'controls'):.2f}; "
          f"CPU the shufflings add, at 20 / at 10 = {extra_cpu[20] / extra_cpu[10]:.2f}")


def control_jobs(path: Path) -> None:
    """The built-in study's 32 control jobs, as analyse_study hands them to run_controls, pickled (bench scratch)."""
    import pickle

    from roughsense._util import cache
    from roughsense._util.cache import cache_dir
    from roughsense.analysis import controls, dataset, study_analysis
    from roughsense.io.study import read_study

    root = next(p for p in sorted(cache_dir().glob("simulated-study-seed0-*")) if (p / "manifest.csv").is_file())
    study = read_study(root, require_ratings=True)
    definition = dataset.spectrum_for(study).feature_definition()
    features, _ = cache.cached_frame(cache.features_key(study, definition),
                                     lambda: dataset.study_features(study, n_jobs=2))
    captured = []
    study_analysis._controls.run_controls = lambda jobs, **_: captured.extend(jobs) or controls.controls_table([])
    study_analysis.analyse_study(study, features=features, stricter=False)
    path.write_bytes(pickle.dumps(captured))


def chunk_run(path: Path, law_cells: int, pls_bytes: int) -> None:
    """One fresh process: run_controls (2 threads) on the pickled jobs with these chunk sizes; CPU and peak RSS."""
    import pickle
    import resource

    from roughsense.analysis import controls
    from roughsense.model.peak_law import family as peak_law_family
    from roughsense.model.pls import cv as pls_cv

    jobs = pickle.loads(path.read_bytes())
    peak_law_family.LAW_CHUNK_CELLS, pls_cv._BATCH_BYTES = law_cells, pls_bytes
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    started = time.process_time()
    controls.run_controls(jobs, n_jobs=2)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{time.process_time() - started:.2f} {peak - before:.0f}")


def chunks(args, scratch: Path) -> None:
    """CPU and the controls' own peak RSS (above the jobs' process) for chunk sizes of both families, alternated."""
    jobs = scratch / "jobs.pickle"
    control_jobs(jobs)
    settings = [(1 << 21, 8 << 20), (1 << 19, 8 << 20), (1 << 17, 8 << 20), (1 << 19, 64 << 20), (1 << 19, 2 << 20)]
    runs = {setting: [] for setting in settings}
    for _ in range(args.repeats):
        for law_cells, pls_bytes in settings:
            out = subprocess.run([sys.executable, __file__, "--chunk-run", str(jobs), str(law_cells), str(pls_bytes)],
                                 check=True, capture_output=True, text=True).stdout.split()
            runs[(law_cells, pls_bytes)].append((float(out[0]), float(out[1])))
    for (law_cells, pls_bytes), some in runs.items():
        print(f"law chunk 2^{law_cells.bit_length() - 1} cells, PLS chunk {pls_bytes >> 20} MiB: CPU "
              f"{statistics.median(c for c, _ in some):5.1f} s, controls' peak +{statistics.median(m for _, m in some):4.0f} "
              f"MiB (runs: {', '.join(f'{c:.1f} s' for c, _ in some)})")


KINDS = ("pls loo", "pls loso", "peak-law loo", "peak-law loso")


def kind_run(path: Path) -> None:
    """One fresh process: CPU of control_row on the pickled jobs, one thread, single-threaded BLAS, summed per kind
    (family x CV scheme, 8 models each); after one untimed job (imports, first calls)."""
    import pickle

    from roughsense.analysis import controls
    from roughsense.model.pls.simpls import single_threaded_blas

    jobs = pickle.loads(path.read_bytes())
    cpu = dict.fromkeys(KINDS, 0.0)
    with single_threaded_blas():
        controls.control_row(*jobs[0])
        for job in jobs:
            started = time.process_time()
            controls.control_row(*job)
            cpu[f"{getattr(job[0], 'model', 'pls')} {job[0].cv}"] += time.process_time() - started
    print(" ".join(f"{cpu[kind]:.3f}" for kind in KINDS))


def kinds(args, scratch: Path) -> None:
    """CPU per kind of control job (one thread), this checkout and ``--peer-src`` alternated, each run a fresh process."""
    jobs = scratch / "jobs.pickle"
    control_jobs(jobs)
    peers = {"this": None} | ({"peer": args.peer_src} if args.peer_src else {})
    runs = {name: [] for name in peers}
    for _ in range(args.repeats):
        for name, src in peers.items():
            env = dict(os.environ) | ({} if src is None else {"PYTHONPATH": str(src.resolve())})
            out = subprocess.run([sys.executable, __file__, "--kind-run", str(jobs)], env=env, check=True,
                                 capture_output=True, text=True).stdout.split()
            runs[name].append([float(value) for value in out])
    for name, some in runs.items():
        medians = [statistics.median(run[i] for run in some) for i in range(len(KINDS))]
        print(f"{name}: " + ", ".join(f"{kind} {m:.2f} s" for kind, m in zip(KINDS, medians))
              + f"; all {sum(medians):.2f} s (runs: {', '.join(f'{sum(run):.1f}' for run in some)})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--peer-src", type=Path, default=None)
    parser.add_argument("--peer-cache", type=Path, default=None,
                        help="The peer's own cache folder (default: one in the scratch folder, built on first use).")
    parser.add_argument("--growth", action="store_true", help="Only the growth at 10 and 20 repetitions.")
    parser.add_argument("--chunks", action="store_true", help="Only the controls' chunk sizes (CPU, peak RSS).")
    parser.add_argument("--chunk-run", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("--kinds", action="store_true",
                        help="Only the controls' CPU per kind of job, one thread (this and --peer-src alternated).")
    parser.add_argument("--kind-run", help=argparse.SUPPRESS)
    parser.add_argument("--scratch", type=Path, default=None, help="Reuse this folder (e.g. its simulated studies).")
    parser.add_argument("--report-only", action="store_true",
                        help="Only the --permutations 0 study: the report stage's share (and the study's CPU).")
    args = parser.parse_args()
    if args.chunk_run:
        chunk_run(Path(args.chunk_run[0]), int(args.chunk_run[1]), int(args.chunk_run[2]))
        return
    if args.kind_run:
        kind_run(Path(args.kind_run))
        return
    print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f} at start")
    scratch = args.scratch or Path(tempfile.mkdtemp(prefix="roughsense-bench-issue37-"))
    (growth if args.growth else chunks if args.chunks else kinds if args.kinds else ratio)(args, scratch)
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
