"""Surfaces never seen: how well each model predicts a specimen held out of training (nested LOSO), in one table.

This is the question a user of the sensor asks (what will it say about a new surface?), so the report and the
terminal summary lead with it. Every number comes from the LOSO fits and controls already computed; the only new
ones are the training mean's per-specimen RMSE (so the model and the null are compared on the same metric) and
Spearman's rho between each specimen's mean prediction and its perceived roughness; the empirical coverage of the 90 %
prediction interval on held-out specimens (of a press read alone: the peak law's nested jackknife+,
model/peak_law/folds.py; PLS's plain jackknife from the others' residuals, model/interval.py; of a surface: the
plain jackknife and the nested jackknife+);
and how often the applicability flag fell on a held-out specimen's trials (overall, and its worst specimen).
"""
from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
from scipy import stats

from ..model.interval import held_out_coverage
from ..model.registry import PAPER_MODEL
from ..paper import COMBINED
from .controls import fold_mean_predictions
from .results import Controls, CrossValidation, RunSettings, StudyFacts, UnseenSurfaces

UNSEEN_COLUMNS = ["model", "pad", "condition", "rmse", "null_rmse", "cv_rmse", "null_cv_rmse", "permutation_p",
                  "n_permutations", "passes", "spearman_rho", "spearman_p", "n_rated", "pi90_coverage_trials",
                  "pi90_coverage_specimens", "jackknife_plus_coverage", "jackknife_plus_median_factor",
                  "jackknife_plus_misses", "jackknife_plus_specimens", "jackknife_plus_missed", "flagged_share",
                  "flagged_max_share", "flagged_max_specimen"]


def headline_condition(conditions) -> str:
    """The condition every "surface left out" summary quotes: combined where it was analysed (every force's images
    together, what a user scores with), else the last one analysed."""
    conditions = list(conditions)
    return COMBINED if COMBINED in conditions else conditions[-1]


def null_specimen_rmse(predictions: pd.DataFrame, perceived: pd.DataFrame) -> pd.Series:
    """Per-specimen RMSE of the training mean under leave-one-specimen-out, by specimen.

    Every trial of a held-out specimen is predicted by the mean target of the other specimens' trials (the
    0-component model of PLS's LOSO, whose pooled RMSE is the controls' null_rmse); all its trials share one
    target, so its RMSE is the distance between that mean and its perceived value.
    """
    specimens = predictions["specimen"].to_numpy()
    target = predictions["specimen"].map(perceived.set_index("specimen")["gmean"]).to_numpy(dtype=float)
    distance = np.abs(fold_mean_predictions(target, specimens) - target)
    return pd.Series(distance, index=pd.Index(specimens, name="specimen")).groupby(level=0, sort=False).first()


def _spearman(table: pd.DataFrame, reference: str) -> tuple[float, float, int]:
    """rho and p between specimen-mean predictions and perceived roughness over the rated specimens."""
    rated = table[table["specimen"] != reference]
    if len(rated) < 3:
        return float("nan"), float("nan"), int(len(rated))
    with warnings.catch_warnings():  # constant input: NaN says it
        warnings.simplefilter("ignore")
        rho, p = stats.spearmanr(rated["pred_mean"], rated["gmean"])
    return float(rho), float(p), int(len(rated))


def _control(controls: pd.DataFrame, fit) -> dict:
    if controls is None or controls.empty:
        return {"permutation_p": float("nan"), "n_permutations": 0, "passes": None}
    model = controls.get("model", PAPER_MODEL)  # controls.csv before a second family had no model column
    rows = controls[(controls["pad"] == fit.pad) & (controls["condition"] == fit.condition) & (controls["cv"] == "loso")
                    & (model == fit.model)]
    if rows.empty:
        return {"permutation_p": float("nan"), "n_permutations": 0, "passes": None}
    row = rows.iloc[0]
    return {"permutation_p": float(row["permutation_p"]), "n_permutations": int(row["n_permutations"]),
            "passes": bool(row["passes"])}


