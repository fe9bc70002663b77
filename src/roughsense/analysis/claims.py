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

import pandas as pd

from ..model.registry import registry
from ..paper import FINGERPRINT_PAD, SMOOTH_PAD
from .claim_tests import (
    ClaimTest,
    Evidence,
    _aligns,
    _beats_controls,
    _combined_beats_singles,
    _combined_lowest_mean,
    _low_ovl_specimens,
    _ovl_pads_comparable,
    _ovl_same_across_forces,
    _rating_claims,
    _rmse_below_sd,
    _sd_flat,
    _smooth_beats_fingerprint,
)
from .controls import training_mean_results
from .metrics import ALPHA
from .results import CrossValidation, StudyFacts

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


def _paper_text(key: str, pad: str) -> str:
    says = PAPER_SAYS.get(key, {})
    return says.get(pad) or says.get("any") or says.get("") or ""


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


def _scheme_claims(perceived: pd.DataFrame, cross_validation: CrossValidation, paper_fits: list, cv: str,
                   controls: pd.DataFrame) -> list[ClaimTest]:
    """Every sensor claim of one CV scheme, on the PLS fits (``paper_fits``) and the training mean under the same
    folds."""
    pads = cross_validation.pads
    people = perceived[["specimen", "gmean", "sd"]]
    results = _of_pls(cross_validation.results(cv)).merge(people, on="specimen", how="left")
    null = training_mean_results(perceived, paper_fits, cv)
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


def evaluate_claims(facts: StudyFacts, cross_validation: CrossValidation, controls: pd.DataFrame) -> pd.DataFrame:
    """Every claim for every pad and CV scheme of a study's fits, as a table (CLAIM_COLUMNS): the ratings' claims from
    ``facts``, the sensor's from ``cross_validation`` with ``controls`` (controls.csv) as their premise.

    Of the paper's PLS model only: the other families' rows of the results and controls are left out.
    """
    paper = {f.name for f in registry() if f.paper}
    paper_fits = [f for f in cross_validation.fits if f.model in paper]
    schemes = [cv for cv in ("loo", "loso") if any(f.cv == cv for f in paper_fits)]
    controls = _of_pls(controls)
    if controls is None or controls.empty:
        controls = pd.DataFrame(columns=["pad", "condition", "cv", "passes"])
    tested = []
    for cv in schemes:
        tested += _scheme_claims(facts.perceived, cross_validation, paper_fits, cv, controls)
    # The ratings' claims last here; the table's rows are ordered by claim and scheme below.
    tested += _rating_claims(facts.perceived, facts.shapes, facts.wavelengths, facts.geometries)
    rows = [_claim_row(claim, controls, facts.provenance.settings) for claim in tested]
    order = {key: i for i, key in enumerate(CLAIMS)}
    frame = pd.DataFrame(rows)
    frame["_order"] = frame["key"].map(order)
    frame["_cv"] = frame["cv"].map({"none": 0, "loo": 1, "loso": 2})
    frame = frame.sort_values(["_order", "_cv"], kind="stable")
    return frame[CLAIM_COLUMNS].reset_index(drop=True)
