"""The tests of the paper's sensor and rating claims: each gives one row's statistic, p and evidence
(:class:`ClaimTest`), before :mod:`.claims` looks up the controls of the models it rests on and applies the one
verdict rule.

Each claim's margin (:data:`OVL_MARGIN`, :data:`SD_SLOPE_MARGIN`) was chosen before looking at any result; a claim
the training-mean model meets as well (``null_meets``) cannot tell a model from no model.
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import KW_ONLY, dataclass
from itertools import combinations

import numpy as np
import pandas as pd
from scipy import stats

from ..paper import COMBINED, FINGERPRINT_PAD, FORCE_CONDITIONS, SMOOTH_PAD
from .geometry import PAPER_GEOMETRY
from .metrics import ALPHA, compare_conditions, paired_tost, signed_rank, slope_tost

#: Equivalence margin for a difference in mean OVL (a 0..1 scale), chosen before looking at any result: a tenth
#: of the scale, below the between-specimen SD of OVL in the paper's Tables 2 and 5 (0.13-0.19), and over twice
#: every difference the paper reads as "the same" (at most 0.04 between its conditions and pads).
OVL_MARGIN = 0.1
#: "Flat" prediction SD: it changes by less than a factor 1.25 (either way) per doubling of perceived roughness,
#: i.e. a slope within ±log2(1.25) = 0.32 of log SD on log perceived roughness. People's SD, by Weber's law, has
#: slope 1 (it doubles per doubling), the contrast the paper draws; 0.32 is under a third of that.
SD_RATIO_PER_DOUBLING = 1.25
SD_SLOPE_MARGIN = math.log2(SD_RATIO_PER_DOUBLING)
#: Specimens the paper names as having OVL < 0.5 in every condition (Discussion).
LOW_OVL_SPECIMENS = ("R2", "R2.5", "C5")


@dataclass(frozen=True)
class Evidence:
    """What one row of claims.csv holds for its verdict (the columns of the same names)."""

    testable: bool
    holds: bool  # the claim's statement holds in the point estimates (direction, share, within the margin)
    p: float  # the claim's own test, after its correction; NaN: a descriptive claim with no test
    premise_passes: bool = True  # every model the claim rests on passes its controls (True when it rests on none)
    null_meets: bool | None = None  # the training-mean model meets the claim too; None: not applicable
    equivalence_margin: float = float("nan")  # set for a claim of no difference or of flatness
    equivalence_p: float = float("nan")  # its TOST p (intersection-union: the largest over its comparisons)
    alpha: float = ALPHA


def _quiet(test, *args):
    """A scipy test with its warnings (constant input, tiny samples) silenced: a NaN result says it all."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return test(*args)


@dataclass(frozen=True)
class ClaimTest:
    """One claim tested on one pad and CV scheme: its statistic and evidence, before its premise is looked up.

    Its verdict also needs the controls of the models it ``rests_on``; :func:`.claims.evaluate_claims` adds them.
    """

    key: str
    pad: str
    cv: str
    statistic: float
    p: float
    rule: str
    detail: str = ""
    _: KW_ONLY
    holds: bool
    rests_on: Sequence[tuple[str, str]] = ()  # (pad, condition) of each model the claim rests on
    margin: float = float("nan")
    equivalence_p: float = float("nan")
    null_meets: bool | None = None
    correction: str = "none"
    testable: bool = True

    def evidence(self, premise_passes: bool) -> Evidence:
        return Evidence(testable=self.testable, holds=bool(self.holds), p=float(self.p), premise_passes=premise_passes,
                        null_meets=self.null_meets, equivalence_margin=float(self.margin),
                        equivalence_p=float(self.equivalence_p))


def _untestable(key, pad, cv, why) -> ClaimTest:
    return ClaimTest(key, pad, cv, np.nan, np.nan, "", why, holds=False, testable=False)


def _largest_p(ps) -> float:
    """Intersection-union: the claim holds only if every comparison rejects, so its p is the largest (NaN if any is)."""
    ps = np.asarray(list(ps), dtype=float)
    return float("nan") if ps.size == 0 or np.isnan(ps).any() else float(ps.max())


