"""Which new readings of the contact image could tell a rectangular from a circular grating of one period, and does
any of them earn a term in the law (issue 35, item 2)? Figures in BENCHMARKS.md.

Three parts, each on the built-in study (paper's ratings), per seed, pad and condition:

1. ``terms``: candidate shape features added to the law's current terms (log f, and the harmonic ratio where
   every surface shows it), each fitted by the law's Huber IRLS with features held to each fold's training range
   (bench_shape_terms.clipped_cv), scored by LOSO: mean per-specimen RMSE, Spearman rho (13 rated), mean log bias
   per shape. Candidates, read on each surface's mean spectrum:
   ``logA``: the fundamental's log height (normalised spectrum); ``f0/ridge``: the fundamental's log height less the
   fingerprint ridges' (the ridges as a carrier whose strength follows the contact's length); ``logA 3N-1N`` and
   ``harmonic 3N-1N``: how the fundamental and the second harmonic change from 1 N to 3 N (combined rows; a
   semi-cylinder's contact widens with force, a land's does not); ``harmonic, where readable``: on the fingerprint
   pad the harmonic ratio of every surface whose 2 f0 lies off the ridges and off their first sideband 1 - f0
   (2 and 3 mm unread, set to the mean of the read ones).
2. ``line``: the share of the image line brighter than half its range after removing its illumination (a moving
   median over ~10 mm): the contact fraction as the line shows it, beside the twin's true contact fraction
   (simulated manifests only), per pad, force and shape (4 repetitions).
3. ``rows``: the spectrum read on the mean of the 31 central rows instead of one (SpatialSpectrum(rows=31), a
   documented deviation from the paper's one line), the current law: LOSO RMSE, rho, and a held-out surface read
   from 1 and 3 presses (analysis/presses.py). Re-reads every image of the study (about a minute per seed).

Choose on seeds 0-2 (``--seeds 0 1 2``), check on 3-5, which redraw the twin's noise on the same 14 surfaces.

Run: .venv/bin/python benchmarks/bench_shape_features.py [--seeds 0 1 2] [--parts terms line rows] [--csv prefix]
"""
from __future__ import annotations

import argparse
import os
import platform

import numpy as np
import pandas as pd
from scipy.stats import spearmanr

from bench_peak_law import CONDITIONS, condition_cells, law_settings, study_of
from bench_shape_terms import clipped_cv, scores, term_features

#: Rows averaged in part 3 (~0.9 mm across a 10 mm specimen's band; the centre crop is 150 rows).
ROWS = 31


def _rho(prediction, y, specimens) -> float:
    means = pd.Series(prediction).groupby(specimens).mean()
    target = pd.Series(y).groupby(specimens).first()
    rated = [name for name in means.index if name != "R3"]
    return float(spearmanr(means[rated], target[rated])[0])


def candidates(X, settings: dict, specimens) -> dict[str, np.ndarray]:
    """Each candidate's value per row (read on its surface's mean spectrum); see the module docstring."""
    from roughsense.model.peak_law.folds import specimen_codes
    from roughsense.model.peak_search import peak_features
    from roughsense.sensor.shape import harmonic_ratio, lobe_height

    freq, n_blocks, ridge = settings["freq_per_mm"], settings["n_blocks"], settings["pad_ridge_period_mm"]
    codes, names = specimen_codes(specimens)
    features = peak_features(X, **settings)
    f0 = np.exp(features[np.unique(codes, return_index=True)[1], 0])
    blocks = X.reshape(len(X), n_blocks, freq.size)

    def surface(spectra):
        return np.log(np.maximum(np.stack([spectra[codes == c].mean(axis=0) for c in range(names.size)]), 1e-300))

    mean = surface(blocks.mean(axis=1))
    found = {"logA": lobe_height(mean, freq, f0)}
    if ridge:
        found["f0/ridge"] = found["logA"] - lobe_height(mean, freq, np.full(names.size, 1 / ridge))
        ratio = harmonic_ratio(mean, freq, f0, ridge)
        ratio[np.abs(3 * f0 - 1 / ridge) <= 0.1] = np.nan  # 2 f0 on the ridges' first sideband 1/ridge - f0
        found["harmonic, where readable"] = np.where(np.isfinite(ratio), ratio, np.nanmean(ratio))
    if n_blocks == 3:
        low, high = surface(blocks[:, 0]), surface(blocks[:, -1])
        found["logA 3N-1N"] = lobe_height(high, freq, f0) - lobe_height(low, freq, f0)
        change = harmonic_ratio(high, freq, f0, ridge) - harmonic_ratio(low, freq, f0, ridge)
        if np.all(np.isfinite(change)):
            found["harmonic 3N-1N"] = change
    return {name: value[codes] for name, value in found.items()}


