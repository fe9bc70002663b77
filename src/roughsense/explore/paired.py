"""How a sweep words a comparison: paired intervals over seeds, a stated margin, and what the seeds could detect.

Two designs run with the same seed share their simulated panel, mounts and noise, so a comparison is the mean of the
per-seed differences with its t-based 95 % interval. Its verdict is *better*/*worse* when the interval excludes 0,
*equivalent within ±m* when it lies inside the margin m (chosen before the rerun, see MARGINS), otherwise
*undetermined within ±x* (x: the interval's farthest end) -- never "as good as" on absence of evidence. Fewer than
MIN_SEEDS seeds give no interval at all. Levels of bounded quantities keep their interval inside the range.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import optimize, stats

from ..analysis.controls import training_mean_predictions
from ..analysis.metrics import ALPHA, mean_interval

MIN_SEEDS = 3  # two seeds leave one degree of freedom: t = 12.7, an interval wider than any effect asked about
POWER = 0.8
#: Equivalence margins, fixed before the rerun of data/examples/paper_questions.toml. RMSE (perceived units, the
#: reference R3 = 1): 0.05, 5 % of the reference's roughness and a quarter of the paper's best LOO error (~0.2), a
#: change no user of the sensor would notice. OVL (overlap of two distributions, 0-1): 0.05, five points of overlap.
MARGINS = {"rmse": 0.05, "ovl": 0.05}
#: The range of each quantity: a displayed interval is clipped to it (and says so).
RANGES = {"rmse": (0.0, math.inf), "ovl": (0.0, 1.0), "ovl_predictive": (0.0, 1.0), "null_rmse": (0.0, math.inf)}
#: For which quantities a larger value is better.
HIGHER_IS_BETTER = {"rmse": False, "ovl": True, "ovl_predictive": True, "null_rmse": False}


def too_few(n: int) -> str:
    """The one line that replaces an interval when the seeds cannot give one."""
    return f"{n} seed{'s' if n != 1 else ''}: too few for an interval; run >= {MIN_SEEDS} seeds"


def paired_t_power(effect: float, n: int, alpha: float = ALPHA) -> float:
    """Power of the two-sided paired t-test on ``n`` pairs against a true mean difference of ``effect`` SDs.

    The statistic is noncentral t (n - 1 degrees of freedom, noncentrality effect * sqrt(n)); the far tail is taken
    as the upper tail at -effect, which stays finite where the lower tail of a large noncentrality does not.
    """
    df, noncentrality = n - 1, effect * math.sqrt(n)
    critical = stats.t.ppf(1 - alpha / 2, df)
    return float(stats.nct.sf(critical, df, noncentrality) + stats.nct.sf(critical, df, -noncentrality))


def mde_80(sd_diff: float, n: int, alpha: float = ALPHA, power: float = POWER) -> float:
    """Smallest paired difference a two-sided paired t-test on ``n`` seeds detects with 80 % power.

    Solved exactly from the noncentral t (:func:`paired_t_power`), since the textbook shortcut
    (t_{1-alpha/2} + t_{power}) * sd / sqrt(n) understates it by 5 % at 3 seeds and 2 % at 4.
    """
    if not alpha < power < 1:
        raise ValueError(f"mde_80: power must lie between alpha ({alpha}) and 1, got {power}")
    if n < 2 or not np.isfinite(sd_diff):
        return math.nan
    high = (stats.t.ppf(1 - alpha / 2, n - 1) + stats.t.ppf(power, n - 1)) / math.sqrt(n)  # the shortcut: a start
    while paired_t_power(high, n, alpha) < power:
        high *= 2
    effect = optimize.brentq(lambda d: paired_t_power(d, n, alpha) - power, 0.0, high, xtol=1e-12)
    return float(effect * sd_diff)


@dataclass(frozen=True)
class Paired:
    """A paired difference over seeds (``a - b``) and its verdict for a quantity with a margin."""

    n: int
    mean: float
    low: float
    high: float
    mde: float
    margin: float
    verdict: str  # better | worse | equivalent | undetermined | too few seeds
    within: float  # the half-width the verdict states (the margin, or the interval's farthest end)

    def words(self) -> str:
        """The verdict as the report writes it."""
        if self.verdict == "too few seeds":
            return too_few(self.n)
        if self.verdict == "equivalent":
            return f"equivalent within ±{self.margin:.2f}"
        if self.verdict == "undetermined":
            return f"undetermined within ±{self.within:.3f}"
        return self.verdict

    def interval(self) -> str:
        """``-0.001 [-0.075, +0.073], n = 4 seeds`` (or only the mean and why there is no interval)."""
        if self.verdict == "too few seeds":
            return f"{self.mean:+.3f} ({too_few(self.n)})" if np.isfinite(self.mean) else too_few(self.n)
        return f"{self.mean:+.3f} [{self.low:+.3f}, {self.high:+.3f}]"

    def sentence(self) -> str:
        """Interval, verdict and the smallest effect the seeds could detect, in one clause."""
        if self.verdict == "too few seeds":
            return self.interval()
        return (f"{self.interval()} over {self.n} paired seeds: {self.words()} (margin ±{self.margin:.2f}; "
                f"smallest difference {self.n} seeds detect with 80 % power: {self.mde:.3f})")


def paired(a: pd.Series, b: pd.Series, metric: str = "rmse") -> Paired:
    """The paired difference ``a - b`` over the seeds both have (Series indexed by seed) and its verdict."""
    common = a.dropna().index.intersection(b.dropna().index)
    d = (a.loc[common] - b.loc[common]).to_numpy(dtype=float)
    return judge(d, metric)


def judge(d, metric: str = "rmse") -> Paired:
    """The verdict of per-seed differences ``d`` on ``metric`` (lower RMSE, higher OVL is better)."""
    d = np.asarray(d, dtype=float)
    d = d[np.isfinite(d)]
    mean, half, n = mean_interval(d)
    margin = MARGINS.get(metric, math.nan)
    if n < MIN_SEEDS:
        return Paired(n, mean, math.nan, math.nan, math.nan, margin, "too few seeds", math.nan)
    low, high = mean - half, mean + half
    bound = 1.0 if RANGES.get(metric, (0, math.inf))[1] == 1.0 else math.inf  # a difference of OVLs is in [-1, 1]
    low, high = max(low, -bound), min(high, bound)
    if low > 0 or high < 0:
        verdict = "worse" if (mean > 0) != HIGHER_IS_BETTER.get(metric, False) else "better"
    elif np.isfinite(margin) and -margin <= low and high <= margin:
        verdict = "equivalent"
    else:
        verdict = "undetermined"
    return Paired(n, mean, low, high, mde_80(float(d.std(ddof=1)), n), margin, verdict, max(abs(low), abs(high)))


def level(values, metric: str) -> tuple[float, float, float, int]:
    """Mean of a level over seeds and its 95 % interval clipped to the quantity's range (NaN below MIN_SEEDS)."""
    mean, half, n = mean_interval(values)
    if n < MIN_SEEDS:
        return mean, math.nan, math.nan, n
    lo, hi = RANGES.get(metric, (-math.inf, math.inf))
    return mean, max(mean - half, lo), min(mean + half, hi), n


