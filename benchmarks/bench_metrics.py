"""Benchmark the paper's metrics against their obvious peers, in one run, medians over repeats.

- OVL: roughsense.analysis.metrics.overlap (closed form, vectorised) vs scipy.integrate.quad of min(f1, f2) per pair.
- Signed-rank: roughsense.analysis.metrics.signed_rank (exact, n = 14, like MATLAB) vs scipy.stats.wilcoxon(method="exact").
- Ratings: aggregate_ratings on the paper's design (10 participants x 3 sessions x 13 specimens) vs a bare
  pandas groupby (median, then geometric mean) that does no validation and no gap check.

Usage: .venv/bin/python benchmarks/bench_metrics.py [--repeats 7]
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import pandas as pd
from scipy import integrate, stats

from roughsense.analysis.magnitude_estimation import aggregate_ratings, make_schedule
from roughsense.analysis.metrics import overlap, signed_rank
from roughsense.paper import PAPER_SPECIMENS


def median_seconds(fn, repeats: int, number: int = 1) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - start) / number)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    rng = np.random.default_rng(0)

    # --- OVL: 104 pairs, the size of Tables 2 + 5
    n_pairs = 104
    m1, m2 = rng.uniform(0.3, 1.8, n_pairs), rng.uniform(0.3, 1.8, n_pairs)
    s1, s2 = rng.uniform(0.1, 0.6, n_pairs), rng.uniform(0.08, 0.3, n_pairs)

    def by_quad():
        out = []
        for a, b, c, d in zip(m1, s1, m2, s2):
            f = lambda x: min(stats.norm.pdf(x, a, b), stats.norm.pdf(x, c, d))
            out.append(integrate.quad(f, -5, 7, points=[a, c], limit=200)[0])
        return np.array(out)

    closed = overlap(m1, s1, m2, s2)
    numeric = by_quad()
    t_closed = median_seconds(lambda: overlap(m1, s1, m2, s2), args.repeats, number=50)
    t_quad = median_seconds(by_quad, max(3, args.repeats // 2))
    print(f"OVL, {n_pairs} pairs: closed form {t_closed * 1e3:.3f} ms, quad {t_quad * 1e3:.1f} ms, "
          f"ratio quad/closed {t_quad / t_closed:.0f}x, max |diff| {np.max(np.abs(closed - numeric)):.1e}")

    # --- signed-rank, n = 14 (one per specimen), no ties so scipy's exact path applies
    x = rng.permutation(np.arange(1, 15)) * rng.choice([-1, 1], 14)
    ours = signed_rank(x)
    theirs = stats.wilcoxon(x, method="exact")
    t_ours = median_seconds(lambda: signed_rank(x), args.repeats, number=200)
    t_scipy = median_seconds(lambda: stats.wilcoxon(x, method="exact"), args.repeats, number=200)
    print(f"signed-rank exact, n=14: roughsense {t_ours * 1e6:.0f} us, scipy {t_scipy * 1e6:.0f} us, "
          f"ratio scipy/roughsense {t_scipy / t_ours:.2f}, p {ours.p:.6g} vs {theirs.pvalue:.6g}")

    # --- ratings aggregation on the paper's design
    schedule = make_schedule(PAPER_SPECIMENS, 10, 3, rng=rng)
    ratings = schedule.assign(rating=rng.lognormal(0, 0.3, len(schedule)), session=schedule.session.astype(str))

    def bare():
        med = ratings.groupby(["specimen", "participant"])["rating"].median()
        return np.exp(np.log(med).groupby(level=0).mean())

    t_agg = median_seconds(lambda: aggregate_ratings(ratings), args.repeats, number=5)
    t_bare = median_seconds(bare, args.repeats, number=5)
    same = np.allclose(aggregate_ratings(ratings).set_index("specimen")["gmean"].drop("R3").sort_index(),
                       bare().sort_index())
    print(f"aggregate 390 ratings: aggregate_ratings {t_agg * 1e3:.2f} ms, bare groupby {t_bare * 1e3:.2f} ms, "
          f"ratio {t_agg / t_bare:.1f}x (validation + gap check), same gmean: {same}")


if __name__ == "__main__":
    pd.set_option("display.width", 120)
    main()
