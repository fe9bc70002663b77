"""Benchmark the simulator: the contact solver against ContactMechanics, the per-image stages, and the full
default study (840 images) with 1 and 2 workers: wall time, size on disk and peak memory.

``--frames whole`` also runs the full study as it was written before issue 12 (whole 1920 x 1080 frames, OpenCV's
default PNG encoding) in the same run, as the peer of today's stored frames (a 320-row sensor window,
PNG with the "average" row filter and Huffman coding only).

    .venv/bin/python benchmarks/bench_simulate.py [--repeats 15] [--full-repeats 1] [--skip-serial] [--frames both]
"""
from __future__ import annotations

import argparse
import dataclasses
import resource
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench_solver(repeats: int) -> None:
    from ContactMechanics import PeriodicFFTElasticHalfSpace
    from ContactMechanics.Optimization import constrained_conjugate_gradients
    from SurfaceTopography import UniformLineScan

    from roughsense.sim import contact
    from roughsense.sim.pads import make_pad
    from roughsense.sim.specimens import PRESETS

    pad = make_pad("fingerprint")
    print("contact solve (one trial's periodic domain, 3 N):")
    for name in ("C3", "R4.5"):
        length, pad_period = contact.periodic_domain(PRESETS[name].period_mm, pad.period_mm)
        n = contact.grid_points(length)
        x = np.arange(n) * (length / n)
        h = PRESETS[name].height_mm(x) + pad.height_mm(x - 0.3, period_mm=pad_period)
        p = contact.nominal_pressure_pa(3.0)
        ours = median_time(lambda: contact.solve_periodic(h, length, p, pad.contact_modulus_pa), repeats)

        def theirs():
            sub = PeriodicFFTElasticHalfSpace((n,), pad.contact_modulus_pa, physical_sizes=(length,))
            constrained_conjugate_gradients(sub, UniformLineScan(h, length, periodic=True),
                                            external_force=p * length, pentol=1e-10)

        ref = median_time(theirs, repeats)
        print(f"  {name}+fingerprint n={n}: roughsense {ours * 1e3:7.1f} ms   ContactMechanics {ref * 1e3:7.1f} ms"
              f"   ratio {ref / ours:4.1f}x")
        # A trial's five pressure levels: solved together, against one after another with each level warm-started
        # from the previous one (what the simulator did before the batch), same tolerance as the simulator.
        levels = p * np.linspace(0.4, 1.6, 5)
        tol = 1e-5

        def chained():
            start = None
            for level in levels:
                start = contact.solve_periodic(h, length, level, pad.contact_modulus_pa, tol=tol,
                                               initial_pressure_pa=start).pressure_pa

        batch = median_time(lambda: contact.solve_periodic_many(h, length, levels, pad.contact_modulus_pa, tol=tol),
                            repeats)
        chain = median_time(chained, repeats)
        print(f"  {name}+fingerprint, 5 levels 0.4-1.6 x 3 N: batched {batch * 1e3:7.1f} ms   chained single solves "
              f"{chain * 1e3:7.1f} ms   ratio {chain / batch:4.1f}x")


