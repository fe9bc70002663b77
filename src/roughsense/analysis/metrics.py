"""The paper's performance indices (§3.4) and statistics (§4): OVL, per-specimen RMSE, summaries, signed-rank, and
the one significance level and t-interval of the mean that the controls and the sweeps share.

Everything here works on plain arrays and small per-specimen tables, so the study analysis, the report
and the tests against the published tables all share one definition of each number.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import NamedTuple

import numpy as np
import pandas as pd
from scipy.special import ndtr

from ..errors import ConfigError, InputError

#: Largest number of non-zero differences for which :func:`signed_rank` enumerates the exact null
#: distribution by default (MATLAB's signrank switches to the normal approximation above 15).
EXACT_MAX_N = 15

OVERALL_GROUP = "all"

#: The significance level of every test and interval: a control passes when p < ALPHA, intervals are 1 - ALPHA.
ALPHA = 0.05


# --------------------------------------------------------------------------- overlap coefficient


def _tail_masses(mean, sd, lo, hi):
    """P(lo < X < hi) for X ~ N(mean, sd), taking the upper tail from the survival side for accuracy."""
    z_lo = (lo - mean) / sd
    z_hi = (hi - mean) / sd
    # Both limits in the upper tail: 1 - Phi loses digits there, Phi(-z) does not.
    upper = (z_lo > 0)
    return np.where(upper, ndtr(-z_lo) - ndtr(-z_hi), ndtr(z_hi) - ndtr(z_lo))


def overlap(mean1, sd1, mean2, sd2):
    """Overlap coefficient OVL = ∫ min(f1, f2) dx of two normal densities (paper eq. 9), in closed form.

    Broadcasts like numpy; a float for scalar input. NaN or infinite input gives NaN (e.g. the reference specimen,
    whose perceived SD is undefined); a negative SD is an error; an SD of 0 is a point mass, overlapping nothing
    (0, the limit as the SD shrinks) but an identical point mass (1).

    Parameters
    ----------
    mean1, sd1 : float or array-like
        The first normal density (e.g. people's perceived roughness and its SD).
    mean2, sd2 : float or array-like
        The second (e.g. the sensor's predictions of it).

    Returns
    -------
    float or numpy.ndarray
        The overlap, from 0 (disjoint) to 1 (identical).

    Examples
    --------
    >>> import roughsense as rs
    >>> round(rs.overlap(1.39, 0.35, 1.33, 0.18), 3)
    0.681
    >>> rs.overlap(1.0, 0.2, [1.0, 2.0], 0.2).round(3)  # broadcasts
    array([1.   , 0.012])
    """
    m1, s1, m2, s2 = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (mean1, sd1, mean2, sd2)))
    if np.any(s1 < 0) or np.any(s2 < 0):
        raise ConfigError("overlap: standard deviations must be >= 0")
    finite = np.isfinite(m1) & np.isfinite(s1) & np.isfinite(m2) & np.isfinite(s2)
    degenerate = finite & ((s1 == 0) | (s2 == 0))
    regular = finite & ~degenerate
    # Work on safe stand-ins where the formula does not apply; those entries are overwritten below.
    m1r, m2r = np.where(regular, m1, 0.0), np.where(regular, m2, 0.0)
    s1r, s2r = np.where(regular, s1, 1.0), np.where(regular, s2, 1.0)
    x_lo, x_hi = _crossings(m1r, s1r, m2r, s2r)
    edges = (np.full_like(x_lo, -np.inf), x_lo, x_hi, np.full_like(x_lo, np.inf))
    total = np.zeros_like(x_lo)
    for lo, hi in zip(edges[:-1], edges[1:]):
        with np.errstate(invalid="ignore"):
            p1 = _tail_masses(m1r, s1r, lo, hi)
            p2 = _tail_masses(m2r, s2r, lo, hi)
        total += np.where(hi > lo, np.minimum(np.nan_to_num(p1), np.nan_to_num(p2)), 0.0)
    both_points_equal = (s1 == 0) & (s2 == 0) & (m1 == m2)
    result = np.where(regular, np.clip(total, 0.0, 1.0), np.nan)
    result = np.where(degenerate, np.where(both_points_equal, 1.0, 0.0), result)
    return float(result) if result.ndim == 0 else result


def _crossings(m1, s1, m2, s2) -> tuple[np.ndarray, np.ndarray]:
    """Where two normal densities cross (lower, upper; +inf where they cross once or not at all).

    The log-densities differ by a quadratic, so they cross at most twice, and between consecutive crossings one
    density lies below the other throughout: the integral of the minimum there is the smaller of the two normal
    probabilities of the interval (:func:`overlap`), with no case split on which SD is larger. Equal SDs degrade to
    the single crossing at the midpoint (the quadratic term vanishes; the stable root formula sends the second root
    to infinity).
    """
    v1, v2 = s1**2, s2**2
    # s2²(x−m1)² − s1²(x−m2)² + 2 s1² s2² ln(s1/s2) = 0  →  a x² + 2 b x + c = 0
    a = v2 - v1
    b = m2 * v1 - m1 * v2
    c = v2 * m1**2 - v1 * m2**2 + 2.0 * v1 * v2 * np.log(s1 / s2)
    root_disc = s1 * s2 * np.sqrt((m1 - m2) ** 2 + 2.0 * (v1 - v2) * np.log(s1 / s2))
    q = -(b + np.where(b >= 0, 1.0, -1.0) * root_disc)
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(q != 0, c / q, np.nan)
        r2 = np.where(a != 0, q / a, np.nan)
    # q == 0 only when the densities coincide (b = 0 and no discriminant): nothing to split.
    r1 = np.where(np.isnan(r1), np.inf, r1)
    r2 = np.where(np.isnan(r2), np.inf, r2)
    return np.minimum(r1, r2), np.maximum(r1, r2)


# --------------------------------------------------------------------------- per-specimen table


def specimen_rmse(predictions, target: float) -> float:
    """RMSE of one specimen's predictions against its perceived geometric mean (§3.4)."""
    values = np.asarray(predictions, dtype=float)
    if values.size == 0:
        return float("nan")
    return float(np.sqrt(np.mean((values - float(target)) ** 2)))


def specimen_table(pred_df: pd.DataFrame, summary_df: pd.DataFrame, *, pred_sd_ddof: int = 1) -> pd.DataFrame:
    """Per specimen: perceived gmean/sd, predictions' mean and SD, OVL and RMSE (Tables 1-6).

    ``pred_df`` has one row per prediction (columns specimen, prediction); ``summary_df`` is the output
    of :func:`roughsense.analysis.magnitude_estimation.aggregate_ratings`. Rows follow the order of ``summary_df``; only
    specimens with predictions appear. OVL is NaN where the perceived SD is undefined (the reference).
    ``pred_sd`` is the sample SD by default; the paper's tables are consistent with the population SD
    (``pred_sd_ddof=0``), which also enters the OVL -- see docs/perception.md.
    """
    for frame, name, needed in ((pred_df, "predictions", ("specimen", "prediction")),
                                (summary_df, "perceived summary", ("specimen", "gmean", "sd"))):
        missing = [c for c in needed if c not in frame.columns]
        if missing:
            raise InputError(f"{name} table lacks column(s) {', '.join(missing)}")
    perceived = summary_df.set_index("specimen")
    unknown = sorted(set(pred_df["specimen"]) - set(perceived.index))
    if unknown:
        raise InputError(f"no perceived roughness for specimen(s) {', '.join(map(str, unknown))}")
    groups = pred_df.groupby("specimen", sort=False)["prediction"]
    rows = []
    for specimen in perceived.index:
        if specimen not in groups.groups:
            continue
        values = groups.get_group(specimen).to_numpy(dtype=float)
        gmean, sd = float(perceived.at[specimen, "gmean"]), float(perceived.at[specimen, "sd"])
        pred_mean = float(values.mean())
        pred_sd = float(values.std(ddof=pred_sd_ddof)) if values.size > pred_sd_ddof else float("nan")
        rows.append({
            "specimen": specimen,
            "gmean": gmean,
            "sd": sd,
            "pred_mean": pred_mean,
            "pred_sd": pred_sd,
            "ovl": overlap(gmean, sd, pred_mean, pred_sd),
            "rmse": specimen_rmse(values, gmean),
            "n_predictions": int(values.size),
        })
    columns = ["specimen", "gmean", "sd", "pred_mean", "pred_sd", "ovl", "rmse", "n_predictions"]
    return pd.DataFrame(rows, columns=columns)


def shape_summary(table: pd.DataFrame, shapes: Mapping[str, str], column: str) -> pd.DataFrame:
    """Mean ± sample SD (ddof=1, as MATLAB's std) of ``column`` per shape and over all specimens.

    Rows: one per shape in order of first appearance in ``table``, then ``"all"`` -- the summary rows of
    Tables 2, 3, 5 and 6. NaN values (the reference's OVL) are left out and not counted.
    """
    if column not in table.columns:
        raise InputError(f"table has no column {column!r}")
    unknown = [s for s in table["specimen"] if s not in shapes]
    if unknown:
        raise InputError(f"no shape given for specimen(s) {', '.join(map(str, dict.fromkeys(unknown)))}")
    shape_of = table["specimen"].map(shapes)
    rows = []
    for group in [*dict.fromkeys(shape_of), OVERALL_GROUP]:
        selected = table[column] if group == OVERALL_GROUP else table.loc[shape_of == group, column]
        values = selected.to_numpy(dtype=float)
        values = values[~np.isnan(values)]
        rows.append({
            "group": group,
            "mean": float(values.mean()) if values.size else float("nan"),
            "sd": float(values.std(ddof=1)) if values.size > 1 else float("nan"),
            "n": int(values.size),
        })
    return pd.DataFrame(rows, columns=["group", "mean", "sd", "n"])


# --------------------------------------------------------------------------- signed-rank test


class SignedRankResult(NamedTuple):
    statistic: float  # W: sum of the ranks of the positive differences x - y (MATLAB's stats.signedrank)
    p: float  # two-sided
    method: str  # "exact" or "approximate"
    n: int  # number of non-zero differences


def _clean_differences(x, y) -> np.ndarray:
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if x.shape != y.shape:
        raise InputError(f"signed-rank test needs paired samples of equal length, got {x.size} and {y.size}")
    if np.isnan(x).any() or np.isnan(y).any():
        raise InputError("signed-rank test: NaN in the paired samples")
    d = x - y
    # Values read from a table carry binary noise (0.45 - 0.35 != 0.20 - 0.10); differences that agree
    # to 12 significant digits of the data's scale are the same number, so ties and zeros are detected.
    scale = max(float(np.max(np.abs(x), initial=0.0)), float(np.max(np.abs(y), initial=0.0)), np.finfo(float).tiny)
    quantum = scale * 1e-12
    return np.round(d / quantum) * quantum


def _exact_upper_tail(ranks: np.ndarray, w: float) -> tuple[float, float]:
    """P(T <= w) and P(T >= w) for T = sum of a random subset of ``ranks`` (each sign equally likely).

    Midranks are multiples of 1/2, so doubled ranks are integers and the null distribution is the
    coefficient list of prod (1 + z^r) -- a small convolution, exact for ties too (as MATLAB enumerates).
    """
    doubled = np.rint(2 * ranks).astype(np.int64)
    counts = np.zeros(int(doubled.sum()) + 1)
    counts[0] = 1.0
    for r in doubled:
        shifted = np.zeros_like(counts)
        shifted[r:] = counts[: counts.size - r]
        counts = counts + shifted
    probs = counts / counts.sum()
    k = int(np.rint(2 * w))
    return float(probs[: k + 1].sum()), float(probs[k:].sum())


def signed_rank(x, y=None, *, method: str = "auto") -> SignedRankResult:
    """Two-sided Wilcoxon signed-rank test of x - y (or of x), as MATLAB's ``signrank`` reports it.

    Zero differences are dropped, tied |differences| get average ranks, W is the sum of the ranks of
    the positive differences, and the p-value is exact (enumerating the null distribution of the given
    midranks) for n <= 15, else the tie-corrected normal approximation with continuity correction.
    """
    d = _clean_differences(x, np.zeros_like(np.asarray(x, dtype=float)) if y is None else y)
    d = d[d != 0]
    n = int(d.size)
    if method not in ("auto", "exact", "approximate"):
        raise ConfigError(f"signed_rank: method must be auto, exact or approximate, got {method!r}")
    if n == 0:
        return SignedRankResult(0.0, 1.0, "exact", 0)
    from scipy.stats import rankdata

    ranks = rankdata(np.abs(d))
    w = float(ranks[d > 0].sum())
    chosen = method if method != "auto" else ("exact" if n <= EXACT_MAX_N else "approximate")
    if chosen == "exact":
        below, above = _exact_upper_tail(ranks, w)
        p = min(1.0, 2.0 * min(below, above))
    else:
        _, tie_counts = np.unique(ranks, return_counts=True)
        variance = n * (n + 1) * (2 * n + 1) / 24.0 - np.sum(tie_counts**3 - tie_counts) / 48.0
        centred = w - n * (n + 1) / 4.0
        z = (centred - 0.5 * np.sign(centred)) / np.sqrt(variance) if variance > 0 else 0.0
        p = float(min(1.0, 2.0 * ndtr(-abs(z))))
    return SignedRankResult(w, float(p), chosen, n)


def _aligned(values: Mapping[str, object], names: Iterable[str]) -> dict[str, np.ndarray]:
    """Pair the samples by specimen when they are Series, by position otherwise."""
    names = list(names)
    series = [values[n] for n in names]
    if all(isinstance(s, pd.Series) for s in series):
        common = series[0].index
        for s in series[1:]:
            common = common.intersection(s.index, sort=False)
        dropped = set().union(*(set(s.index) - set(common) for s in series))
        if dropped:
            raise InputError(
                f"signed-rank comparison: specimen(s) {', '.join(map(str, sorted(dropped)))} "
                "are missing from some conditions"
            )
        return {n: s.loc[common].to_numpy(dtype=float) for n, s in zip(names, series)}
    return {n: np.asarray(s, dtype=float) for n, s in zip(names, series)}


def compare_conditions(
    rmse_by_condition: Mapping[str, object],
    baseline: str,
    others: Sequence[str] | None = None,
    *,
    bonferroni: int | None = None,
) -> pd.DataFrame:
    """Signed-rank tests of ``baseline`` against each of ``others`` over specimens, Bonferroni-adjusted.

    W is for baseline - other, so W = 0 means the baseline was lower for every specimen (the paper's
    "combined vs 3 N: W = 0"). ``bonferroni`` defaults to the number of comparisons.
    """
    if baseline not in rmse_by_condition:
        raise ConfigError(f"baseline condition {baseline!r} not among {', '.join(rmse_by_condition)}")
    others = [c for c in rmse_by_condition if c != baseline] if others is None else list(others)
    missing = [c for c in others if c not in rmse_by_condition]
    if missing:
        raise ConfigError(f"condition(s) {', '.join(missing)} not among {', '.join(rmse_by_condition)}")
    factor = len(others) if bonferroni is None else int(bonferroni)
    if factor < 1:
        raise ConfigError(f"Bonferroni factor must be >= 1, got {bonferroni}")
    samples = _aligned(rmse_by_condition, [baseline, *others])
    rows = []
    for other in others:
        test = signed_rank(samples[baseline], samples[other])
        rows.append({
            "comparison": f"{baseline} vs {other}",
            "statistic": test.statistic,
            "p": test.p,
            "p_adjusted": min(1.0, test.p * factor),
            "n": test.n,
            "method": test.method,
        })
    return pd.DataFrame(rows, columns=["comparison", "statistic", "p", "p_adjusted", "n", "method"])


# --------------------------------------------------------------------------- t-interval of a mean


def mean_interval(values, alpha: float = ALPHA) -> tuple[float, float, int]:
    """Mean of the finite ``values``, the half-width of its two-sided t-interval (1 - ``alpha``), and their count.

    NaN mean for no values, NaN half-width for one: the replicate-based intervals of sweeps and paired comparisons.
    """
    from scipy.stats import t

    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return float("nan"), float("nan"), 0
    if n == 1:
        return float(x[0]), float("nan"), 1
    return float(x.mean()), float(t.ppf(1 - alpha / 2, n - 1) * x.std(ddof=1) / np.sqrt(n)), n


# --------------------------------------------------------------------------- equivalence (TOST)


class EquivalenceResult(NamedTuple):
    estimate: float  # the mean paired difference, or the slope
    p: float  # the larger of the two one-sided p-values: equivalence is shown when p < alpha
    p_lower: float  # H0: estimate <= -margin
    p_upper: float  # H0: estimate >= +margin
    df: int


def tost(estimate: float, standard_error: float, df: int, margin: float) -> EquivalenceResult:
    """Two one-sided t-tests that ``estimate`` lies within ±``margin`` (Schuirmann's TOST).

    Equivalence is claimed only when both "estimate <= -margin" and "estimate >= +margin" are rejected, so the
    p-value is the larger one-sided p; a large p says the data cannot tell, never that the two are the same.
    NaN when the estimate has no finite standard error (too few values, or none of them vary).
    """
    from scipy.stats import t

    if not margin > 0:
        raise ConfigError(f"tost: the equivalence margin must be > 0, got {margin}")
    if df < 1 or not np.isfinite(estimate) or not (np.isfinite(standard_error) and standard_error > 0):
        return EquivalenceResult(float(estimate), float("nan"), float("nan"), float("nan"), int(df))
    p_lower = float(t.sf((estimate + margin) / standard_error, df))
    p_upper = float(t.cdf((estimate - margin) / standard_error, df))
    return EquivalenceResult(float(estimate), max(p_lower, p_upper), p_lower, p_upper, int(df))


def paired_tost(x, y, margin: float) -> EquivalenceResult:
    """TOST on the paired differences x - y (one pair per specimen): is their mean within ±margin?"""
    d = np.asarray(x, dtype=float) - np.asarray(y, dtype=float)
    d = d[np.isfinite(d)]
    if d.size < 2:
        return tost(float(d.mean()) if d.size else float("nan"), float("nan"), 0, margin)
    return tost(float(d.mean()), float(d.std(ddof=1) / np.sqrt(d.size)), d.size - 1, margin)


def slope_tost(x, y, margin: float) -> EquivalenceResult:
    """TOST on the least-squares slope of y on x: is it within ±margin (flat, up to the margin)?"""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    n = x.size
    sxx = float(np.sum((x - x.mean()) ** 2)) if n else 0.0
    if n < 3 or sxx == 0:
        return tost(float("nan"), float("nan"), 0, margin)
    slope = float(np.sum((x - x.mean()) * (y - y.mean())) / sxx)
    residuals = y - y.mean() - slope * (x - x.mean())
    standard_error = float(np.sqrt(np.sum(residuals**2) / (n - 2) / sxx))
    return tost(slope, standard_error, n - 2, margin)
