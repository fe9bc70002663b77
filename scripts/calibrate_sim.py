"""Calibrate the simulator's trial-to-trial noise against the paper's regime (not a test; see docs/simulator.md).

Renders the paper's study in memory (no PNG files), extracts the paper's features with roughsense.sensor
(1900 x 150 centre crop, gray, middle row, |FFT| at 45 frequencies 0.1-1.0 mm^-1, area-normalised), runs LOO PLS
with roughsense.pls_cv (components 1..20, the minimum-RMSE count) against the paper's perceived roughness, and
prints the mean per-specimen RMSE per pad and condition. The paper: fingerprint single-force ~0.2-0.3,
smooth lower, combined lower still.

    .venv/bin/python scripts/calibrate_sim.py [--scale 1.0] [--seed 0] [--repetitions 10] [--jobs 2]
        [--pads smooth,fingerprint] [--camera key=value ...] [--bench key=value ...] [--save features.npz]
"""
from __future__ import annotations

import argparse
import dataclasses
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pandas as pd

from roughsense.model.pls.cv import pls_cv
from roughsense.sensor.line import spatial_spectrum
from roughsense.sim.config import SimulationConfig
from roughsense.sim.frames import render_trial
from roughsense.sim.panel import paper_perceived
from roughsense.sim.plan import plan_trials


def _features(trial):
    frame, _ = render_trial(trial)
    return spatial_spectrum(frame)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=float, default=1.0, help="multiply every bench spread by this")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repetitions", type=int, default=10)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--camera", nargs="*", default=[], help="camera overrides, e.g. read_noise_dn=4")
    parser.add_argument("--bench", nargs="*", default=[], help="bench overrides, e.g. ridge_visibility_sd=0.2")
    parser.add_argument("--pads", default="smooth,fingerprint", help="comma-separated pads to calibrate")
    parser.add_argument("--save", default=None, help="write the features and trial table to this .npz")
    args = parser.parse_args()

    config = SimulationConfig(seed=args.seed, repetitions=args.repetitions,
                              pads=tuple(p.strip() for p in args.pads.split(",") if p.strip()))
    config = dataclasses.replace(config, bench=config.bench.scaled(args.scale))
    if args.camera:
        overrides = {k: float(v) for k, v in (item.split("=") for item in args.camera)}
        config = dataclasses.replace(config, camera=dataclasses.replace(config.camera, **overrides))
    if args.bench:
        overrides = {k: float(v) for k, v in (item.split("=") for item in args.bench)}
        config = dataclasses.replace(config, bench=dataclasses.replace(config.bench, **overrides))
    pads, specimens = config.validate()
    trials = plan_trials(config, pads, specimens)
    with ProcessPoolExecutor(args.jobs) as pool:
        X_all = np.array(list(pool.map(_features, trials, chunksize=8)))
    meta = pd.DataFrame({"pad": [t.pad.name for t in trials], "specimen": [t.specimen.name for t in trials],
                         "force": [t.nominal_force_n for t in trials], "rep": [t.repetition for t in trials]})
    if args.save:
        np.savez(args.save, X=X_all, pad=meta["pad"].to_numpy(str), specimen=meta["specimen"].to_numpy(str),
                 force=meta["force"].to_numpy(float), rep=meta["rep"].to_numpy(int))
    target = paper_perceived()["perceived_gmean"]
    rows = []
    per_specimen, pred_means = {}, {}
    for pad in config.pads:
        blocks = {}
        for force in config.forces_n:
            sel = (meta["pad"] == pad) & (meta["force"] == force)
            blocks[f"{force:g}N"] = (X_all[sel.to_numpy()], meta[sel].reset_index(drop=True))
        first_meta = next(iter(blocks.values()))[1]
        blocks["combined"] = (np.hstack([b[0] for b in blocks.values()]), first_meta)
        for condition, (X, m) in blocks.items():
            y = target.loc[m["specimen"]].to_numpy(float)
            result = pls_cv(X, y, max_components=20)
            a = int(np.argmin(result.rmse[1:]) + 1)
            pred = result.predictions[:, a]
            err = pd.Series((pred - y) ** 2).groupby(m["specimen"].to_numpy()).mean() ** 0.5
            per_specimen[(pad, condition)] = err
            pred_means[(pad, condition)] = pd.Series(pred).groupby(m["specimen"].to_numpy()).mean()
            rows.append({"pad": pad, "condition": condition, "components": a,
                         "overall_rmse": float(result.rmse[a]), "mean_specimen_rmse": float(err.mean())})
    table = pd.DataFrame(rows)
    print(f"bench scale {args.scale:g}, seed {args.seed}, camera overrides {args.camera or 'none'}")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print("per-specimen RMSE:")
    print(pd.DataFrame(per_specimen).T.to_string(float_format=lambda v: f"{v:.2f}"))
    print("per-specimen mean prediction (target: the paper's perceived roughness):")
    means = pd.DataFrame(pred_means).T
    means.loc[("target", ""), :] = target.loc[means.columns].to_numpy(float)
    print(means.to_string(float_format=lambda v: f"{v:.2f}"))


if __name__ == "__main__":
    main()
