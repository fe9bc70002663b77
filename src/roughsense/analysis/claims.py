"""The paper's claims (Results, Discussion and Conclusions; Tables 1-6), each tested on a study's analysis.

Every claim is stated once, then judged per pad and CV scheme (LOO, the paper's protocol, and nested
leave-one-specimen-out) with our statistic and its p-value (after the claim's stated correction; NaN for a
descriptive claim, which has none). Claims about people's ratings do not depend on the sensor or the CV scheme and
are judged once (``cv = "none"``).

Every verdict comes from ONE rule, :func:`verdict`, applied to the evidence each row of claims.csv carries (the
models it rests on and whether they pass their controls, whether the training-mean model meets the claim too, the
equivalence margin and test of a claim of no difference), so a reader can recompute every verdict from the CSV and
disagree with a margin rather than with a hidden threshold. ``rule`` says what the claim's own test and statement are.

``basis`` separates findings from properties of a simulator: on a simulated study, a claim about the
ratings only checks what the simulator was given (by default its ratings for the paper's specimens are
drawn from the paper's Table 1), and the LOO error level was tuned to land in the paper's range.

The claims are about the paper's model, so only its fits and controls are judged (the registered family whose
``paper`` is true: PLS); other model families are reported beside them, never mixed into a verdict.
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

from ..model.families import family, registry
from ..paper import COMBINED, FINGERPRINT_PAD, FORCE_CONDITIONS, SMOOTH_PAD
from .controls import ALPHA, training_mean_predictions
from .metrics import compare_conditions, paired_tost, signed_rank, slope_tost, specimen_table

#: claims.csv: the original columns first, then (only added, never reordered) the evidence behind each verdict.
CLAIM_COLUMNS = ["claim", "pad", "cv", "statistic", "p", "verdict", "rule", "detail", "paper", "basis", "key",
                 "rests_on", "premise_passes", "failed_controls", "holds", "equivalence_margin", "equivalence_p",
                 "null_meets", "alpha", "correction"]
REPRODUCED, NOT_REPRODUCED, NOT_TESTABLE = "reproduced", "not reproduced", "not testable"
PREMISE_FAILED, NOT_EVIDENCE, UNDETERMINED = "premise failed", "not evidence", "undetermined"
VERDICTS = (REPRODUCED, NOT_REPRODUCED, UNDETERMINED, NOT_EVIDENCE, PREMISE_FAILED, NOT_TESTABLE)
#: The verdict rule in words, as the report and docs/controls.md state it (first match wins).
VERDICT_RULE = (
    "not testable: the study lacks what the claim needs.",
    "premise failed: a model the claim rests on fails its controls (controls.csv), whatever the claim's own test says.",
    "not evidence: the training-mean model, under the same CV, meets the claim too.",
    f"reproduced: its test rejects at alpha = {ALPHA} after its stated correction, and the claim holds; a claim of no "
    "difference or of flatness only by an equivalence test (TOST) within the margin shown.",
    "otherwise not reproduced (no rejection, the claim does not hold, or a difference beyond the margin) or "
    "undetermined (a claim of no difference, or one without a test, that the data cannot decide).",
)
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

CLAIMS = {
    "combined_beats_singles": "Combining the three forces lowers the per-specimen RMSE against each single force "
                              "(signed rank, Bonferroni x3)",
    "combined_lowest_mean": "The combined condition has the lowest mean RMSE of the four conditions",
    "smooth_beats_fingerprint": "The smooth pad predicts better than the fingerprint pad (combined RMSE, signed rank)",
    "rmse_below_sd": "RMSE is below the people's SD for most specimens (combined condition)",
    "ovl_same_across_forces": "OVL does not differ between the four force conditions (Friedman; equivalence: "
                              "paired TOST of every pair of conditions)",
    "ovl_pads_comparable": "Mean OVL is comparable between the pads (equivalence: paired TOST in every condition; "
                           "signed rank, Bonferroni x4)",
    "low_ovl_specimens": "R2, R2.5 and C5 have OVL below 0.5 in every condition",
    "sd_flat": "The prediction SD stays flat: it does not grow with perceived roughness (Spearman; equivalence: TOST "
               "of the log-log slope; combined condition)",
    "aligns": "Predicted roughness aligns with perceived roughness (Spearman over specimens, combined condition)",
    "beats_controls": "Predictions beat shuffled targets and the training mean (combined condition; "
                      "the premise of the conclusions)",
    "ratings_rise": "Perceived roughness rises with the period for each shape (Spearman)",
    "circular_rougher": "Circular gratings feel rougher than rectangular ones of the same period (signed rank)",
    "human_sd_grows": "The people's SD grows with perceived roughness, as Weber's law suggests (Spearman)",
}

PAPER_SAYS = {
    "combined_beats_singles": {FINGERPRINT_PAD: "W = 6, 14, 0; p = 0.0048, 0.00072 (adjusted), 0.00012",
                               SMOOTH_PAD: "stated without a test (Section 4)"},
    "combined_lowest_mean": {FINGERPRINT_PAD: "0.21 vs 0.26, 0.25, 0.25", SMOOTH_PAD: "0.13 vs 0.16, 0.18, 0.16"},
    "smooth_beats_fingerprint": {"both": "W = 6, p < 0.0017; 0.13 vs 0.21"},
    "rmse_below_sd": {FINGERPRINT_PAD: "combined RMSE 0.15-0.35 vs SD 0.12-0.64: 'most specimens'"},
    "ovl_same_across_forces": {FINGERPRINT_PAD: "0.56 in all four conditions"},
    "ovl_pads_comparable": {"both": "0.56 vs 0.59, 0.59, 0.55, 0.57 (Tables 2, 5)"},
    "low_ovl_specimens": {FINGERPRINT_PAD: "all 12 cells below 0.5 (Table 2)"},
    "sd_flat": {FINGERPRINT_PAD: "prediction SD about 0.2 for all sizes; people's SD grows (Fig. 9)"},
    "aligns": {"any": "'largely aligns with human subjective roughness' (Conclusions)"},
    "beats_controls": {"any": "not tested in the paper"},
    "ratings_rise": {"": "'larger ridge and groove sizes resulted in higher roughness ratings' (Table 1)"},
    "circular_rougher": {"": "'participants perceived rectangular specimens as less rough than circular' (Section 5)"},
    "human_sd_grows": {"": "'for larger specimens ... the SD of human responses also increases' (Section 5)"},
}

RATING_CLAIMS = ("ratings_rise", "circular_rougher", "human_sd_grows")


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


def verdict(evidence: Evidence) -> str:
    """The one verdict rule (VERDICT_RULE), applied in order: the first branch that matches decides."""
    e = evidence
    if not e.testable:
        return NOT_TESTABLE
    if not e.premise_passes:
        return PREMISE_FAILED
    if e.null_meets:
        return NOT_EVIDENCE
    if not math.isnan(e.equivalence_margin):
        if e.equivalence_p < e.alpha:
            return REPRODUCED
        # A significant difference beyond the margin is evidence against "no difference"; anything else cannot tell.
        return NOT_REPRODUCED if e.p < e.alpha and not e.holds else UNDETERMINED
    if not e.holds:
        return NOT_REPRODUCED
    if math.isnan(e.p):
        return UNDETERMINED
    return REPRODUCED if e.p < e.alpha else NOT_REPRODUCED


def _quiet(test, *args):
    """A scipy test with its warnings (constant input, tiny samples) silenced: a NaN result says it all."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return test(*args)