def _coverage(fit, prediction: np.ndarray, target: np.ndarray, specimens: np.ndarray) -> dict:
    """Coverage of held-out presses and specimens by the plain jackknife; of presses, where the family has the
    fully nested check (the peak law), by the jackknife+ a press read alone gets, from models that never saw it."""
    trials, surfaces = held_out_coverage(prediction, target, specimens)
    check = getattr(fit, "interval_check", None)
    if check is not None and "press_covered" in check:  # an unbounded interval (too few specimens) covers nothing
        bounded = np.isfinite(check["press_log_halfwidth"]).all()
        trials = float(np.average(check["press_covered"], weights=check["press_readings"])) if bounded else np.nan
    return {"pi90_coverage_trials": trials, "pi90_coverage_specimens": surfaces}


def _jackknife_plus(fit) -> dict:
    """Coverage of the nested jackknife+ surface intervals, their median width (a factor: prediction x/÷ it) and
    the specimens they miss, with by how much; the specimens checked and the names of those missed, so a share is
    never quoted without its count (NaN, 0 and '' where the family has no such check)."""
    check = getattr(fit, "interval_check", None)
    if check is None or check.empty:
        return {"jackknife_plus_coverage": float("nan"), "jackknife_plus_median_factor": float("nan"),
                "jackknife_plus_misses": "", "jackknife_plus_specimens": 0, "jackknife_plus_missed": ""}
    misses = "; ".join(f"{r.specimen} {r.perceived:.2f} {'below' if r.perceived < r.pi90_low else 'above'} "
                       f"{r.pi90_low:.2f}-{r.pi90_high:.2f} (x{np.exp(r.miss_log):.2f} outside)"
                       for r in check[~check["covered"]].itertuples())
    return {"jackknife_plus_coverage": float(check["covered"].mean()),
            "jackknife_plus_median_factor": float(np.exp(check["log_halfwidth"].median())),
            "jackknife_plus_misses": misses, "jackknife_plus_specimens": int(len(check)),
            "jackknife_plus_missed": ", ".join(map(str, check.loc[~check["covered"], "specimen"]))}


def _flag_shares(fit) -> dict:
    flags = fit.held_out_flags
    if flags is None:
        return {"flagged_share": float("nan"), "flagged_max_share": float("nan"), "flagged_max_specimen": ""}
    shares = pd.Series(np.asarray(flags, dtype=float), index=fit.predictions["specimen"].to_numpy()).groupby(
        level=0, sort=False).mean()
    return {"flagged_share": float(np.mean(flags)), "flagged_max_share": float(shares.max()),
            "flagged_max_specimen": str(shares.idxmax())}


def unseen_summary(facts: StudyFacts, cross_validation: CrossValidation, controls: pd.DataFrame) -> pd.DataFrame:
    """One row per model x pad x condition of the nested LOSO fits (UNSEEN_COLUMNS), with their ``controls``
    (controls.csv); empty without LOSO.

    rmse / null_rmse: mean over specimens (the reference included) of the per-specimen RMSE of the model and of
    the training mean; cv_rmse / null_cv_rmse: the same pooled over trials (what the permutation test compares);
    spearman_*: over the rated specimens (the reference, 1 by definition, left out).
    """
    rows = []
    for fit in cross_validation.ordered_fits():
        if fit.cv != "loso":
            continue
        prediction = fit.predictions["prediction"].to_numpy(dtype=float)
        target = fit.predictions["specimen"].map(facts.perceived.set_index("specimen")["gmean"]).to_numpy(float)
        rho, p, n_rated = _spearman(fit.table, facts.reference_specimen)
        rows.append({
            "model": fit.model, "pad": fit.pad, "condition": fit.condition,
            "rmse": float(fit.table["rmse"].mean()),
            "null_rmse": float(null_specimen_rmse(fit.predictions, facts.perceived).mean()),
            "cv_rmse": float(np.sqrt(np.mean((prediction - target) ** 2))), "null_cv_rmse": float(fit.curve[0]),
            **_control(controls, fit), "spearman_rho": rho, "spearman_p": p, "n_rated": n_rated,
            **_coverage(fit, prediction, target, fit.predictions["specimen"].to_numpy()), **_jackknife_plus(fit),
            **_flag_shares(fit),
        })
    return pd.DataFrame(rows, columns=UNSEEN_COLUMNS)


