"""Benchmark the simulated finger (sim/finger.py): one specimen's percept from scratch (skin contact at four
ridge phases, SA1 readout), against a peer in the same run: the simulator's own contact line for one image of the
same specimen (sim.simulate.trial_line, the smooth pad at 2 N on a quiet bench).

    .venv/bin/python benchmarks/bench_finger.py [--repeats 9]
"""
from __future__ import annotations

import argparse
import statistics

from bench_simulate import median_time  # benchmarks/ is on the path when run as a script


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9)
    args = parser.parse_args()

    from roughsense.sim import finger as finger_model
    from roughsense.sim.bench import BenchNoise
    from roughsense.sim.config import SimulationConfig
    from roughsense.sim.frames import trial_line
    from roughsense.sim.plan import plan_trials
    from roughsense.sim.specimens import parse_specimen

    quiet = SimulationConfig(pads=("smooth",), forces_n=(2.0,), repetitions=1, bench=BenchNoise().scaled(0.0))
    print(f"{'specimen':16s} {'finger (ms)':>12s} {'image line (ms)':>16s} {'ratio':>7s}")
    ratios = []
    for name in ("R2", "R4.5", "C3", "rect:1.7:1:0.6", "sin:3:0.3", "rand:1.5:0.2"):
        specimen = parse_specimen(name)

        def finger():
            finger_model.spatial_variation.cache_clear()
            finger_model.spatial_variation(specimen)

        config = quiet.__class__(**{**quiet.__dict__, "specimens": (name,)})
        pads, specimens = config.validate()
        trial = plan_trials(config, pads, specimens)[0]
        ours = median_time(finger, args.repeats)
        peer = median_time(lambda: trial_line(trial), args.repeats)
        ratios.append(ours / peer)
        print(f"{name:16s} {ours * 1e3:12.1f} {peer * 1e3:16.1f} {ours / peer:7.2f}")
    print(f"median ratio finger / image line: {statistics.median(ratios):.2f}")


if __name__ == "__main__":
    main()
