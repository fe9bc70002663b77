"""The report's tables of surfaces left out of training (nested LOSO, a period or a shape held out, the surfaces
the default model is least sure of) and of the paper's published predictions judged as predictive distributions.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from .. import paper as published
from .control_tables import _control_row, control_text, permutation_p_text
from .paper_tables import FLAG, _cell, _num, _pm, _quiet_nanmean, model_title


def unseen_table(unseen: pd.DataFrame, controls: pd.DataFrame) -> dict:
    """analysis.unseen as a table: nested LOSO error, the training mean's, the controls and Spearman's rho."""
    rows = []
    for _, r in unseen.iterrows():
        rho = "—" if pd.isna(r["spearman_rho"]) else f"{r['spearman_rho']:.2f} (n = {int(r['n_rated'])})"
        rows.append([_cell(model_title(r["model"])), _cell(r["pad"]), _cell(r["condition"]), _cell(_num(r["rmse"], 3)),
                     _cell(_num(r["null_rmse"], 3)), _cell(_num(r["cv_rmse"], 3)), _cell(_num(r["null_cv_rmse"], 3)),
                     _cell(permutation_p_text(r["permutation_p"], r["n_permutations"])),
                     _cell(control_text(_control_row(controls, r["pad"], r["condition"], "loso", r["model"]),
                                        mean_rmse=r["rmse"], null_mean_rmse=r["null_rmse"])),
                     _cell(rho), _cell(_coverage_text(r)), _cell(_jackknife_text(r)), _cell(_flag_text(r))])
    return {
        "title": "A grating left out of training: nested leave-one-specimen-out, per model, pad and condition",
        "caption": ("Every specimen is predicted by a model fitted without any of its images (PLS: its component count "
                    "chosen without it too). Mean RMSE: mean over specimens (the reference included) of the RMSE of the "
                    "specimen's predictions against its perceived roughness; training mean: the same for predicting the "
                    "training specimens' mean, the floor a useful model must beat. Pooled: the same errors over all "
                    "trials, which is what the controls compare (a few badly predicted specimens weigh more there, so "
                    "the two can rank a model and the training mean differently). Permutation p: the same "
                    "cross-validation on specimen-shuffled targets (see Controls). Spearman's rho: each rated specimen's "
                    "mean prediction against its perceived roughness (the reference, 1 by definition, left out). "
                    "90 % interval coverage: the share of held-out trials (and of specimens, by their mean prediction) "
                    "whose perceived roughness lies in the interval built from the other specimens' residuals (goal "
                    "85-95 %; those residuals' models saw the specimen; the peak law's trials: the jackknife+ of a press "
                    "read alone, fully nested, as predict gives it). Surface interval, jackknife+: the fully nested "
                    "check (every model behind a specimen's interval fitted without it), its median width as a factor "
                    "(prediction x/÷ it) and the specimens it misses, by what factor. Flagged: the share of held-out "
                    "trials the model's applicability check would have "
                    f"flagged, and its worst specimen. {FLAG} marks a model that fails its controls."),
        "columns": ["Model", "Pad", "Condition", "Mean RMSE", "Training mean RMSE", "Pooled RMSE",
                    "Training mean, pooled", "Permutation p", "Controls", "Spearman ρ",
                    "90 % interval coverage (trials / specimens)", "Surface interval, jackknife+ (nested)",
                    "Flagged when held out (worst specimen)"],
        "rows": rows,
    }


def jackknife_phrase(coverage: float, factor: float) -> str:
    """The jackknife+ surface interval's coverage and median width; too few specimens give it no finite width, and
    an interval of any width covers everything, so that is said instead of '100%, x/÷ inf' ('' without a check)."""
    if pd.isna(coverage):
        return ""
    if not np.isfinite(factor):
        return "none (too few specimens)"
    return f"{coverage:.0%}, x/÷ {factor:.2f}"


def _jackknife_text(row) -> str:
    text = jackknife_phrase(row.get("jackknife_plus_coverage", np.nan), row.get("jackknife_plus_median_factor", np.nan))
    misses = row["jackknife_plus_misses"] if text else ""
    return (text or "—") + (f"; misses {misses}" if isinstance(misses, str) and misses else "")


def _coverage_text(row) -> str:
    if pd.isna(row.get("pi90_coverage_trials", np.nan)):
        return "—"
    return f"{row['pi90_coverage_trials']:.0%} / {row['pi90_coverage_specimens']:.0%}"


def _flag_text(row) -> str:
    if pd.isna(row.get("flagged_share", np.nan)):
        return "—"
    return f"{row['flagged_share']:.0%} ({row['flagged_max_specimen']}: {row['flagged_max_share']:.0%})"


def paper_predictive_table(paper_predictive: pd.DataFrame) -> dict:
    """Mean OVL of the paper's published predictions: the paper's way and with the predictive distribution."""
    rows = []
    for (pad, condition), g in paper_predictive.groupby(["pad", "condition"], sort=False):
        printed = published.PAPER_SUMMARIES.get((pad, "ovl", condition, "all"))
        rows.append([_cell(pad), _cell(condition),
                     _cell(_num(_quiet_nanmean(g["ovl"])), _pm(*printed) if printed else None),
                     _cell(_num(_quiet_nanmean(g["ovl_predictive"]))),
                     _cell(f"{int((g['ovl_predictive'] >= 0.75).sum())} of {int(g['ovl_predictive'].notna().sum())}")])
    return {
        "title": "Predictive OVL of the paper's own published predictions (Tables 1 and 4)",
        "caption": ("Same published predictions (pred_mean ± pred_sd per specimen), judged two ways. Paper's OVL: "
                    "N(perceived mean, SD) against N(prediction mean, SD of the predictions), the mean of its per-specimen "
                    "values (its printed summary beneath). Predictive OVL: against the predictions widened by a Weber-like "
                    "spread of people's ratings, SD = k × mean, with k the pooled coefficient of variation of the other 12 "
                    "rated specimens (leave one specimen out), the sensor's own scatter kept. Nothing was tuned on the "
                    "specimen being judged."),
        "columns": ["Pad", "Condition", "Paper's OVL (mean)", "Predictive OVL (mean)", "Specimens with predictive OVL ≥ 0.75"],
        "rows": rows,
    }


def unsure_table(unsure: pd.DataFrame) -> dict:
    """analysis.unsure (unseen.unsure_specimens) as a table: the held-out surfaces the default model is least sure of."""
    rows = [[_cell(r.pad), _cell(r.specimen), _cell(f"{r.perceived:.2f}"), _cell(f"{r.prediction:.2f}"),
             _cell(f"{r.pi90_low:.2f}-{r.pi90_high:.2f}"),
             _cell("yes" if r.covered else f"no: x{r.missed_by:.2f} {'below' if r.perceived < r.pi90_low else 'above'}"),
             _cell(f"{r.flagged_share:.0%}")] for r in unsure.itertuples()]
    model = str(unsure["model"].iloc[0]) if len(unsure) else ""
    condition = str(unsure["condition"].iloc[0]) if len(unsure) else ""
    return {
        "title": f"Surfaces it is unsure of: {model_title(model)}, {condition}, each specimen held out",
        "caption": ("Per pad, the held-out specimens whose presses the model's applicability check flagged, then those "
                    "its 90 % interval missed, then the widest intervals. Prediction: the mean of the specimen's "
                    "held-out predictions; interval: the jackknife+ over the other specimens (models that never saw "
                    "it; PLS: from the other specimens' residuals); covered: if not, by what factor it lies outside; "
                    "flagged: the share of its presses the model fitted without it would have marked as outside what it was "
                    "trained on."),
        "columns": ["Pad", "Specimen", "Perceived", "Predicted", "90 % interval", "Covered", "Flagged presses"],
        "rows": rows,
    }


def held_out_table(held_out: pd.DataFrame, words: dict[str, str]) -> dict:
    """analysis.held_out as a table: each model under each held-out scheme (``words``: what each holds out)."""
    shape_columns = [c for c in held_out.columns if c.startswith("log_bias_")]
    rows = []
    for r in held_out.itertuples():
        passes = "passes" if r.passes else f"{FLAG} fails"
        if not r.n_permutations:
            passes += " (training mean only)"
        rows.append([_cell(model_title(r.model)), _cell(r.pad), _cell(r.condition),
                     _cell(f"{words.get(r.scheme, r.scheme)}" + (f": {r.held_out}" if r.held_out != "all" else
                                                                  f" ({r.n_folds} folds)")), _cell(_num(r.rmse, 3)),
                     _cell(_num(r.null_rmse, 3)), _cell(f"{r.bias:+.3f}"),
                     _cell("; ".join(f"{c.removeprefix('log_bias_')} {getattr(r, c):+.2f}" for c in shape_columns
                                     if pd.notna(getattr(r, c)))),
                     _cell(_num(r.spearman_rho, 2)), _cell(permutation_p_text(r.permutation_p, r.n_permutations)),
                     _cell(passes), _cell("—" if pd.isna(r.flagged_share) else f"{r.flagged_share:.0%}")])
    return {
        "title": "Held out of training: a grating, a period, a shape",
        "caption": ("Each model cross-validated three ways. A grating left out: one specimen at a time (the table above); "
                    "the other shape of its period stays in training. A period left out: both shapes of one period at a "
                    "time, so its period is new. A shape left out: fitted on one shape, it predicts every grating of the "
                    "other. Mean RMSE over specimens beside the training mean's under the same folds; bias: mean "
                    "prediction less perceived (rating units); log bias per shape: mean log(predicted / perceived) of "
                    "that shape's specimens (a model blind to shape shows one sign per shape); Spearman's rho over the "
                    "rated specimens; permutation p from the controls' specimen shufflings (PLS: LOSO only, its nested "
                    "search would double the controls); flagged: the share of held-out presses the applicability check "
                    "marks. Every design choice of the models was made on this study's specimens, so none of these "
                    "schemes is a fresh set of surfaces."),
        "columns": ["Model", "Pad", "Condition", "Held out", "Mean RMSE", "Training mean RMSE", "Bias",
                    "Log bias by shape", "Spearman ρ", "Permutation p", "Controls", "Flagged"],
        "rows": rows,
    }