def _by_condition(results: pd.DataFrame, pad: str, column: str) -> dict[str, pd.Series]:
    rows = results[results.pad == pad]
    return {c: g.set_index("specimen")[column] for c, g in rows.groupby("condition", sort=False)}


def _combined_beats_singles(results, pad, cv):
    series = _by_condition(results, pad, "rmse")
    key = "combined_beats_singles"
    if COMBINED not in series or not all(c in series for c in FORCE_CONDITIONS):
        return _untestable(key, pad, cv, "needs the 1N, 2N, 3N and combined conditions")
    table = compare_conditions(series, COMBINED, list(FORCE_CONDITIONS), bonferroni=len(FORCE_CONDITIONS))
    lower = all(series[COMBINED].mean() < series[c].mean() for c in FORCE_CONDITIONS)
    worst = table.loc[table["p_adjusted"].idxmax()]
    detail = "; ".join(f"{r.comparison}: W = {r.statistic:g}, adjusted p = {r.p_adjusted:.2g}" for r in table.itertuples())
    return ClaimTest(key, pad, cv, worst["statistic"], worst["p_adjusted"],
                "test: signed rank of combined against each single force (statistic, p: the weakest comparison); "
                "holds: the combined mean RMSE is lower than each", detail, holds=lower,
                rests_on=[(pad, c) for c in (*FORCE_CONDITIONS, COMBINED)],
                correction=f"Bonferroni x{len(FORCE_CONDITIONS)}")


def _combined_lowest_mean(results, pad, cv):
    series = _by_condition(results, pad, "rmse")
    key = "combined_lowest_mean"
    singles = [c for c in FORCE_CONDITIONS if c in series]
    if COMBINED not in series or not singles:
        return _untestable(key, pad, cv, "needs the combined condition and a single force")
    means = {c: float(s.mean()) for c, s in series.items()}
    margin = means[COMBINED] - min(means[c] for c in singles)
    table = compare_conditions(series, COMBINED, singles, bonferroni=1)
    detail = ", ".join(f"{c} {v:.3f}" for c, v in means.items())
    return ClaimTest(key, pad, cv, margin, _largest_p(table["p"]),
                "test: signed rank of combined against each single force (p: the largest); holds: combined mean "
                "RMSE minus the lowest single-force mean < 0 (statistic)", detail, holds=margin < 0,
                rests_on=[(pad, c) for c in (*singles, COMBINED)],
                correction=f"none (intersection-union: each of the {len(singles)} comparisons must reject)")


def _smooth_beats_fingerprint(results, pads, cv):
    key = "smooth_beats_fingerprint"
    if not {SMOOTH_PAD, FINGERPRINT_PAD} <= set(pads):
        return _untestable(key, "both", cv, "needs both the smooth and the fingerprint pad")
    a = _by_condition(results, SMOOTH_PAD, "rmse").get(COMBINED)
    b = _by_condition(results, FINGERPRINT_PAD, "rmse").get(COMBINED)
    if a is None or b is None:
        return _untestable(key, "both", cv, "needs the combined condition")
    common = a.index.intersection(b.index)
    test = signed_rank(a.loc[common].to_numpy(), b.loc[common].to_numpy())
    return ClaimTest(key, "both", cv, test.statistic, test.p,
                "test: signed rank over specimens; holds: the smooth pad's mean RMSE is lower",
                f"mean RMSE smooth {a.loc[common].mean():.3f}, fingerprint {b.loc[common].mean():.3f}",
                holds=a.loc[common].mean() < b.loc[common].mean(),
                rests_on=[(SMOOTH_PAD, COMBINED), (FINGERPRINT_PAD, COMBINED)])


