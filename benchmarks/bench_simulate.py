"""Benchmark the simulator: the contact solver against ContactMechanics, the per-image stages, and the full
default study (840 images, 1920 x 1080) with 1 and 2 workers: wall time and peak memory.

    .venv/bin/python benchmarks/bench_simulate.py [--repeats 15] [--full-repeats 1] [--skip-serial]
"""
from __future__ import annotations

import argparse
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


def bench_stages(repeats: int) -> None:
    import cv2

    from roughsense.sim.simulate import SimulationConfig, plan_trials, render, trial_line, _rng

    config = SimulationConfig(specimens=("R4.5", "C3"), repetitions=1)
    pads, specimens = config.validate()
    trials = [t for t in plan_trials(config, pads, specimens) if t.nominal_force_n == 2.0]
    print("per-image stages (median over trials and repeats):")
    for trial in trials:
        line_t = median_time(lambda: trial_line(trial), repeats)
        line, _ = trial_line(trial)
        rend = lambda: render(trial.camera, line, band_center_px=540.0, lighting=trial.exposure.lighting,
                              rng=_rng(0, 1), spots=trial.mount.spots)
        render_t = median_time(rend, repeats)
        frame = rend()
        enc = {level: median_time(lambda: cv2.imencode(".png", frame, [cv2.IMWRITE_PNG_COMPRESSION, level]), repeats)
               for level in (1, 3, 6)}
        size = len(cv2.imencode(".png", frame)[1])
        print(f"  {trial.image:34s} contact+line {line_t * 1e3:6.1f} ms  render {render_t * 1e3:6.1f} ms  "
              f"PNG level1 {enc[1] * 1e3:5.1f} ms (level3 {enc[3] / enc[1]:.1f}x, level6 {enc[6] / enc[1]:.1f}x), "
              f"{size / 1e6:.2f} MB")


def bench_full(jobs: int, repeats: int) -> tuple[float, float]:
    from roughsense.sim import SimulationConfig, simulate_study

    times = []
    for _ in range(repeats):
        out = Path(tempfile.mkdtemp(prefix="bench_sim_"))
        try:
            t0 = time.perf_counter()
            simulate_study(out / "study", SimulationConfig(), jobs=jobs)
            times.append(time.perf_counter() - t0)
        finally:
            shutil.rmtree(out, ignore_errors=True)
    return statistics.median(times), min(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--full-repeats", type=int, default=1)
    parser.add_argument("--skip-serial", action="store_true", help="skip the 1-worker full study")
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}, {__import__('os').cpu_count()} cores")
    bench_solver(args.repeats)
    bench_stages(args.repeats)
    print("full default study (2 pads x 14 specimens x 3 forces x 10 repetitions = 840 PNGs):")
    parallel, _ = bench_full(2, args.full_repeats)
    print(f"  jobs=2: {parallel:6.1f} s median of {args.full_repeats}")
    if not args.skip_serial:
        serial, _ = bench_full(1, args.full_repeats)
        print(f"  jobs=1: {serial:6.1f} s   speed-up with 2 workers {serial / parallel:.2f}x")
    parent = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"  peak RSS: parent {parent:.0f} MB, largest worker {child:.0f} MB, "
          f"parent + 2 workers <= {parent + 2 * child:.0f} MB")


if __name__ == "__main__":
    main()