def _paper_text(key: str, pad: str) -> str:
    says = PAPER_SAYS.get(key, {})
    return says.get(pad) or says.get("any") or says.get("") or ""


@dataclass(frozen=True)
class ClaimTest:
    """One claim tested on one pad and CV scheme: its statistic and evidence, before its premise is looked up.

    Its verdict also needs the controls of the models it ``rests_on``; :func:`_claim_row` adds them.
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


def _rating_claims(perceived: pd.DataFrame, shapes: dict, wavelengths: dict) -> list[ClaimTest]:
    people = perceived.assign(shape=perceived["specimen"].map(shapes),
                              wavelength_mm=perceived["specimen"].map(wavelengths))
    known = people.dropna(subset=["wavelength_mm"])
    rows = [_ratings_rise(known)]
    circ = known[known["shape"] == "circular"].set_index("wavelength_mm")["gmean"]
    rect = known[known["shape"] == "rectangular"].set_index("wavelength_mm")["gmean"]
    common = circ.index.intersection(rect.index)
    if len(common) < 3:
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


def _failed_control(r) -> str:
    """Which control one model fails, in the controls table's own numbers."""
    why = []
    if not bool(r["beats_null"]):
        why.append(f"RMSE {r['rmse']:.3f} >= training mean {r['null_rmse']:.3f}")
    if r["beats_permutation"] is not None and not pd.isna(r["beats_permutation"]) and not bool(r["beats_permutation"]):
        why.append(f"shuffled targets p = {r['permutation_p']:.2g}")
    return f"{r['pad']} {r['condition']} {str(r['cv']).upper()} ({'; '.join(why)})"


def _claim_row(claim: ClaimTest, controls: pd.DataFrame, simulation: dict | None) -> dict:
    """The row of claims.csv: the premise of ``claim`` looked up in the controls, and its verdict by the one rule."""
    failed = []
    for pad, condition in claim.rests_on:
        hit = controls[(controls.pad == pad) & (controls.condition == condition) & (controls.cv == claim.cv)]
        if hit.empty:
            failed.append(f"{pad} {condition} {claim.cv.upper()} (no controls were run)")
        elif not bool(hit.iloc[0]["passes"]):
            failed.append(_failed_control(hit.iloc[0]))
    evidence = claim.evidence(premise_passes=not failed)
    return {"claim": CLAIMS[claim.key], "pad": claim.pad, "cv": claim.cv, "statistic": float(claim.statistic),
            "p": evidence.p, "verdict": verdict(evidence), "rule": claim.rule, "detail": claim.detail,
            "paper": _paper_text(claim.key, claim.pad), "basis": _basis(claim, simulation), "key": claim.key,
            "rests_on": "; ".join(f"{pad} {condition} {claim.cv}" for pad, condition in claim.rests_on),
            "premise_passes": evidence.premise_passes, "failed_controls": "; ".join(failed), "holds": evidence.holds,
            "equivalence_margin": evidence.equivalence_margin, "equivalence_p": evidence.equivalence_p,
            "null_meets": claim.null_meets, "alpha": evidence.alpha, "correction": claim.correction}