def _rmse_below_sd(results, null, pad, cv):
    key = "rmse_below_sd"
    rows = results[(results.pad == pad) & (results.condition == COMBINED)].dropna(subset=["sd"])
    if rows.empty:
        return _untestable(key, pad, cv, "needs the combined condition and rated specimens")
    below, n = int((rows["rmse"] < rows["sd"]).sum()), len(rows)
    base = null[(null.pad == pad) & (null.condition == COMBINED)].set_index("specimen").reindex(rows["specimen"])
    null_below = int((base["rmse"].to_numpy() < rows["sd"].to_numpy()).sum())
    p = stats.binomtest(below, n, 0.5, alternative="greater").pvalue
    return ClaimTest(key, pad, cv, below / n, p,
                "test: one-sided sign test (p); holds: more than half of the rated specimens have RMSE < SD "
                "(statistic: the share); the training mean meets it when its own share is above half",
                f"{below} of {n} specimens; training mean: {null_below} of {n}", holds=below > n / 2,
                rests_on=[(pad, COMBINED)], null_meets=null_below > n / 2)


def _ovl_same_across_forces(results, pad, cv):
    key = "ovl_same_across_forces"
    series = _by_condition(results, pad, "ovl")
    if len(series) < 3:
        return _untestable(key, pad, cv, "needs at least three conditions")
    frame = pd.DataFrame(series).dropna()
    if len(frame) < 2:
        return _untestable(key, pad, cv, "needs at least 2 rated specimens")
    test = _quiet(stats.friedmanchisquare, *[frame[c].to_numpy() for c in frame.columns])
    pairs = list(combinations(frame.columns, 2))
    tosts = [paired_tost(frame[a], frame[b], OVL_MARGIN) for a, b in pairs]
    largest = max(abs(t.estimate) for t in tosts)
    return ClaimTest(key, pad, cv, test.statistic, test.pvalue,
                f"test of a difference: Friedman (p); equivalence: paired TOST of the mean OVL difference of every "
                f"pair of conditions within ±{OVL_MARGIN} (equivalence_p: the largest); holds: every pair's mean "
                "difference within the margin",
                ", ".join(f"{c} {frame[c].mean():.2f}" for c in frame.columns) + f"; largest pair difference {largest:.2f}",
                holds=largest < OVL_MARGIN, rests_on=[(pad, c) for c in frame.columns], margin=OVL_MARGIN,
                equivalence_p=_largest_p(t.p for t in tosts),
                correction=f"Friedman: none; TOST: none (intersection-union over the {len(pairs)} pairs)")


def _ovl_pads_comparable(results, pads, cv):
    key = "ovl_pads_comparable"
    if not {SMOOTH_PAD, FINGERPRINT_PAD} <= set(pads):
        return _untestable(key, "both", cv, "needs both the smooth and the fingerprint pad")
    a, b = _by_condition(results, SMOOTH_PAD, "ovl"), _by_condition(results, FINGERPRINT_PAD, "ovl")
    conditions = [c for c in a if c in b]
    if not conditions:
        return _untestable(key, "both", cv, "the pads share no condition")
    diffs, ps, tosts = [], [], []
    for c in conditions:
        pair = pd.concat([a[c], b[c]], axis=1, join="inner").dropna()
        diffs.append(float(pair.iloc[:, 0].mean() - pair.iloc[:, 1].mean()))
        ps.append(min(1.0, signed_rank(pair.iloc[:, 0].to_numpy(), pair.iloc[:, 1].to_numpy()).p * len(conditions)))
        tosts.append(paired_tost(pair.iloc[:, 0], pair.iloc[:, 1], OVL_MARGIN).p)
    largest = float(np.max(np.abs(diffs)))
    return ClaimTest(key, "both", cv, largest, min(ps),
                "test of a difference: signed rank per condition (p: the smallest adjusted); equivalence: paired TOST "
                f"of the mean OVL difference within ±{OVL_MARGIN} in every condition (equivalence_p: the largest); "
                "holds: largest |difference of mean OVL| (statistic) within the margin",
                ", ".join(f"{c} {d:+.2f}" for c, d in zip(conditions, diffs)), holds=largest < OVL_MARGIN,
                rests_on=[(pad, c) for pad in (SMOOTH_PAD, FINGERPRINT_PAD) for c in conditions], margin=OVL_MARGIN,
                equivalence_p=_largest_p(tosts),
                correction=f"signed rank: Bonferroni x{len(conditions)}; TOST: none (intersection-union over "
                           f"the {len(conditions)} conditions)")


