"""The paper's claims (Results, Discussion and Conclusions; Tables 1-6), each tested on a study's analysis.

Every claim is stated once, then judged per pad and CV scheme (LOO, the paper's protocol, and nested
leave-one-specimen-out) with our statistic, its p-value (NaN for a descriptive claim, which has none) and
a verdict: ``reproduced``, ``not reproduced`` or ``not testable`` (the study lacks what the claim needs,
e.g. a second pad or the paper's specimens). ``rule`` says what the verdict required, so a reader can
disagree with the threshold rather than with a hidden one. Claims about people's ratings do not depend on
the sensor or the CV scheme and are judged once (``cv = "none"``).

``basis`` separates findings from properties of a simulator: on a simulated study, a claim about the
ratings only checks what the simulator was given (by default its ratings for the paper's specimens are
drawn from the paper's Table 1), and the LOO error level was tuned to land in the paper's range.

The claims are about the paper's model, so only the PLS fits and their controls are judged (``model == "pls"``);
other model families are reported beside them, never mixed into a verdict.
"""
from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
from scipy import stats

from ..model.families import PLS
from ..paper import COMBINED, FORCE_CONDITIONS
from .controls import ALPHA
from .metrics import compare_conditions, signed_rank

CLAIM_COLUMNS = ["claim", "pad", "cv", "statistic", "p", "verdict", "rule", "detail", "paper", "basis", "key"]
REPRODUCED, NOT_REPRODUCED, NOT_TESTABLE = "reproduced", "not reproduced", "not testable"
VERDICTS = (REPRODUCED, NOT_REPRODUCED, NOT_TESTABLE)
#: Largest difference in mean OVL between the pads that still counts as "comparable" (the paper's
#: Tables 2 and 5 differ by at most 0.03 in any condition).
OVL_COMPARABLE = 0.05
#: Specimens the paper names as having OVL < 0.5 in every condition (Discussion).
LOW_OVL_SPECIMENS = ("R2", "R2.5", "C5")

CLAIMS = {
    "combined_beats_singles": "Combining the three forces lowers the per-specimen RMSE against each single force "
                              "(signed rank, Bonferroni x3)",
    "combined_lowest_mean": "The combined condition has the lowest mean RMSE of the four conditions",
    "smooth_beats_fingerprint": "The smooth pad predicts better than the fingerprint pad (combined RMSE, signed rank)",
    "rmse_below_sd": "RMSE is below the people's SD for most specimens (combined condition)",
    "ovl_same_across_forces": "OVL does not differ between the four force conditions (Friedman)",
    "ovl_pads_comparable": f"Mean OVL is comparable between the pads (every condition within {OVL_COMPARABLE}; "
                           "signed rank, Bonferroni x4)",
    "low_ovl_specimens": "R2, R2.5 and C5 have OVL below 0.5 in every condition",
    "sd_flat": "The prediction SD stays flat: it does not grow with perceived roughness (Spearman, combined condition)",
    "aligns": "Predicted roughness aligns with perceived roughness (Spearman over specimens, combined condition)",
    "beats_controls": "Predictions beat shuffled targets and the training mean (combined condition; "
                      "the premise of the conclusions)",
    "ratings_rise": "Perceived roughness rises with the period for each shape (Spearman)",
    "circular_rougher": "Circular gratings feel rougher than rectangular ones of the same period (signed rank)",
    "human_sd_grows": "The people's SD grows with perceived roughness, as Weber's law suggests (Spearman)",
}

