"""The sensor's scale and band on the twin: issue 34's goals, measured (figures in BENCHMARKS.md).

Seeds: the built-in study (seed 0) trains the models; "another session" is the twin at seed 41 (3 repetitions); the
calibration and band studies use seed 7. Every study is simulated into --work (kept, so a rerun reuses them).

1. calibrate: px/mm from 3 presses (2 N) of each 2-5 mm grating (the paper's 14), each pad, at 20, 34.9 and 60 px/mm;
   error against the camera's true scale (the twin's mounts also vary in magnification, 2.2 % SD per mount).
2. A wrong scale: another session's study.toml stating 34.9 x (1 +- 5 %, 1 +- 10 %) px/mm for images at 34.9, and
   images magnified x1.1 (true 38.39) under a stated 34.9: predict --study with the default model (peak law,
   combined) of each pad; rows flagged, the one line, the largest silent shift; fit's corrected nested-LOSO RMSE.
3. The band: gratings of 0.3, 0.5, 0.8 and 10 mm, both pads, 3 repetitions x 3 forces, predicted by each family
   alone (2 N model, bare images) and grouped (2 N and combined models, --study): share flagged, reasons.
4. False flags: each of the 14 gratings of another session, predicted grouped with the default model, and each
   built-in specimen held out (the family's nested held-out flag or the band test), share of presses flagged.

Run: .venv/bin/python benchmarks/bench_scale.py [--work /tmp/bench-scale]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

ROUGHSENSE = [sys.executable, "-m", "roughsense.cli"]
PADS = ("smooth", "fingerprint")


def run(*args, check: bool = True) -> subprocess.CompletedProcess:
    done = subprocess.run([*ROUGHSENSE, *map(str, args)], capture_output=True, text=True)
    if check and done.returncode != 0:
        raise SystemExit(f"roughsense {' '.join(map(str, args))} failed:\n{done.stderr}")
    return done


def simulate(out: Path, *, seed: int, px_per_mm: float = 34.9, stated_px_per_mm: float | None = None,
             specimens=None, repetitions: int = 3, forces=(1.0, 2.0, 3.0), steady: bool = False) -> Path:
    """A twin study at ``px_per_mm`` (its study.toml stating ``stated_px_per_mm`` if given), reused if present."""
    from roughsense.io.study_config import write_px_per_mm
    from roughsense.sim.config import SimulationConfig
    from roughsense.sim.simulate import simulate_study

    if (out / "manifest.csv").exists():
        return out
    config = SimulationConfig()
    stored = 0 if px_per_mm > 45 else config.camera.stored_height_px  # the band outgrows 320 rows at 60 px/mm
    changes = {"repetitions": repetitions, "forces_n": tuple(forces),
               "camera": replace(config.camera, px_per_mm=px_per_mm, stored_height_px=stored)}
    if specimens is not None:
        changes["specimens"] = tuple(specimens.split(","))
    if steady:  # no mount-to-mount magnification: the method's own error, apart from the bench's
        changes["bench"] = replace(config.bench, magnification_sd=0.0)
    simulate_study(out, replace(config, **changes), seed=seed, jobs=2, force=True)
    if stated_px_per_mm is not None:
        write_px_per_mm(out / "study.toml", stated_px_per_mm, note="bench_scale: stated, not measured", force=True)
    return out


def fit(study, pad: str, condition: str, out: Path, model: str = "peak-law") -> Path:
    if not out.exists():
        run("fit", "--study", study, "--pad", pad, "--condition", condition, "--model", model, "--out", out)
    return out


def predict(model: Path, *args) -> tuple[pd.DataFrame, str]:
    out = model.parent / f"pred-{os.getpid()}.csv"
    done = run("predict", model, *args, "--out", out, "--force")
    table = pd.read_csv(out, dtype={"outside": str}, keep_default_na=False)
    out.unlink()
    return table, done.stderr


def roughness(table: pd.DataFrame) -> np.ndarray:
    return table[[c for c in table.columns if c.startswith("roughness_rel_")][0]].to_numpy(float)


def calibrate_goal(work: Path) -> None:
    from roughsense.io.study import read_study
    from roughsense.sensor.period import calibrate_scale
    from roughsense.sensor.spectrum import SpatialSpectrum

    print("1. calibrate from 3 presses (2 N) of each grating, 2-5 mm; error against the true px/mm")
    for px, steady in ((20.0, False), (34.9, False), (60.0, False), (34.9, True)):
        study = read_study(simulate(work / f"cal-{px:g}{'-steady' if steady else ''}", seed=7, px_per_mm=px,
                                    forces=(2.0,), steady=steady))
        reader = SpatialSpectrum(roi=study.sensor.roi)
        rows = []
        for (pad, specimen), group in study.manifest.groupby(["pad", "specimen"]):
            period = float(study.specimens.set_index("specimen").loc[specimen, "wavelength_mm"])
            lines = [reader.line(study.root / image)[0] for image in group["image"]]
            m = calibrate_scale(lines, period,  # the CLI's default search: every resolvable scale
                                ridge_period_mm=study.pad_ridge_period_mm.get(pad))
            rows.append({"pad": pad, "specimen": specimen, "error": m.px_per_mm / px - 1, "n": m.n_measured})
        table = pd.DataFrame(rows)
        for pad, group in table.groupby("pad"):
            error = group["error"].abs()
            label = f"{px:5.1f} px/mm{' (no magnification jitter)' if steady else ''}, {pad:11s}"
            print(f"  {label}: within 0.5 % {np.mean(error <= 0.005):4.0%} of 14 gratings; "
                  f"|error| median {100 * error.median():.2f} %, max {100 * error.max():.2f} % "
                  f"({group.loc[error.idxmax(), 'specimen']}); presses read {group['n'].sum()} of {3 * len(group)}")


def scale_goal(work: Path, models: dict) -> None:
    print("\n2. a wrong scale: another session (seed 41), predict --study with the default model (peak law, combined)")
    right = simulate(work / "session41", seed=41)
    baseline = {}
    for pad in PADS:
        table, err = predict(models[pad, "combined"], "--study", right)
        baseline[pad] = roughness(table)
        said = next((line for line in err.splitlines() if "scale" in line and "read at" not in line), "")
        print(f"  right scale       {pad:11s}: flagged 'scale' {table['outside'].str.contains('scale: ').mean():4.0%}; "
              f"{said.removeprefix('roughsense: ')[:120]}")
    cases = [(f"study.toml x{1 + d:g}", simulate(work / f"session41-stated-{d:+g}", seed=41,
                                                stated_px_per_mm=34.9 * (1 + d))) for d in (-0.10, -0.05, 0.05, 0.10)]
    cases.append(("images x1.1", simulate(work / "session41-magnified", seed=41, px_per_mm=34.9 * 1.1,
                                          stated_px_per_mm=34.9)))
    for label, study in cases:
        for pad in PADS:
            table, err = predict(models[pad, "combined"], "--study", study)
            flagged = table["outside"].str.contains("scale: ")
            shift = np.abs(roughness(table) / baseline[pad] - 1)
            silent = shift[~flagged.to_numpy()]
            lines = [line for line in err.splitlines() if "warning: scale: measured" in line]
            print(f"  {label:17s} {pad:11s}: flagged 'scale' {flagged.mean():4.0%} of {len(table)}; one line: "
                  f"{len(lines) == 1}; shift median {100 * np.median(shift):.1f} %, largest silent "
                  f"{100 * silent.max() if silent.size else 0:.1f} %")
            if lines:
                print(f"      {lines[0].removeprefix('roughsense: warning: ')[:150]}")
    rmse = {}
    stated_right = simulate(work / "session41-magnified-stated", seed=41, px_per_mm=34.9 * 1.1)
    for label, study in (("right scale", right), ("images x1.1, corrected", cases[-1][1]),
                         ("images x1.1, stated right", stated_right)):
        out = fit(study, "fingerprint", "combined", work / f"fit-{label.split()[0]}-{len(label)}.json")
        training = json.loads(out.read_text())["training"]
        rmse[label] = training["unseen"]["rmse"]
        print(f"  fit fingerprint combined on {label}: nested-LOSO RMSE {rmse[label]:.3f}; {training['scale_check'][:90]}")
    print(f"  RMSE difference x1.1 corrected - right: {rmse['images x1.1, corrected'] - rmse['right scale']:+.3f}")


def band_goal(work: Path, models: dict) -> None:
    print("\n3. the band: gratings of 0.3, 0.5, 0.8 and 10 mm (seed 7), share of presses flagged")
    study = simulate(work / "band", seed=7, specimens="R3,rect:0.3,rect:0.5,rect:0.8,rect:10")
    manifest = pd.read_csv(study / "manifest.csv")
    outside = manifest[manifest["specimen"] != "R3"]
    for pad in PADS:
        for family in ("peak-law", "pls"):
            images = [study / p for p in outside[(outside["pad"] == pad) & (outside["nominal_force_n"] == 2.0)]["image"]]
            alone, _ = predict(models[pad, "2N", family], *images)
            grouped_2n, _ = predict(models[pad, "2N", family], "--study", study)
            grouped_c, _ = predict(models[pad, "combined", family], "--study", study)
            parts = [f"alone {alone['extrapolates'].mean():4.0%}"]
            for name, table in (("grouped 2N", grouped_2n), ("grouped combined", grouped_c)):
                mine = table[table["specimen"] != "R3"]
                parts.append(f"{name} {mine['extrapolates'].mean():4.0%}")
            named = alone["outside"].str.contains("than the sensor resolves").mean()
            print(f"  {pad:11s} {family:8s}: {', '.join(parts)}; band named (alone) {named:4.0%}")
            print(f"      e.g. {alone['outside'].iloc[0][:110]} | {grouped_c['outside'].iloc[-1][:110]}")


def false_flags_goal(work: Path, models: dict, builtin: Path) -> None:
    from roughsense.analysis import dataset
    from roughsense.io.study import read_study
    from roughsense.model.peak_law.cv import law_domain_flags
    from roughsense.sensor.band import band_reading, band_reason
    from roughsense.sensor.spectrum import SpatialSpectrum

    print("\n4. false flags: share of presses flagged per specimen (goal < 20 % each)")
    right = work / "session41"
    for pad in PADS:
        table, _ = predict(models[pad, "combined"], "--study", right)
        share = table.groupby("specimen")["extrapolates"].mean()
        print(f"  another session, {pad:11s}, grouped: worst {share.max():4.0%} ({share.idxmax()}); "
              f"specimens >= 20 %: {', '.join(share[share >= 0.2].index) or 'none'}")
    study = read_study(builtin)
    features = dataset.study_features(study)
    perceived = dataset.perceived_roughness(study)
    reader = SpatialSpectrum(roi=study.sensor.roi)
    for pad in PADS:
        X, meta = dataset.condition_matrix(features, pad, "2N")
        y = dataset.targets(meta, perceived)
        specimens = meta["specimen"].astype(str).to_numpy()
        freq = dataset.column_frequencies(dataset.frequency_columns(features))
        ridge = study.pad_ridge_period_mm.get(pad)
        law = law_domain_flags(X, y, specimens, freq_per_mm=freq, pad_ridge_period_mm=ridge, surfaces=specimens)
        band = np.array([bool(band_reason(band_reading(reader.line(study.root / image)[0], 34.9, 0.1, 1.0,
                                                       ridge_period_mm=ridge), 0.1, 1.0)) for image in meta["image"]])
        share = pd.Series(law | band).groupby(specimens).mean()
        print(f"  built-in held out, {pad:11s} 2N peak law: worst {share.max():4.0%} ({share.idxmax()}); band test alone "
              f"flags {band.mean():4.0%}; specimens >= 20 %: {', '.join(share[share >= 0.2].index) or 'none'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, default=Path("/tmp/bench-scale"))
    parser.add_argument("--goals", default="1234")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    from roughsense.cli._studies import builtin_study

    print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    builtin = builtin_study(0, 2)
    models = {}
    for pad in PADS:
        models[pad, "combined"] = fit("builtin", pad, "combined", args.work / f"{pad}-combined.json")
        for family in ("peak-law", "pls"):
            models[pad, "2N", family] = fit("builtin", pad, "2N", args.work / f"{pad}-2N-{family}.json", family)
            models[pad, "combined", family] = fit("builtin", pad, "combined",
                                                  args.work / f"{pad}-combined-{family}.json", family)
    goals = {"1": lambda: calibrate_goal(args.work), "2": lambda: scale_goal(args.work, models),
             "3": lambda: band_goal(args.work, models), "4": lambda: false_flags_goal(args.work, models, builtin)}
    for key in args.goals:
        goals[key]()
    print(f"\nload average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