def _low_ovl_specimens(results, null, pad, cv):
    key = "low_ovl_specimens"
    rows = results[(results.pad == pad) & results.specimen.isin(LOW_OVL_SPECIMENS)]
    if set(rows["specimen"]) != set(LOW_OVL_SPECIMENS):
        return _untestable(key, pad, cv, f"needs the specimens {', '.join(LOW_OVL_SPECIMENS)}")
    below = int((rows["ovl"] < 0.5).sum())
    base = null[(null.pad == pad) & null.specimen.isin(LOW_OVL_SPECIMENS)]
    null_below = int((base["ovl"] < 0.5).sum())
    return ClaimTest(key, pad, cv, below / len(rows), np.nan,
                "descriptive, no test: every one of these cells has OVL < 0.5 (statistic: the share); the training "
                "mean meets it when all its cells do", f"{below} of {len(rows)} cells; training mean: {null_below} "
                f"of {len(base)}", holds=below == len(rows), rests_on=[(pad, c) for c in dict.fromkeys(rows.condition)],
                null_meets=len(base) > 0 and null_below == len(base))


def _sd_flat(results, pad, cv):
    key = "sd_flat"
    rows = results[(results.pad == pad) & (results.condition == COMBINED)].dropna(subset=["sd"])
    if len(rows) < 4:
        return _untestable(key, pad, cv, "needs the combined condition and at least 4 rated specimens")
    rho, p = _quiet(stats.spearmanr, rows["gmean"], rows["pred_sd"])
    if np.isnan(rho):
        return _untestable(key, pad, cv, "the prediction SD or the perceived roughness is constant")
    positive = bool((rows["pred_sd"] > 0).all() and (rows["gmean"] > 0).all())
    flat = slope_tost(np.log2(rows["gmean"]), np.log2(rows["pred_sd"]), SD_SLOPE_MARGIN) if positive else None
    slope = flat.estimate if flat else float("nan")
    return ClaimTest(key, pad, cv, rho, p,
                "test of a rise: Spearman of the prediction SD on perceived roughness (statistic, p); equivalence: "
                f"TOST of the least-squares slope of log2 SD on log2 perceived roughness within ±{SD_SLOPE_MARGIN:.3f} "
                f"(the SD changes by less than x{SD_RATIO_PER_DOUBLING} per doubling); holds: the slope within it",
                f"mean prediction SD {rows['pred_sd'].mean():.2f}; log-log slope {slope:.2f}",
                holds=abs(slope) < SD_SLOPE_MARGIN, rests_on=[(pad, COMBINED)], margin=SD_SLOPE_MARGIN,
                equivalence_p=flat.p if flat else float("nan"))


def _aligns(results, null, pad, cv):
    key = "aligns"
    rows = results[(results.pad == pad) & (results.condition == COMBINED)]
    if len(rows) < 4:
        return _untestable(key, pad, cv, "needs the combined condition and at least 4 specimens")
    rho, p = _quiet(stats.spearmanr, rows["gmean"], rows["pred_mean"])
    if np.isnan(rho):
        return _untestable(key, pad, cv, "the predictions or the perceived roughness are constant")
    base = null[(null.pad == pad) & (null.condition == COMBINED)]
    null_rho = _quiet(stats.spearmanr, base["gmean"], base["pred_mean"])[0]
    return ClaimTest(key, pad, cv, rho, p,
                "test: Spearman over specimens, the reference included (statistic, p); holds: rho > 0; the training "
                "mean meets it when its own rho > 0", f"{len(rows)} specimens; {_null_rho_words(null_rho)}",
                holds=rho > 0, rests_on=[(pad, COMBINED)], null_meets=bool(null_rho > 0))


def _null_rho_words(null_rho: float) -> str:
    """The training mean's own rho, with why it is what it is: it is what the claim is judged against."""
    words = f"the training mean's own rho = {null_rho:.2f}"
    if null_rho <= -0.999:
        return (words + " (the mean of the other trials falls as the held-out specimen's roughness rises, so the "
                "training mean ranks every specimen backwards and cannot meet this claim)")
    return words + (" (so it meets this claim too)" if null_rho > 0 else " (so it does not meet this claim)")


