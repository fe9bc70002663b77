"""Benchmark the study's controls (issue 11): 199 specimen shufflings per model, LOO and nested LOSO.

Bar: the controls may add at most 30 s to a warm ``make study`` on 2 cores.
- Overhead: ``roughsense study --permutations 0`` against the default (199), each a fresh process on the
  warm cache of the built-in simulated study, interleaved round by round; the difference of the medians.
- Peer: a scikit-learn refit loop for the same shufflings -- one ``PLSRegression(A, scale=False)`` fit per
  training fold (every component count read from its rotations, which is cheaper than refitting per count),
  the same selection (argmin over 1..A; nested LOSO), timed on a few shufflings of the largest model
  (combined, p = 135) and compared per shuffling with the batched ``pls_cv_many`` path. It also checks
  that both give the same shuffled CV RMSE.

Run: .venv/bin/python benchmarks/bench_controls.py [--repeats 3] [--sklearn-permutations 2]
(ROUGHSENSE_CACHE_DIR selects the cache; the simulated study is built there on first use.)
"""
from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def run_study(out: Path, permutations: int) -> tuple[float, float]:
    """Wall time and CPU time (user + system) of one fresh ``roughsense study`` process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "roughsense.cli", "study", "--out", str(out), "--force",
                    "--permutations", str(permutations)], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def study_matrices():
    from roughsense._util import cache
    from roughsense._util.cache import cache_dir
    from roughsense.analysis import dataset
    from roughsense.analysis.magnitude_estimation import aggregate_ratings
    from roughsense.io.study import read_study

    root = next(p for p in sorted(cache_dir().glob("simulated-study-seed0-*")) if (p / "manifest.csv").is_file())
    study = read_study(root, require_ratings=True)
    definition = dataset.spectrum_for(study).feature_definition()
    features, _ = cache.cached_frame(cache.features_key(study, definition),
                                     lambda: dataset.study_features(study, n_jobs=2))
    perceived = aggregate_ratings(study.ratings, study.reference_specimen)
    for pad in study.pads:
        for condition in ("1N", "2N", "3N", "combined"):
            X, meta = dataset.condition_matrix(features, pad, condition)
            yield pad, condition, X, dataset.targets(meta, perceived), meta, perceived


def sklearn_cv(X, y, folds, A):
    """(n, A) out-of-fold predictions for 1..A components: one scikit-learn fit per training fold."""
    from sklearn.cross_decomposition import PLSRegression

    out = np.empty((len(y), A))
    for fold in np.unique(folds):
        test = folds == fold
        model = PLSRegression(n_components=A, scale=False).fit(X[~test], y[~test])
        xc = X[test] - model._x_mean
        for k in range(1, A + 1):
            out[test, k - 1] = xc @ model.x_rotations_[:, :k] @ model.y_loadings_[:, :k].T[:, 0] + model._y_mean[0]
    return out


def sklearn_permuted_rmse(X, y, specimens, cv, A):
    if cv == "loo":
        pred = sklearn_cv(X, y, np.arange(len(y)), A)
        return float(np.sqrt(((pred - y[:, None]) ** 2).mean(axis=0)).min())
    outer = sklearn_cv(X, y, specimens, A)
    nested = np.empty(len(y))
    for name in np.unique(specimens):
        held = specimens == name
        rest = specimens[~held]
        usable = min(A, len(rest) - int(np.unique(rest, return_counts=True)[1].max()) - 1, X.shape[1])
        inner = sklearn_cv(X[~held], y[~held], rest, usable)
        k = 1 + int(np.argmin(((inner - y[~held][:, None]) ** 2).sum(axis=0)))
        nested[held] = outer[held, k - 1]
    return float(np.sqrt(np.mean((nested - y) ** 2)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="fresh study runs per setting (median)")
    parser.add_argument("--sklearn-permutations", type=int, default=2)
    args = parser.parse_args()
    from roughsense import defaults
    from roughsense.analysis import controls
    from roughsense.analysis.family_fits import family_fit
    from roughsense.model.pls.family import permuted_cv_rmse

    print(f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f} at start")
    scratch = Path(tempfile.mkdtemp(prefix="roughsense-bench-controls-"))
    run_study(scratch / "warmup", 0)  # builds the cache on first use; not timed
    with_controls, without = [], []
    for _ in range(args.repeats):
        without.append(run_study(scratch / "off", 0))
        with_controls.append(run_study(scratch / "on", defaults.PERMUTATIONS))
    off, on = (statistics.median(w for w, _ in without), statistics.median(w for w, _ in with_controls))
    off_cpu, on_cpu = (statistics.median(c for _, c in without), statistics.median(c for _, c in with_controls))
    print(f"warm study, no controls:            {off:6.1f} s wall, {off_cpu:6.1f} s CPU (median of {args.repeats})")
    print(f"warm study, 199 shufflings x 16:    {on:6.1f} s wall, {on_cpu:6.1f} s CPU")
    print(f"overhead of the controls:           {on - off:6.1f} s wall, {on_cpu - off_cpu:6.1f} s CPU (bar: 30 s wall)")

    B = defaults.PERMUTATIONS
    per_model = {}
    for pad, condition, X, y, meta, perceived in study_matrices():
        specimens = meta["specimen"].astype(str).to_numpy()
        perms = controls.specimen_permutations(len(np.unique(specimens)), B, 0)
        for cv in ("loo", "loso"):
            fit = family_fit("pls", X, y, meta, perceived, pad, condition, cv, max_components=20)
            started = time.perf_counter()
            controls.control_row(fit, X, y, specimens, perms)
            per_model[(pad, condition, cv)] = time.perf_counter() - started
            if (pad, condition) == ("smooth", "combined"):
                Y = controls.permuted_targets(y, specimens, perms[: args.sklearn_permutations])
                A = int(fit.curve.size - 1)
                started = time.perf_counter()
                theirs = [sklearn_permuted_rmse(X, Y[:, b], specimens, cv, A) for b in range(Y.shape[1])]
                peer = (time.perf_counter() - started) / Y.shape[1]
                ours = permuted_cv_rmse(X, Y, specimens, cv, A)
                agree = np.max(np.abs(np.asarray(theirs) - ours))
                mine = per_model[(pad, condition, cv)] / B
                print(f"{pad} {condition} {cv.upper():4}: ours {1000 * mine:7.1f} ms/shuffling (batched, {B}), "
                      f"scikit-learn refits {1000 * peer:8.1f} ms/shuffling ({Y.shape[1]}): {peer / mine:6.0f}x; "
                      f"max |RMSE difference| {agree:.1e}")
    total = sum(per_model.values())
    print(f"controls of all 16 models in-process: {total:.1f} s "
          f"(LOO {sum(v for k, v in per_model.items() if k[2] == 'loo'):.1f} s, "
          f"LOSO {sum(v for k, v in per_model.items() if k[2] == 'loso'):.1f} s)")


if __name__ == "__main__":
    main()