UNSURE_COLUMNS = ["model", "pad", "condition", "specimen", "perceived", "prediction", "pi90_low", "pi90_high",
                  "covered", "missed_by", "flagged_share"]


def unsure_specimens(perceived: pd.DataFrame, cross_validation: CrossValidation, model: str, *,
                     per_pad: int = 5) -> pd.DataFrame:
    """The held-out specimens a model is least sure of, per pad (combined condition, or the last): those whose
    presses its applicability check flagged, then those its 90 % interval missed, then the widest intervals.

    Each specimen's interval is built as in the coverage check: the nested jackknife+ where the family has one
    (model/jackknife_plus.py), else from the other specimens' LOSO residuals only. ``missed_by``: the factor by
    which the perceived value lies outside its interval (NaN where covered).
    """
    from ..model.interval import held_out_floors, held_out_halfwidths, log_residuals

    fits = [f for f in cross_validation.ordered_fits() if f.cv == "loso" and f.model == model]
    if not fits:
        return pd.DataFrame(columns=UNSURE_COLUMNS)
    condition = headline_condition(dict.fromkeys(f.condition for f in fits))
    gmean = perceived.set_index("specimen")["gmean"]
    rows = []
    for fit in (f for f in fits if f.condition == condition):
        specimens = fit.predictions["specimen"].to_numpy()
        prediction = fit.predictions["prediction"].to_numpy(dtype=float)
        target = fit.predictions["specimen"].map(gmean).to_numpy(dtype=float)
        floors = held_out_floors(target, specimens)
        _, surface = log_residuals(prediction, target, specimens, floors)
        halfwidths = held_out_halfwidths(surface)
        flags = fit.held_out_flags if fit.held_out_flags is not None else np.zeros(len(specimens), dtype=bool)
        check = fit.interval_check.set_index("specimen") if fit.interval_check is not None else None
        for i, name in enumerate(pd.unique(pd.Series(specimens))):
            mine = specimens == name
            mean = float(np.maximum(prediction[mine], floors[mine]).mean())
            row = {"model": model, "pad": fit.pad, "condition": condition, "specimen": str(name),
                   "perceived": float(gmean[name]), "prediction": mean,
                   "pi90_low": mean * np.exp(-halfwidths[i]), "pi90_high": mean * np.exp(halfwidths[i]),
                   "covered": bool(abs(surface[i]) <= halfwidths[i]), "missed_by": np.exp(abs(surface[i]) - halfwidths[i]),
                   "flagged_share": float(np.mean(flags[mine]))}
            if check is not None:  # the jackknife+ interval, from models that never saw the specimen
                mine_check = check.loc[str(name)]
                row.update(pi90_low=float(mine_check["pi90_low"]), pi90_high=float(mine_check["pi90_high"]),
                           covered=bool(mine_check["covered"]), missed_by=float(np.exp(mine_check["miss_log"])))
            row["missed_by"] = float("nan") if row["covered"] else row["missed_by"]
            rows.append(row)
    table = pd.DataFrame(rows, columns=UNSURE_COLUMNS)
    table["width"] = table["pi90_high"] - table["pi90_low"]
    table = table.sort_values(["pad", "flagged_share", "covered", "width"], ascending=[True, False, True, False],
                              kind="stable")
    return table.groupby("pad", sort=False).head(per_pad).drop(columns="width").reset_index(drop=True)


def unseen_surfaces(facts: StudyFacts, run: RunSettings, cross_validation: CrossValidation,
                    controls: Controls) -> UnseenSurfaces:
    """The study's stage of surfaces never seen: the summary table, the condition it quotes, and the specimens the
    default family (else the first fitted) is least sure of."""
    models = cross_validation.models
    unsure_model = facts.fit_default if facts.fit_default in models else models[0]
    return UnseenSurfaces(unseen_summary(facts, cross_validation, controls.controls),
                          headline_condition(run.conditions),
                          unsure_specimens(facts.perceived, cross_validation, unsure_model))