def _beats_controls(controls, pad, cv):
    key = "beats_controls"
    row = controls[(controls.pad == pad) & (controls.cv == cv) & (controls.condition == COMBINED)]
    if row.empty or not row["n_permutations"].iloc[0]:
        return _untestable(key, pad, cv, "needs the combined condition and the permutation control")
    r = row.iloc[0]
    return ClaimTest(key, pad, cv, r["rmse"], r["permutation_p"],
                "the control the other claims rest on (so it rests on no other): test: permutation p; holds: CV RMSE "
                "(statistic) below the training mean's", f"CV RMSE {r['rmse']:.3f}, training mean {r['null_rmse']:.3f}, "
                f"shuffled median {r['permuted_rmse_median']:.3f} ({int(r['n_permutations'])} shufflings)",
                holds=bool(r["rmse"] < r["null_rmse"]))


def _ratings_rise(known: pd.DataFrame) -> ClaimTest:
    groups = [g for _, g in known.groupby("shape", sort=False) if len(g) >= 3]
    if not groups:
        return _untestable("ratings_rise", "", "none", "needs at least 3 specimens of a shape with a period")
    tests = [(g["shape"].iloc[0], *_quiet(stats.spearmanr, g["wavelength_mm"], g["gmean"])) for g in groups]
    worst = max(tests, key=lambda t: t[2])
    return ClaimTest("ratings_rise", "", "none", worst[1], _largest_p(t[2] for t in tests),
                "test: Spearman per shape (statistic, p: the weakest shape); holds: every shape's rho > 0",
                "; ".join(f"{s}: rho = {r:.2f}, p = {p:.2g}" for s, r, p in tests),
                holds=all(rho > 0 for _, rho, _ in tests),
                correction=f"none (intersection-union: each of the {len(tests)} shapes must reject)")


def _paper_geometry(known: pd.DataFrame, geometries: dict) -> pd.DataFrame:
    """The specimens of the paper's design: a rectangle only if half land (where the study has several rectangular
    geometries, analysis/geometry.py), so that the paper's claims compare what the paper compared."""
    if not geometries:
        return known
    geometry = known["specimen"].map(geometries)
    return known[(known["shape"] != "rectangular") | (geometry == PAPER_GEOMETRY)]


def _rating_claims(perceived: pd.DataFrame, shapes: dict, wavelengths: dict,
                   geometries: dict | None = None) -> list[ClaimTest]:
    people = perceived.assign(shape=perceived["specimen"].map(shapes),
                              wavelength_mm=perceived["specimen"].map(wavelengths))
    known = _paper_geometry(people.dropna(subset=["wavelength_mm"]), geometries or {})
    rows = [_ratings_rise(known)]
    circ = known[known["shape"] == "circular"].set_index("wavelength_mm")["gmean"]
    rect = known[known["shape"] == "rectangular"].set_index("wavelength_mm")["gmean"]
    common = circ.index.intersection(rect.index)
    if rect.index.duplicated().any():
        rows.append(_untestable("circular_rougher", "", "none",
                                "needs one rectangular grating per period (the paper's, half land: give "
                                "ridge_width_mm in specimens.csv)"))
    elif len(common) < 3:
        rows.append(_untestable("circular_rougher", "", "none",
                                "needs circular and rectangular gratings of at least 3 common periods"))
    else:
        test = signed_rank(circ.loc[common].to_numpy(), rect.loc[common].to_numpy())
        rows.append(ClaimTest("circular_rougher", "", "none", test.statistic, test.p,
                         "test: signed rank over periods; holds: the median difference circular - rectangular > 0",
                         f"{int((circ.loc[common] > rect.loc[common]).sum())} of {len(common)} periods",
                         holds=float(np.median(circ.loc[common] - rect.loc[common])) > 0))
    rated = people.dropna(subset=["sd"])
    if len(rated) < 4:
        rows.append(_untestable("human_sd_grows", "", "none", "needs at least 4 rated specimens"))
    else:
        rho, p = _quiet(stats.spearmanr, rated["gmean"], rated["sd"])
        rows.append(ClaimTest("human_sd_grows", "", "none", rho, p, "test: Spearman; holds: rho > 0",
                         f"{len(rated)} rated specimens", holds=rho > 0))
    return rows
