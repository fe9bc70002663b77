"""Benchmark: leave-one-out PLS1 over 1..20 components on the paper's combined-force problem (n=140, p=135).

Peers, measured in the same run and interleaved round by round (the machine is shared and noisy):
- scikit-learn: ``cross_val_predict(PLSRegression(k, scale=False), cv=LeaveOneOut())`` for k = 1..20;
- ikpls: ``ikpls.fast_cross_validation.numpy.PLS(...).cross_validate`` (Improved Kernel PLS #1 and #2,
  centred, not scaled, 20 components, n_jobs=1), which returns every component count in one pass;
- a plain loop refitting roughsense.SIMPLS on each fold (what pls_cv replaces);
- roughsense.pls_cv(X, y, 20, cv="loo").
Each peer runs with the BLAS at its default threads and again limited to one thread; a peer's time is the
faster of the two (so ratios against it are conservative). Prints medians and ratios, and checks that
every peer's predictions agree with pls_cv's.

    .venv/bin/python benchmarks/bench_pls.py [--repeats 7] [--sklearn-repeats 2]
"""
from __future__ import annotations

import argparse
import contextlib
import io
import platform
import time

import numpy as np
from threadpoolctl import threadpool_limits


def combined_spectra(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """14 specimens x 10 repetitions; each row is three 45-bin spectra (1, 2, 3 N) side by side."""
    rng = np.random.default_rng(seed)
    freq = np.linspace(0.1, 1.0, 45)
    X, y = [], []
    for _ in range(14):
        f0 = 0.15 + 0.8 * rng.random()
        for _ in range(10):
            blocks = []
            for force in (1.0, 2.0, 3.0):
                peak = (0.5 + 0.2 * force) * np.exp(-(((freq - f0) / 0.04) ** 2))
                ridge = 0.5 * np.exp(-(((freq - 1.0) / 0.05) ** 2))
                blocks.append(peak * (1 + 0.05 * rng.standard_normal()) + ridge + 0.02 * rng.standard_normal(45))
            X.append(np.concatenate(blocks))
            y.append(f0**-0.8)
    return np.array(X), np.array(y)


def run_sklearn(X, y, A):
    from sklearn.cross_decomposition import PLSRegression
    from sklearn.model_selection import LeaveOneOut, cross_val_predict

    out = np.empty((len(y), A))
    for k in range(1, A + 1):
        out[:, k - 1] = cross_val_predict(PLSRegression(n_components=k, scale=False), X, y, cv=LeaveOneOut()).ravel()
    return out


def run_ikpls(X, y, A, algorithm):
    from ikpls.fast_cross_validation.numpy import PLS

    pls = PLS(algorithm=algorithm, center_X=True, center_Y=True, scale_X=False, scale_Y=False)
    with contextlib.redirect_stdout(io.StringIO()):  # it prints a banner
        by_fold = pls.cross_validate(X, y, A, np.arange(len(y)), lambda y_val, y_pred: y_pred, n_jobs=1, verbose=0)
    return np.vstack([np.asarray(by_fold[i])[:, 0, 0] for i in range(len(y))])


def run_refit(X, y, A):
    from roughsense import SIMPLS

    out = np.empty((len(y), A))
    for i in range(len(y)):
        train = np.arange(len(y)) != i
        model = SIMPLS(A).fit(X[train], y[train])
        for k in range(1, A + 1):
            out[i, k - 1] = model.predict(X[i : i + 1], n_components=k)[0]
    return out


def run_ours(X, y, A):
    from roughsense import pls_cv

    return pls_cv(X, y, max_components=A, cv="loo").predictions[:, 1:]


def timed(fn, threads):
    context = threadpool_limits(1, user_api="blas") if threads == 1 else contextlib.nullcontext()
    with context:
        start = time.perf_counter()
        result = fn()
        return time.perf_counter() - start, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--sklearn-repeats", type=int, default=2)
    args = parser.parse_args()
    X, y = combined_spectra()
    A = 20
    peers = {
        "roughsense.pls_cv": lambda: run_ours(X, y, A),
        "ikpls fast CV #1": lambda: run_ikpls(X, y, A, 1),
        "ikpls fast CV #2": lambda: run_ikpls(X, y, A, 2),
        "refit loop (SIMPLS)": lambda: run_refit(X, y, A),
        "sklearn cross_val_predict x20": lambda: run_sklearn(X, y, A),
    }
    times = {(name, threads): [] for name in peers for threads in ("default", 1)}
    results = {}
    for round_ in range(args.repeats):
        for name, fn in peers.items():
            if name.startswith("sklearn") and round_ >= args.sklearn_repeats:
                continue
            for threads in ("default", 1):
                seconds, results[name] = timed(fn, threads)
                times[(name, threads)].append(seconds)
    print(f"LOO over 1..{A} components, n={X.shape[0]}, p={X.shape[1]}; Python {platform.python_version()}, "
          f"{platform.system()}; {args.repeats} rounds ({args.sklearn_repeats} for scikit-learn)")
    ours = results["roughsense.pls_cv"]
    best = {}
    print(f"{'peer':32s} {'default thr (ms)':>17s} {'1 thread (ms)':>14s} {'max rel diff':>13s}")
    for name in peers:
        medians = {t: float(np.median(times[(name, t)])) for t in ("default", 1)}
        best[name] = min(medians.values())
        diff = float(np.max(np.abs(results[name] - ours) / np.abs(ours)))
        print(f"{name:32s} {medians['default'] * 1e3:17.2f} {medians[1] * 1e3:14.2f} {diff:13.1e}")
    print()
    for name in peers:
        if name != "roughsense.pls_cv":
            print(f"pls_cv is {best[name] / best['roughsense.pls_cv']:8.1f}x faster than {name} (best setting of each)")


if __name__ == "__main__":
    main()
