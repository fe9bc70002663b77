"""True vs apparent contact on a quiet bench: does the rendered line show the contact the solver found?

For each specimen and force, one trial on a bench without variation (no tilt, warp, shift or light changes) and
without the fingerprint ridges' own image: the true contact fraction is the solver's (``render_trial``'s ground
truth); the apparent one is the fraction of pixel columns whose brightness, after the lens blur, is above half-way
between "nothing touches" and "full contact" -- what one would read off the band. docs/simulator.md, Optics.

    .venv/bin/python scripts/contact_agreement.py [--pads smooth] [--specimens C2,...] [--forces-n 1,2,3]
        [--camera key=value ...]
"""
from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from roughsense.sim.bench import BenchNoise
from roughsense.sim.config import SimulationConfig
from roughsense.sim.frames import trial_line
from roughsense.sim.optics import Camera, apparent_contact_fraction
from roughsense.sim.plan import plan_trials

SPECIMENS = ("C2", "C3", "C4", "C5", "R2", "R3", "R4", "R5")


def agreement(pads=("smooth",), specimens=SPECIMENS, forces_n=(1.0, 2.0, 3.0), camera=None) -> list[dict]:
    quiet = dataclasses.replace(BenchNoise().scaled(0.0), ridge_visibility=0.0, spots_per_mount=0.0)
    config = SimulationConfig(pads=tuple(pads), specimens=tuple(specimens), forces_n=tuple(forces_n),
                              repetitions=1, bench=quiet)
    if camera is not None:
        config = dataclasses.replace(config, camera=camera)
    pads_, specimens_ = config.validate()
    rows = []
    for trial in plan_trials(config, pads_, specimens_):
        line, true = trial_line(trial)
        seen = apparent_contact_fraction(line, trial.camera)
        rows.append({"pad": trial.pad.name, "specimen": trial.specimen.name, "force_n": trial.nominal_force_n,
                     "true": true, "apparent": seen, "relative_error": seen / true - 1.0 if true > 0 else np.nan})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pads", default="smooth")
    parser.add_argument("--specimens", default=",".join(SPECIMENS))
    parser.add_argument("--forces-n", default="1,2,3")
    parser.add_argument("--camera", nargs="*", default=[], help="camera overrides, e.g. micro_roughness_mm=0.0005")
    args = parser.parse_args()
    camera = Camera(**{k: float(v) for k, v in (item.split("=") for item in args.camera)})
    rows = agreement(pads=args.pads.split(","), specimens=args.specimens.split(","),
                     forces_n=tuple(float(f) for f in args.forces_n.split(",")), camera=camera)
    print("| pad | specimen | force (N) | true | apparent | apparent / true - 1 |")
    print("|---|---|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['pad']} | {r['specimen']} | {r['force_n']:g} | {r['true']:.3f} | {r['apparent']:.3f} "
              f"| {100 * r['relative_error']:+.1f} % |")
    worst = max(abs(r["relative_error"]) for r in rows)
    print(f"largest |apparent / true - 1|: {100 * worst:.1f} %")


if __name__ == "__main__":
    main()