def null_rmse(specimens: pd.DataFrame, reference_rows: int | None = None) -> pd.Series:
    """The training mean's RMSE under the same CV, mean over specimens, per stored (cell, pad, condition, cv, model).

    From the stored per-specimen targets (``gmean``): every specimen has the same number of rows in a cell (one per
    mount, the ``repetitions`` column, or ``reference_rows``), so its rows are rebuilt and predicted by the analysis's
    own training-mean model (analysis.controls.training_mean_predictions: LOSO leaves out the specimen, LOO the
    row). Each specimen's rows share one target and one prediction, so its RMSE is their distance; the mean over
    specimens is on the same footing as a cell's ``rmse`` (tests/explore/test_explore.py checks it against the analysis).
    """
    keys = ["cell", "pad", "condition", "cv", "model"]
    out = {}
    for key, group in specimens.groupby(keys, sort=False, dropna=False):
        g = group["gmean"].to_numpy(dtype=float)
        if g.size < 2:
            out[key] = math.nan
            continue
        rows = int(group["repetitions"].iloc[0]) if reference_rows is None else reference_rows
        rows = 1 if key[3] == "loso" else rows  # LOSO leaves a specimen's rows out together: one stands for all
        y = np.repeat(g, rows)
        prediction = training_mean_predictions(y, np.repeat(np.arange(g.size), rows), key[3])[::rows]
        out[key] = float(np.abs(prediction - g).mean())
    return pd.Series(out, dtype=float).rename_axis(keys).rename("null_rmse")