PAPER_SAYS = {
    "combined_beats_singles": {"fingerprint": "W = 6, 14, 0; p = 0.0048, 0.00072 (adjusted), 0.00012",
                               "smooth": "stated without a test (Section 4)"},
    "combined_lowest_mean": {"fingerprint": "0.21 vs 0.26, 0.25, 0.25", "smooth": "0.13 vs 0.16, 0.18, 0.16"},
    "smooth_beats_fingerprint": {"both": "W = 6, p < 0.0017; 0.13 vs 0.21"},
    "rmse_below_sd": {"fingerprint": "combined RMSE 0.15-0.35 vs SD 0.12-0.64: 'most specimens'"},
    "ovl_same_across_forces": {"fingerprint": "0.56 in all four conditions"},
    "ovl_pads_comparable": {"both": "0.56 vs 0.59, 0.59, 0.55, 0.57 (Tables 2, 5)"},
    "low_ovl_specimens": {"fingerprint": "all 12 cells below 0.5 (Table 2)"},
    "sd_flat": {"fingerprint": "prediction SD about 0.2 for all sizes; people's SD grows (Fig. 9)"},
    "aligns": {"any": "'largely aligns with human subjective roughness' (Conclusions)"},
    "beats_controls": {"any": "not tested in the paper"},
    "ratings_rise": {"": "'larger ridge and groove sizes resulted in higher roughness ratings' (Table 1)"},
    "circular_rougher": {"": "'participants perceived rectangular specimens as less rough than circular' (Section 5)"},
    "human_sd_grows": {"": "'for larger specimens ... the SD of human responses also increases' (Section 5)"},
}

RATING_CLAIMS = ("ratings_rise", "circular_rougher", "human_sd_grows")