def _of_pls(frame: pd.DataFrame) -> pd.DataFrame:
    """The paper's model's rows (a frame without a model column is all the paper's)."""
    if frame is None or "model" not in frame.columns:
        return frame
    paper = [f.name for f in registry() if f.paper]
    return frame[frame["model"].isin(paper)].drop(columns="model").reset_index(drop=True)


def training_mean_results(analysis, cv: str) -> pd.DataFrame:
    """The per-specimen table (pad, condition, specimen, gmean, sd, pred_mean, pred_sd, ovl, rmse) of the model
    that predicts each training fold's mean, on the same trials and folds as the PLS fits of ``cv``.

    A claim the training mean also meets cannot tell a model from no model.
    """
    frames = []
    gmean = analysis.perceived.set_index("specimen")["gmean"]
    for fit in analysis.fits:
        if fit.cv != cv or not family(fit.model).paper:
            continue
        trials = fit.predictions[["specimen"]].copy()
        y = trials["specimen"].map(gmean).to_numpy(dtype=float)
        trials["prediction"] = training_mean_predictions(y, trials["specimen"].astype(str).to_numpy(), cv)
        # Every trial of a specimen gets the same prediction, so the SD is 0 under either ddof.
        table = specimen_table(trials, analysis.perceived, pred_sd_ddof=0)
        table.insert(0, "pad", fit.pad)
        table.insert(1, "condition", fit.condition)
        frames.append(table)
    columns = ["pad", "condition", "specimen", "gmean", "sd", "pred_mean", "pred_sd", "ovl", "rmse", "n_predictions"]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=columns)


def _basis(claim: ClaimTest, simulation: dict | None) -> str:
    if simulation is None:
        return "finding"
    if claim.key in RATING_CLAIMS:
        if simulation.get("ratings_from", "paper") == "paper":
            return "property of the simulator (its default ratings for the paper's specimens are drawn from Table 1)"
        return ("property of the simulator (its ratings come from its simulated finger, ratings_from = "
                f"{simulation.get('ratings_from')}: a model of people, not people)")
    if claim.key == "rmse_below_sd" and claim.cv == "loo":
        return "property of the simulator (its noise was tuned so LOO errors land in the paper's range)"
    return "finding on simulated data"


def _scheme_claims(analysis, cv: str, controls: pd.DataFrame) -> list[ClaimTest]:
    """Every sensor claim of one CV scheme, on the PLS fits and the training mean under the same folds."""
    pads = analysis.pads
    people = analysis.perceived[["specimen", "gmean", "sd"]]
    results = _of_pls(analysis.results(cv)).merge(people, on="specimen", how="left")
    null = training_mean_results(analysis, cv)
    rows = []
    for pad in pads:
        rows += [_combined_beats_singles(results, pad, cv), _combined_lowest_mean(results, pad, cv)]
    rows.append(_smooth_beats_fingerprint(results, pads, cv))
    for pad in pads:
        rows += [_rmse_below_sd(results, null, pad, cv), _ovl_same_across_forces(results, pad, cv)]
    rows.append(_ovl_pads_comparable(results, pads, cv))
    for pad in pads:
        rows += [_low_ovl_specimens(results, null, pad, cv), _sd_flat(results, pad, cv),
                 _aligns(results, null, pad, cv), _beats_controls(controls, pad, cv)]
    return rows


def evaluate_claims(analysis, wavelengths: dict | None = None) -> pd.DataFrame:
    """Every claim for every pad and CV scheme of ``analysis`` (a StudyAnalysis), as a table (CLAIM_COLUMNS).

    Of the paper's PLS model only: the other families' rows of the results and controls are left out.
    """
    schemes = [cv for cv in ("loo", "loso") if any(f.cv == cv and family(f.model).paper for f in analysis.fits)]
    controls = _of_pls(analysis.controls)
    if controls is None or controls.empty:
        controls = pd.DataFrame(columns=["pad", "condition", "cv", "passes"])
    tested = _rating_claims(analysis.perceived, analysis.shapes, wavelengths or analysis.wavelengths)
    for cv in schemes:
        tested += _scheme_claims(analysis, cv, controls)
    rows = [_claim_row(claim, controls, analysis.simulation) for claim in tested]
    order = {key: i for i, key in enumerate(CLAIMS)}
    frame = pd.DataFrame(rows)
    frame["_order"] = frame["key"].map(order)
    frame["_cv"] = frame["cv"].map({"none": 0, "loo": 1, "loso": 2})
    frame = frame.sort_values(["_order", "_cv"], kind="stable")
    return frame[CLAIM_COLUMNS].reset_index(drop=True)
