"""Benchmark the sensor front end against plain decoding of the same files, in the same run.

Writes N synthetic 1920 x 1080 RGB contact frames as PNG into a temporary folder (noisy, so they
decode like camera frames, not like flat test patterns), then reports medians over repeats of:

* plain decoding, ``cv2.imread`` of every file, on 1 thread and on a pool of 2 threads;
* ``SpatialSpectrum(n_jobs=1)`` and ``(n_jobs=2)`` over the same paths (decode + crop + spectrum);
* the work after decoding alone (crop, gray, line, DFT, normalise) on frames already in memory;
* peak traced memory of the streaming transform for N/4 and N images (it should not grow);
* the band test and the scale check predict runs on each image's line, against features' cost per image;
* predict with and without the contact-image gate and the orientation (issue 43: at most +10 % per image), on these
  frames and on 1920 x 320 gray crops of them (the twin's frame).

The machine is shared, so besides wall-clock rates it prints CPU seconds per image (all threads) and
the rate that CPU cost allows when every core is free (cores / CPU per image): a projection, labelled so.

Run: .venv/bin/python benchmarks/bench_sensor.py [--images 60] [--repeats 9]
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time
import tracemalloc
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from roughsense.sensor.band import band_reading
from roughsense.sensor.line import _Plan
from roughsense.sensor.period import check_scale
from roughsense.sensor.spectrum import SpatialSpectrum

PX_PER_MM = 34.9


def contact_frame(rng: np.random.Generator, wavelength_mm: float) -> np.ndarray:
    """A 1080 x 1920 BGR uint8 frame: vignetted background, a bright grating band, sensor noise."""
    height, width = 1080, 1920
    x_mm = np.arange(width) / PX_PER_MM
    lands = 0.5 + 0.5 * np.tanh(3 * np.sin(2 * np.pi * x_mm / wavelength_mm))
    profile = 0.75 * lands + 0.25 * lands * (0.5 + 0.5 * np.cos(2 * np.pi * x_mm))
    rows = np.arange(height) - height / 2
    band = np.clip((100 - np.abs(rows)) / 15, 0, 1)
    yy, xx = np.mgrid[0:height, 0:width]
    vignette = 1 - 0.35 * (((xx - width / 2) / width) ** 2 + ((yy - height / 2) / height) ** 2)
    gray = 40 + 170 * band[:, None] * profile[None, :]
    gray = gray * vignette + rng.normal(0, 2.0, size=(height, width))
    tint = np.array([0.85, 0.95, 1.0])  # BGR
    return np.clip(np.round(gray[:, :, None] * tint), 0, 255).astype(np.uint8)


def timed(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def thread_timed(fn) -> float:
    """CPU seconds of this thread: the cost of single-threaded work, unaffected by other processes."""
    start = time.thread_time()
    fn()
    return time.thread_time() - start


def decode_all(paths, jobs: int) -> None:
    if jobs == 1:
        for p in paths:
            cv2.imread(str(p), cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH)
        return
    with ThreadPoolExecutor(jobs) as pool:
        list(pool.map(lambda p: cv2.imread(str(p), cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH), paths))


def peak_traced_mb(paths, jobs: int) -> float:
    estimator = SpatialSpectrum(n_jobs=jobs)
    tracemalloc.start()
    for _ in estimator.iter_transform(paths):
        pass
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2**20


def checks_against_features(frames, paths) -> None:
    """What predict adds per image on the line it already has: the band test (the line's strongest period) and the
    scale check on a pad's 1 mm ridges, against ``features``' own cost per image (a file read, decoded as far as
    the line, and its spectrum: thread CPU of SpatialSpectrum's per-image work)."""
    plan = _Plan.build(PX_PER_MM, "center", 1, 0.1, 1.0, 45, "hann")
    features_s = statistics.median(thread_timed(lambda p=p: plan.spectrum(p)) for p in paths for _ in range(3))
    lines = [plan.spectrum_and_line(f)[1] for f in frames]

    def checks(line) -> None:
        band_reading(line, PX_PER_MM, 0.1, 1.0, ridge_period_mm=1.0)
        check_scale([line], 1.0, PX_PER_MM)

    checks(lines[0])  # imports
    check_s = statistics.median(thread_timed(lambda line=line: checks(line)) for line in lines for _ in range(3))
    print(f"  band test + scale check on the line: {check_s * 1e3:7.3f} ms/image = {100 * check_s / features_s:5.2f} % "
          f"of features ({features_s * 1e3:.2f} ms/image: read, decode to the line, spectrum)")


def gate_against_predict(frames, folder: Path, repeats: int) -> None:
    """What the contact-image gate and the orientation add to ``predict`` per image (issue 43's goal: at most 10 %):
    one peak-law model file saved twice, with and without its gate, predicting the same files, interleaved; and, in
    thread CPU, the per-image reading with the descriptors against the reading without them."""
    import warnings

    import roughsense as rs
    from roughsense.model.contact_gate import fit_gate
    from roughsense.model.gate_file import KEY, gate_section
    from roughsense.model.modelfile import save_model
    from roughsense.sensor.descriptors import descriptor_names

    for label, crop in (("1920x1080 RGB", lambda f: f), ("1920x320 gray (the twin's)", lambda f: f[380:700, :, 1])):
        paths = []
        for i, frame in enumerate(frames):
            paths.append(folder / f"gate_{i:03d}_{crop(frames[0]).ndim}.png")
            cv2.imwrite(str(paths[-1]), crop(frame))
        spectrum = SpatialSpectrum().fit()
        readings = list(spectrum.iter_readings(paths))
        X = np.vstack([r[0] for r in readings])
        periods = 1.0 + np.arange(len(paths)) % 5
        law = rs.PeakPowerLaw(freq_per_mm=spectrum.freq_per_mm_).fit(X, periods / 3)
        names = descriptor_names(False)
        values = np.array([[r[2][n] for n in names] for r in readings])
        gate = fit_gate(values, names, np.arange(len(paths)) % 5, seed=0)
        features = {"spectrum": spectrum.feature_definition(), "conditions": ["2N"]}
        models = {}
        for gated in (False, True):
            training = {"reference_specimen": "R3", **({KEY: gate_section(gate)} if gated else {})}
            models[gated] = save_model(folder / f"law_{gated}_{label[:4]}.json", law, feature_definition=features,
                                       training=training, force=True)
        batch = paths * 3  # per-image work, not the run's fixed cost, decides the ratio
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rs.predict(models[True], paths[:2])
            cpu_without, cpu_with = [], []
            for _ in range(repeats):  # CPU of all this process's threads: robust to other processes' load
                cpu0 = time.process_time()
                rs.predict(models[False], batch)
                cpu1 = time.process_time()
                rs.predict(models[True], batch)
                cpu_without.append((cpu1 - cpu0) / len(batch))
                cpu_with.append((time.process_time() - cpu1) / len(batch))
        plan = _Plan.build(PX_PER_MM, "center", 1, 0.1, 1.0, 45, "hann")
        old = statistics.median(thread_timed(lambda p=p: plan.spectrum_and_line(p)) for p in paths for _ in range(3))
        new = statistics.median(thread_timed(lambda p=p: plan.reading(p)) for p in paths for _ in range(3))
        # predict always reads the descriptors (the orientation is written with or without a gate): issue 43's cost
        # is the descriptors' reading plus the gate's scoring, against predict as it was (without both)
        gate_s = statistics.median(w - o for w, o in zip(cpu_with, cpu_without))
        before = statistics.median(cpu_without) - (new - old)
        added = (new - old) + gate_s
        print(f"  {label}: predict {before * 1e3:.2f} ms CPU/image before; descriptors and orientation "
              f"+{(new - old) * 1e3:.3f} ms (reading {old * 1e3:.2f} -> {new * 1e3:.2f}), the gate's scoring "
              f"+{gate_s * 1e3:.3f} ms: +{100 * added / before:.1f} % per image ({len(batch)} images, medians of "
              f"{repeats})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=9)
    args = parser.parse_args()
    rng = np.random.default_rng(2025)

    with tempfile.TemporaryDirectory(prefix="bench_sensor_") as tmp:
        paths = []
        for i in range(args.images):
            path = Path(tmp) / f"frame_{i:04d}.png"
            cv2.imwrite(str(path), contact_frame(rng, rng.uniform(2.0, 5.0)))
            paths.append(path)
        size_mb = sum(p.stat().st_size for p in paths) / len(paths) / 2**20
        print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, "
              f"load average {os.getloadavg()[0]:.1f} at start, Python {platform.python_version()}, "
              f"OpenCV {cv2.__version__}, NumPy {np.__version__}")
        print(f"{len(paths)} PNG frames 1920x1080 RGB, {size_mb:.2f} MiB each; medians of {args.repeats} repeats\n")

        decode_all(paths[:10], 1)  # warm caches and imports
        SpatialSpectrum().transform(paths[:10])
        runs = {
            "decode only, 1 thread (cv2.imread)": lambda: decode_all(paths, 1),
            "SpatialSpectrum n_jobs=1": lambda: SpatialSpectrum(n_jobs=1).transform(paths),
            "decode only, 2 threads": lambda: decode_all(paths, 2),
            "SpatialSpectrum n_jobs=2": lambda: SpatialSpectrum(n_jobs=2).transform(paths),
        }
        times: dict[str, list[float]] = {name: [] for name in runs}
        cpu: dict[str, list[float]] = {name: [] for name in runs}
        for _ in range(args.repeats):  # interleaved, so drift on a shared machine hits every peer alike
            for name, fn in runs.items():
                start_cpu = time.process_time()
                times[name].append(timed(fn))
                cpu[name].append(time.process_time() - start_cpu)
        rate = {name: len(paths) / statistics.median(t) for name, t in times.items()}
        cores = os.cpu_count() or 1
        print(f"  {'':40s} {'wall':>13s}   {'CPU/image':>9s}   {'all cores free':>14s}")
        for name in runs:
            cpu_per_image = statistics.median(cpu[name]) / len(paths)
            print(f"  {name:40s} {rate[name]:7.1f} img/s   {cpu_per_image * 1e3:6.1f} ms   {cores / cpu_per_image:7.1f} img/s")
        # Ratios per repeat (each pair ran back to back), then the median: robust to load drifting between repeats.
        for jobs, decode_name in ((1, "decode only, 1 thread (cv2.imread)"), (2, "decode only, 2 threads")):
            ratios = [d / t for d, t in zip(times[decode_name], times[f"SpatialSpectrum n_jobs={jobs}"])]
            print(f"  SpatialSpectrum / decode throughput, {jobs} thread(s): median {statistics.median(ratios):.3f} "
                  f"(per repeat {min(ratios):.2f}-{max(ratios):.2f})")
        # Work after decoding, per image, on frames already decoded (RGB views as the reader returns them);
        # thread CPU time for both, so the ratio does not depend on what else the machine is doing.
        frames = [cv2.imread(str(p))[:, :, ::-1] for p in paths[:20]]
        decode_s = statistics.median(thread_timed(lambda p=p: cv2.imread(str(p))) for p in paths[:20] for _ in range(3))
        for roi in ("center", "auto"):
            plan = _Plan.build(PX_PER_MM, roi, 1, 0.1, 1.0, 45, "hann")  # what transform runs per image
            work_s = statistics.median(thread_timed(lambda f=f: plan.spectrum(f)) for f in frames for _ in range(3))
            print(f"  work after decoding, roi={roi:6s}: {work_s * 1e3:7.3f} ms/image = {100 * work_s / decode_s:5.1f} % "
                  f"of decoding ({decode_s * 1e3:.2f} ms/image)")
        checks_against_features(frames, paths[:20])
        gate_against_predict([f[:, :, ::-1] for f in frames], Path(tmp), args.repeats)
        del frames

        quarter = paths[: len(paths) // 4]
        small, large = peak_traced_mb(quarter, 2), peak_traced_mb(paths, 2)
        print(f"\n  peak traced memory, n_jobs=2: {small:.1f} MiB for {len(quarter)} images, "
              f"{large:.1f} MiB for {len(paths)} images "
              f"(one decoded frame is {1920 * 1080 * 3 / 2**20:.1f} MiB)")
        print(f"  load average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