def _quiet(test, *args):
    """A scipy test with its warnings (constant input, tiny samples) silenced: a NaN result says it all."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return test(*args)


def _paper_text(key: str, pad: str) -> str:
    says = PAPER_SAYS.get(key, {})
    return says.get(pad) or says.get("any") or says.get("") or ""


def _row(key, pad, cv, statistic, p, verdict, rule, detail="") -> dict:
    return {"claim": CLAIMS[key], "pad": pad, "cv": cv, "statistic": float(statistic), "p": float(p),
            "verdict": verdict, "rule": rule, "detail": detail, "paper": _paper_text(key, pad), "key": key}


def _untestable(key, pad, cv, why) -> dict:
    return _row(key, pad, cv, np.nan, np.nan, NOT_TESTABLE, "", why)


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
    ok = lower and bool((table["p_adjusted"] < ALPHA).all())
    detail = "; ".join(f"{r.comparison}: W = {r.statistic:g}, adjusted p = {r.p_adjusted:.2g}" for r in table.itertuples())
    return _row(key, pad, cv, worst["statistic"], worst["p_adjusted"], REPRODUCED if ok else NOT_REPRODUCED,
                f"every adjusted p < {ALPHA} and the combined mean RMSE lower (statistic, p: the weakest comparison)",
                detail)


def _combined_lowest_mean(results, pad, cv):
    series = _by_condition(results, pad, "rmse")
    key = "combined_lowest_mean"
    if COMBINED not in series or not any(c in series for c in FORCE_CONDITIONS):
        return _untestable(key, pad, cv, "needs the combined condition and a single force")
    means = {c: float(s.mean()) for c, s in series.items()}
    margin = means[COMBINED] - min(v for c, v in means.items() if c != COMBINED)
    detail = ", ".join(f"{c} {v:.3f}" for c, v in means.items())
    return _row(key, pad, cv, margin, np.nan, REPRODUCED if margin < 0 else NOT_REPRODUCED,
                "descriptive: combined mean RMSE minus the lowest single-force mean is < 0 (statistic)", detail)


def _smooth_beats_fingerprint(results, pads, cv):
    key = "smooth_beats_fingerprint"
    if not {"smooth", "fingerprint"} <= set(pads):
        return _untestable(key, "both", cv, "needs both the smooth and the fingerprint pad")
    a = _by_condition(results, "smooth", "rmse").get(COMBINED)
    b = _by_condition(results, "fingerprint", "rmse").get(COMBINED)
    if a is None or b is None:
        return _untestable(key, "both", cv, "needs the combined condition")
    common = a.index.intersection(b.index)
    test = signed_rank(a.loc[common].to_numpy(), b.loc[common].to_numpy())
    ok = test.p < ALPHA and a.loc[common].mean() < b.loc[common].mean()
    return _row(key, "both", cv, test.statistic, test.p, REPRODUCED if ok else NOT_REPRODUCED,
                f"p < {ALPHA} and the smooth pad's mean RMSE lower",
                f"mean RMSE smooth {a.loc[common].mean():.3f}, fingerprint {b.loc[common].mean():.3f}")


def _rmse_below_sd(results, pad, cv):
    key = "rmse_below_sd"
    rows = results[(results.pad == pad) & (results.condition == COMBINED)].dropna(subset=["sd"])
    if rows.empty:
        return _untestable(key, pad, cv, "needs the combined condition and rated specimens")
    below = int((rows["rmse"] < rows["sd"]).sum())
    n = len(rows)
    p = stats.binomtest(below, n, 0.5, alternative="greater").pvalue
    return _row(key, pad, cv, below / n, p, REPRODUCED if below > n / 2 else NOT_REPRODUCED,
                "descriptive: more than half of the rated specimens have RMSE < SD (statistic: the share; "
                "p: one-sided sign test)", f"{below} of {n} specimens")


def _ovl_same_across_forces(results, pad, cv):
    key = "ovl_same_across_forces"
    series = _by_condition(results, pad, "ovl")
    if len(series) < 3:
        return _untestable(key, pad, cv, "needs at least three conditions")
    frame = pd.DataFrame(series).dropna()
    if len(frame) < 2:
        return _untestable(key, pad, cv, "needs at least 2 rated specimens")
    test = _quiet(stats.friedmanchisquare, *[frame[c].to_numpy() for c in frame.columns])
    return _row(key, pad, cv, test.statistic, test.pvalue, REPRODUCED if test.pvalue >= ALPHA else NOT_REPRODUCED,
                f"no difference detected: Friedman p >= {ALPHA} (absence of evidence, as the paper argues it)",
                ", ".join(f"{c} {frame[c].mean():.2f}" for c in frame.columns))


def _ovl_pads_comparable(results, pads, cv):
    key = "ovl_pads_comparable"
    if not {"smooth", "fingerprint"} <= set(pads):
        return _untestable(key, "both", cv, "needs both the smooth and the fingerprint pad")
    a, b = _by_condition(results, "smooth", "ovl"), _by_condition(results, "fingerprint", "ovl")
    conditions = [c for c in a if c in b]
    if not conditions:
        return _untestable(key, "both", cv, "the pads share no condition")
    diffs, ps = [], []
    for c in conditions:
        pair = pd.concat([a[c], b[c]], axis=1, join="inner").dropna()
        diffs.append(float(pair.iloc[:, 0].mean() - pair.iloc[:, 1].mean()))
        ps.append(min(1.0, signed_rank(pair.iloc[:, 0].to_numpy(), pair.iloc[:, 1].to_numpy()).p * len(conditions)))
    largest = float(np.max(np.abs(diffs)))
    ok = largest <= OVL_COMPARABLE and min(ps) >= ALPHA
    return _row(key, "both", cv, largest, min(ps), REPRODUCED if ok else NOT_REPRODUCED,
                f"largest |difference of mean OVL| <= {OVL_COMPARABLE} (statistic) and every adjusted p >= {ALPHA} "
                "(p: the smallest)", ", ".join(f"{c} {d:+.2f}" for c, d in zip(conditions, diffs)))


def _low_ovl_specimens(results, pad, cv):
    key = "low_ovl_specimens"
    rows = results[(results.pad == pad) & results.specimen.isin(LOW_OVL_SPECIMENS)]
    if set(rows["specimen"]) != set(LOW_OVL_SPECIMENS):
        return _untestable(key, pad, cv, f"needs the specimens {', '.join(LOW_OVL_SPECIMENS)}")
    below = int((rows["ovl"] < 0.5).sum())
    return _row(key, pad, cv, below / len(rows), np.nan, REPRODUCED if below == len(rows) else NOT_REPRODUCED,
                "descriptive: every one of these cells has OVL < 0.5 (statistic: the share)",
                f"{below} of {len(rows)} cells")


def _sd_flat(results, perceived, pad, cv):
    key = "sd_flat"
    rows = results[(results.pad == pad) & (results.condition == COMBINED)].dropna(subset=["sd"])
    if len(rows) < 4:
        return _untestable(key, pad, cv, "needs the combined condition and at least 4 rated specimens")
    rho, p = _quiet(stats.spearmanr, rows["gmean"], rows["pred_sd"])
    if np.isnan(rho):
        return _untestable(key, pad, cv, "the prediction SD or the perceived roughness is constant")
    grows = rho > 0 and p < ALPHA
    return _row(key, pad, cv, rho, p, NOT_REPRODUCED if grows else REPRODUCED,
                f"the prediction SD does not rise with perceived roughness (not: rho > 0 and p < {ALPHA})",
                f"mean prediction SD {rows['pred_sd'].mean():.2f}")


def _aligns(results, pad, cv):
    key = "aligns"
    rows = results[(results.pad == pad) & (results.condition == COMBINED)]
    if len(rows) < 4:
        return _untestable(key, pad, cv, "needs the combined condition and at least 4 specimens")
    rho, p = _quiet(stats.spearmanr, rows["gmean"], rows["pred_mean"])
    if np.isnan(rho):
        return _untestable(key, pad, cv, "the predictions or the perceived roughness are constant")
    return _row(key, pad, cv, rho, p, REPRODUCED if rho > 0 and p < ALPHA else NOT_REPRODUCED,
                f"rho > 0 and p < {ALPHA} (all specimens, the reference included)", f"{len(rows)} specimens")


def _beats_controls(controls, pad, cv):
    key = "beats_controls"
    row = controls[(controls.pad == pad) & (controls.cv == cv) & (controls.condition == COMBINED)]
    if row.empty or not row["n_permutations"].iloc[0]:
        return _untestable(key, pad, cv, "needs the combined condition and the permutation control")
    r = row.iloc[0]
    return _row(key, pad, cv, r["rmse"], r["permutation_p"], REPRODUCED if r["passes"] else NOT_REPRODUCED,
                f"permutation p < {ALPHA} and CV RMSE below the training mean's (statistic: CV RMSE)",
                f"CV RMSE {r['rmse']:.3f}, training mean {r['null_rmse']:.3f}, shuffled median "
                f"{r['permuted_rmse_median']:.3f} ({int(r['n_permutations'])} shufflings)")


def _rating_claims(perceived: pd.DataFrame, shapes: dict, wavelengths: dict) -> list[dict]:
    people = perceived.assign(shape=perceived["specimen"].map(shapes),
                              wavelength_mm=perceived["specimen"].map(wavelengths))
    rows = []
    known = people.dropna(subset=["wavelength_mm"])
    groups = [g for _, g in known.groupby("shape", sort=False) if len(g) >= 3]
    if not groups:
        rows.append(_untestable("ratings_rise", "", "none", "needs at least 3 specimens of a shape with a period"))
    else:
        tests = [(g["shape"].iloc[0], *_quiet(stats.spearmanr, g["wavelength_mm"], g["gmean"])) for g in groups]
        worst = max(tests, key=lambda t: t[2])
        ok = all(rho > 0 and p < ALPHA for _, rho, p in tests)
        rows.append(_row("ratings_rise", "", "none", worst[1], worst[2], REPRODUCED if ok else NOT_REPRODUCED,
                         f"every shape: rho > 0 and p < {ALPHA} (statistic, p: the weakest shape)",
                         "; ".join(f"{s}: rho = {r:.2f}, p = {p:.2g}" for s, r, p in tests)))
    circ = known[known["shape"] == "circular"].set_index("wavelength_mm")["gmean"]
    rect = known[known["shape"] == "rectangular"].set_index("wavelength_mm")["gmean"]
    common = circ.index.intersection(rect.index)
    if len(common) < 3:
        rows.append(_untestable("circular_rougher", "", "none",
                                "needs circular and rectangular gratings of at least 3 common periods"))
    else:
        test = signed_rank(circ.loc[common].to_numpy(), rect.loc[common].to_numpy())
        ok = test.p < ALPHA and float(np.median(circ.loc[common] - rect.loc[common])) > 0
        rows.append(_row("circular_rougher", "", "none", test.statistic, test.p, REPRODUCED if ok else NOT_REPRODUCED,
                         f"p < {ALPHA} and the median difference circular - rectangular > 0",
                         f"{int((circ.loc[common] > rect.loc[common]).sum())} of {len(common)} periods"))
    rated = people.dropna(subset=["sd"])
    if len(rated) < 4:
        rows.append(_untestable("human_sd_grows", "", "none", "needs at least 4 rated specimens"))
    else:
        rho, p = _quiet(stats.spearmanr, rated["gmean"], rated["sd"])
        rows.append(_row("human_sd_grows", "", "none", rho, p, REPRODUCED if rho > 0 and p < ALPHA else NOT_REPRODUCED,
                         f"rho > 0 and p < {ALPHA}", f"{len(rated)} rated specimens"))
    return rows


def _of_pls(frame: pd.DataFrame) -> pd.DataFrame:
    """The paper's model's rows (a frame without a model column is all PLS)."""
    if frame is None or "model" not in frame.columns:
        return frame
    return frame[frame["model"] == PLS].drop(columns="model").reset_index(drop=True)


def _basis(row: dict, simulation: dict | None) -> str:
    if simulation is None:
        return "finding"
    if row["key"] in RATING_CLAIMS:
        if simulation.get("ratings_from", "paper") == "paper":
            return "property of the simulator (its default ratings for the paper's specimens are drawn from Table 1)"
        return ("property of the simulator (its ratings come from its simulated finger, ratings_from = "
                f"{simulation.get('ratings_from')}: a model of people, not people)")
    if row["key"] == "rmse_below_sd" and row["cv"] == "loo":
        return "property of the simulator (its noise was tuned so LOO errors land in the paper's range)"
    return "finding on simulated data"


def evaluate_claims(analysis, wavelengths: dict | None = None) -> pd.DataFrame:
    """Every claim for every pad and CV scheme of ``analysis`` (a StudyAnalysis), as a table (CLAIM_COLUMNS).

    Of the paper's PLS model only: the other families' rows of the results and controls are left out.
    """
    rows: list[dict] = []
    pads = analysis.pads
    schemes = [cv for cv in ("loo", "loso") if any(f.cv == cv and f.model == PLS for f in analysis.fits)]
    rows += _rating_claims(analysis.perceived, analysis.shapes, wavelengths or analysis.wavelengths)
    controls = _of_pls(analysis.controls)
    for cv in schemes:
        people = analysis.perceived[["specimen", "gmean", "sd"]]
        results = _of_pls(analysis.results(cv)).merge(people, on="specimen", how="left")
        for pad in pads:
            rows.append(_combined_beats_singles(results, pad, cv))
            rows.append(_combined_lowest_mean(results, pad, cv))
        rows.append(_smooth_beats_fingerprint(results, pads, cv))
        for pad in pads:
            rows.append(_rmse_below_sd(results, pad, cv))
            rows.append(_ovl_same_across_forces(results, pad, cv))
        rows.append(_ovl_pads_comparable(results, pads, cv))
        for pad in pads:
            rows.append(_low_ovl_specimens(results, pad, cv))
            rows.append(_sd_flat(results, analysis.perceived, pad, cv))
            rows.append(_aligns(results, pad, cv))
            rows.append(_beats_controls(controls, pad, cv))
    for row in rows:
        row["basis"] = _basis(row, analysis.simulation)
    order = {key: i for i, key in enumerate(CLAIMS)}
    frame = pd.DataFrame(rows)
    frame["_order"] = frame["key"].map(order)
    frame["_cv"] = frame["cv"].map({"none": 0, "loo": 1, "loso": 2})
    frame = frame.sort_values(["_order", "_cv"], kind="stable")
    return frame[CLAIM_COLUMNS].reset_index(drop=True)