def terms_part(seeds) -> pd.DataFrame:
    rows = []
    for cell in condition_cells(seeds):
        X, y, specimens = cell["X"], cell["y"], cell["specimens"]
        settings = law_settings(cell["study"], cell["features"], cell["pad"], cell["condition"], specimens)
        terms = term_features(X, settings, specimens)
        current = terms["period+harmonic"] if terms["period+harmonic"] is not None else terms["period"]
        designs = {"current": current, **{f"+ {name}": np.column_stack([current, value]) for name, value
                                          in candidates(X, settings, specimens).items()}}
        for name, design in designs.items():
            prediction = clipped_cv(design, np.log(y), specimens)
            rows.append({"seed": cell["seed"], "pad": cell["pad"], "condition": cell["condition"], "terms": name,
                         **scores(prediction, y, specimens, cell["shapes"]), "rho": _rho(prediction, y, specimens)})
    return pd.DataFrame(rows)


def line_part(seeds, repetitions: int = 4) -> pd.DataFrame:
    from scipy.ndimage import median_filter

    from roughsense.sensor.spectrum import SpatialSpectrum

    rows = []
    for seed in seeds:
        study, _, _ = study_of(seed)
        manifest = study.manifest.merge(study.specimens[["specimen", "shape", "wavelength_mm"]], on="specimen")
        manifest = manifest[manifest["repetition"] <= repetitions]
        reader = SpatialSpectrum(px_per_mm=study.sensor.px_per_mm, roi=study.sensor.roi)
        window_px = int(round(10 * study.sensor.px_per_mm)) | 1
        for row in manifest.itertuples():
            line = np.asarray(reader.line(study.root / row.image)[0], dtype=np.float64)
            relief = line - median_filter(line, size=window_px, mode="nearest")
            low, high = np.percentile(relief, [5, 95])
            rows.append({"seed": seed, "pad": row.pad, "force_n": row.nominal_force_n, "shape": row.shape,
                         "wavelength_mm": row.wavelength_mm, "line_fraction": float(np.mean(relief > (low + high) / 2)),
                         "true_fraction": row.contact_fraction})
    return pd.DataFrame(rows)


def rows_part(seeds) -> pd.DataFrame:
    from roughsense.analysis import dataset
    from roughsense.analysis.presses import presses_curve
    from roughsense.model.peak_law.cv import peak_law_cv
    from roughsense.sensor.spectrum import SpatialSpectrum

    out = []
    for seed in seeds:
        study, features, perceived = study_of(seed)
        shapes = dict(zip(study.specimens["specimen"], study.specimens["shape"]))
        spectrum = SpatialSpectrum(px_per_mm=study.sensor.px_per_mm, roi=study.sensor.roi, rows=ROWS, n_jobs=2).fit()
        wide = dataset.study_features(study, n_jobs=2, spectrum=spectrum)
        for reading, table in (("1 row", features), (f"{ROWS} rows", wide)):
            for pad in study.pads:
                for condition in CONDITIONS:
                    X, meta = dataset.condition_matrix(table, pad, condition)
                    y = dataset.targets(meta, perceived)
                    specimens = meta["specimen"].astype(str).to_numpy()
                    settings = law_settings(study, table, pad, condition, specimens)
                    prediction = peak_law_cv(X, y, groups=specimens, **settings)[0]
                    curve = presses_curve(X, y, specimens, settings, seed).set_index("n_presses")["rmse"]
                    out.append({"seed": seed, "pad": pad, "condition": condition, "reading": reading,
                                "rmse": scores(prediction, y, specimens, shapes)["rmse"],
                                "rho": _rho(prediction, y, specimens), "press_1": curve.get(1),
                                "press_3": curve.get(3)})
    return pd.DataFrame(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--parts", nargs="+", default=["terms", "line", "rows"], choices=["terms", "line", "rows"])
    parser.add_argument("--csv", help="write each part's table to PREFIX-PART.csv too")
    args = parser.parse_args()
    print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    pd.set_option("display.width", 200)
    for part in args.parts:
        frame = {"terms": terms_part, "line": line_part, "rows": rows_part}[part](args.seeds)
        if part == "terms":
            print("\nLOSO, mean over seeds and conditions: RMSE, rho, mean log bias per shape")
            print(frame.groupby(["pad", "terms"])[["rmse", "rho", "bias_rect", "bias_circ"]].mean().round(3)
                  .to_string())
            print(frame.pivot_table(index=["pad", "condition"], columns="terms", values="rmse").round(3).to_string())
        elif part == "line":
            print("\nShare of the line brighter than half its range, and the twin's true contact fraction")
            print(frame.pivot_table(index=["pad", "force_n"], columns="shape", values=["line_fraction",
                                    "true_fraction"], aggfunc=["mean", "std"]).round(3).to_string())
        else:
            print(f"\nOne row against {ROWS}: LOSO RMSE, rho, a surface from 1 and 3 presses (mean over conditions)")
            print(frame.groupby(["pad", "reading"])[["rmse", "rho", "press_1", "press_3"]].mean().round(3)
                  .to_string())
            print(frame.pivot_table(index=["pad", "seed"], columns="reading", values=["rmse", "press_1"])
                  .round(3).to_string())
        if args.csv:
            frame.to_csv(f"{args.csv}-{part}.csv", index=False)
    print(f"load at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