def bench_stages(repeats: int) -> None:
    import cv2

    from roughsense.sim.config import SimulationConfig
    from roughsense.sim.frames import trial_line
    from roughsense.sim.optics import render
    from roughsense.sim.plan import plan_trials, rng
    from roughsense.sim.png import png_params

    config = SimulationConfig(specimens=("R4.5", "C3"), repetitions=1)
    pads, specimens = config.validate()
    trials = [t for t in plan_trials(config, pads, specimens) if t.nominal_force_n == 2.0]
    whole_camera = dataclasses.replace(config.camera, stored_height_px=0)
    print("per-image stages (median over trials and repeats); stored frame = 320-row window, whole = 1080 rows:")
    for trial in trials:
        line_t = median_time(lambda: trial_line(trial), repeats)
        line, _ = trial_line(trial)
        frames, render_t = {}, {}
        for what, camera in (("stored", trial.camera), ("whole", whole_camera)):
            rend = lambda: render(camera, line, band_center_px=540.0, lighting=trial.exposure.lighting,
                                  rng=rng(0, 1), spots=trial.mount.spots)
            render_t[what] = median_time(rend, repeats)
            frames[what] = rend()
        encode = {}
        for what, frame, params in (("whole, default PNG", frames["whole"], []),
                                    ("whole, ours", frames["whole"], list(png_params())),
                                    ("stored, ours", frames["stored"], list(png_params()))):
            t = median_time(lambda: cv2.imencode(".png", frame, params), repeats)
            encode[what] = (t, len(cv2.imencode(".png", frame, params)[1]))
        print(f"  {trial.image:34s} contact+line {line_t * 1e3:6.1f} ms  render stored {render_t['stored'] * 1e3:5.1f} ms"
              f" (whole {render_t['whole'] * 1e3:5.1f} ms)")
        for what, (t, size) in encode.items():
            print(f"      PNG {what:22s} {t * 1e3:6.1f} ms  {size / 1e6:5.2f} MB")


def bench_full(jobs: int, repeats: int, frames: str = "stored") -> tuple[float, float, int]:
    """Median and best wall time of the default study, and its images' size on disk (bytes)."""
    from roughsense.sim import png, simulate
    from roughsense.sim.config import SimulationConfig

    config = SimulationConfig()
    saved = png.png_params
    if frames == "whole":  # as before issue 12: whole frames, OpenCV's default PNG (workers fork and inherit this)
        config = dataclasses.replace(config, camera=dataclasses.replace(config.camera, stored_height_px=0))
        png.png_params = lambda: ()  # where the workers' write_mount looks it up
    times, size = [], 0
    try:
        for _ in range(repeats):
            out = Path(tempfile.mkdtemp(prefix="bench_sim_"))
            try:
                t0 = time.perf_counter()
                simulate.simulate_study(out / "study", config, jobs=jobs)
                times.append(time.perf_counter() - t0)
                size = sum(p.stat().st_size for p in (out / "study" / "images").iterdir())
            finally:
                shutil.rmtree(out, ignore_errors=True)
    finally:
        png.png_params = saved
    return statistics.median(times), min(times), size


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--full-repeats", type=int, default=1)
    parser.add_argument("--skip-serial", action="store_true", help="skip the 1-worker full study")
    parser.add_argument("--frames", choices=("stored", "both"), default="both",
                        help="both: also the pre-issue-12 whole frames with default PNG, as the peer")
    parser.add_argument("--skip-solver", action="store_true", help="skip the ContactMechanics comparison")
    parser.add_argument("--skip-stages", action="store_true")
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}, {__import__('os').cpu_count()} cores")
    print(f"load average at start {__import__('os').getloadavg()[0]:.1f}")
    if not args.skip_solver:
        bench_solver(args.repeats)
    if not args.skip_stages:
        bench_stages(args.repeats)
    print("full default study (2 pads x 14 specimens x 3 forces x 10 repetitions = 840 PNGs):")
    parallel, _, size = bench_full(2, args.full_repeats)
    print(f"  jobs=2, stored frames: {parallel:6.1f} s median of {args.full_repeats}, images {size / 1e6:6.0f} MB")
    if args.frames == "both":
        whole, _, whole_size = bench_full(2, args.full_repeats, frames="whole")
        print(f"  jobs=2, whole frames:  {whole:6.1f} s median of {args.full_repeats}, images {whole_size / 1e6:6.0f} MB"
              f"  -> stored/whole: time {parallel / whole:.2f}, size {size / whole_size:.2f}")
    if not args.skip_serial:
        serial, _, _ = bench_full(1, args.full_repeats)
        print(f"  jobs=1, stored frames: {serial:6.1f} s   speed-up with 2 workers {serial / parallel:.2f}x")
    print(f"load average at end {__import__('os').getloadavg()[0]:.1f}")
    parent = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"  peak RSS: parent {parent:.0f} MB, largest worker {child:.0f} MB, "
          f"parent + 2 workers <= {parent + 2 * child:.0f} MB")


if __name__ == "__main__":
    main()
