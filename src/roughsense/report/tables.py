"""Report tables in the paper's layout, each of our values next to the paper's where it reports one.

A table is a plain dict (title, caption, columns, rows of cells); a cell is ``{"ours": str, "paper": str}``
so the template can show both without knowing what the numbers mean.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pandas as pd

from .. import paper as published
from ..model.families import PLS
from ..paper import COMBINED, FINGERPRINT_PAD

CONDITION_TITLES = {"1N": "Dataset 1 N", "2N": "Dataset 2 N", "3N": "Dataset 3 N", COMBINED: "Dataset combination"}


def _num(value, digits: int = 2) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "—"
    return f"{float(value):.{digits}f}"


def _pm(mean, sd, digits: int = 2) -> str:
    if mean is None or (isinstance(mean, float) and math.isnan(mean)):
        return "—"
    if sd is None or (isinstance(sd, float) and math.isnan(sd)):
        return _num(mean, digits)
    return f"{float(mean):.{digits}f} ± {float(sd):.{digits}f}"


GROUP_TITLES = {"rectangular": "Rectangular", "circular": "Circular", "all": "Overall"}


def _cell(ours: str, paper: str | None = None) -> dict:
    """A table cell; a paper value that is missing or NaN (the paper reports nothing there) is not shown."""
    if paper is not None and paper.strip() in ("", "—", "nan"):
        paper = None
    return {"ours": ours, "paper": paper}


@functools.cache
def _paper_lookup() -> dict[str, dict[tuple, float]]:
    """The paper's per-specimen values by column, then (pad, specimen, condition): read once, looked up per cell
    (``.loc`` per cell was most of a page's tables' time). Read only: every table shares it."""
    table = published.paper_results().set_index(["pad", "specimen", "condition"])
    return {column: table[column].to_dict() for column in table.columns}


def _paper_value(paper: dict[str, dict[tuple, float]], key: tuple, column: str):
    return paper[column].get(key)


OUT_OF_FOLD = ("Every prediction here is out of fold: it comes from a model that did not see that image (LOO) or "
               "that specimen (LOSO). The paper does not say whether its Tables 1-6 hold out-of-fold or in-sample "
               "predictions. ")
FLAG = "†"
#: How a model family is named in titles; the paper's PLS keeps the paper's titles unchanged.
MODEL_TITLES = {PLS: "PLS (the paper's model)", "peak-law": "peak law"}


def model_title(model: str) -> str:
    return MODEL_TITLES.get(model, model)


def _titled(title: str, model: str) -> str:
    """A per-specimen table's title: the paper's for PLS, the same with the family's name for any other model."""
    return title if model == PLS else f"{title}, {model} model"


def _flagged_columns(conditions: list[str], flags: dict | None) -> list[str]:
    flags = flags or {}
    return [CONDITION_TITLES.get(c, c) + (f" {FLAG}" if c in flags else "") for c in conditions]


def _flag_caption(flags: dict | None) -> str:
    if not flags:
        return ""
    return (f" {FLAG} Fails its controls (no better than shuffled targets and/or the training mean; see Controls): "
            + "; ".join(f"{c}: {why}" for c, why in flags.items()) + ".")


def prediction_table(results: pd.DataFrame, perceived: pd.DataFrame, pad: str, specimens: list[str],
                     cv: str = "loo", *, paper_values: bool = True, flags: dict | None = None, model: str = PLS) -> dict:
    """Tables 1/4: perceived and predicted roughness, mean ± SD (the paper's predictions only beside LOO).

    ``paper_values=False`` leaves out every paper value (the study's design is not the paper's);
    ``flags`` maps a condition to why its model fails the controls (marked in the column heading); ``model``: the
    family of ``results`` (one only), named in the title unless it is the paper's PLS.
    """
    show_perceived = paper_values
    paper_values = paper_values and model == PLS  # the paper's predictions are its PLS's, beside ours only
    paper = _paper_lookup()
    paper_perceived = published.perceived_roughness().set_index("specimen")
    conditions = list(dict.fromkeys(results["condition"]))
    ours = results[results.pad == pad].set_index(["specimen", "condition"])
    means, sds = ours["pred_mean"].to_dict(), ours["pred_sd"].to_dict()  # dict lookups: .loc per cell was slow
    human = perceived.set_index("specimen")
    rows = []
    for specimen in specimens:
        row = [_cell(specimen)]
        h = human.loc[specimen] if specimen in human.index else None
        p = paper_perceived.loc[specimen] if specimen in paper_perceived.index else None
        row.append(_cell(_pm(h["gmean"], h["sd"]) if h is not None else "—",
                         _pm(p["perceived_gmean"], p["perceived_sd"]) if p is not None and show_perceived else None))
        for condition in conditions:
            key = (specimen, condition)
            value = _pm(means[key], sds[key]) if key in means else "—"
            pm = _paper_value(paper, (pad, specimen, condition), "pred_mean") if cv == "loo" and paper_values else None
            ps = _paper_value(paper, (pad, specimen, condition), "pred_sd")
            row.append(_cell(value, _pm(pm, ps) if pm is not None else None))
        rows.append(row)
    caption = ("Perceived: geometric mean over participants of each participant's median over sessions ± the sample SD "
               "of those medians. Predicted: mean ± population SD of the specimen's out-of-fold predictions. ")
    caption += OUT_OF_FOLD
    if not show_perceived:
        caption += "The paper's values are not shown (see the note at the top)."
    elif model != PLS:
        caption += f"The paper has no {model} model; only its perceived values are shown."
    else:
        caption += ("The paper's values (Tables 1 and 4) are beneath ours." if cv == "loo" else
                    "The paper reports no leave-one-specimen-out results; only its perceived values are shown.")
    caption += _flag_caption(flags)
    return {
        "title": _titled(f"Perceived and predicted roughness, {pad} pad, {cv.upper()} (mean ± SD)", model),
        "caption": caption,
        "columns": ["Specimen", "Perceived"] + _flagged_columns(conditions, flags),
        "rows": rows,
    }


def metric_table(results: pd.DataFrame, summary: pd.DataFrame, pad: str, specimens: list[str], column: str,
                 cv: str = "loo", *, paper_values: bool = True, flags: dict | None = None, model: str = PLS) -> dict:
    """Tables 2/5 (OVL) and 3/6 (RMSE) with the rectangular / circular / overall summary rows; also ovl_predictive.

    Beside LOO results of the paper's PLS the paper's per-specimen values and its *printed* summary rows are shown
    (``published.PAPER_SUMMARIES``), not summaries recomputed from its rounded per-specimen values.
    """
    paper = _paper_lookup()
    with_paper = paper_values and cv == "loo" and column in ("ovl", "rmse") and model == PLS
    conditions = list(dict.fromkeys(results["condition"]))
    ours = results[results.pad == pad].set_index(["specimen", "condition"])[column].to_dict()
    rows = []
    for specimen in specimens:
        row = [_cell(specimen)]
        for condition in conditions:
            key = (specimen, condition)
            value = _num(ours[key]) if key in ours else "—"
            pv = _paper_value(paper, (pad, specimen, condition), column) if with_paper else None
            row.append(_cell(value, _num(pv) if pv is not None else None))
        rows.append(row)
    order = {"rectangular": 0, "circular": 1, "all": 99}
    mine = summary[summary.pad == pad].drop_duplicates(["condition", "group"])  # the first row of each, as before
    by_cell = dict(zip(zip(mine["condition"], mine["group"]), zip(mine["mean"], mine["sd"])))
    for group in sorted(summary["group"].drop_duplicates(), key=lambda g: (order.get(g, 50), g)):
        row = [_cell(f"{GROUP_TITLES.get(group, group.capitalize())}: mean ± SD")]
        for condition in conditions:
            cell = by_cell.get((condition, group))
            value = _pm(*cell) if cell is not None else "—"
            printed = published.PAPER_SUMMARIES.get((pad, column, condition, group)) if with_paper else None
            row.append(_cell(value, _pm(*printed) if printed else None))
        rows.append(row)
    name = {"ovl": "Overlap coefficient (OVL)", "rmse": "Root mean squared error (RMSE)",
            "ovl_predictive": "Predictive OVL"}[column]
    caption = "Per specimen, then mean ± sample SD over specimens. " + OUT_OF_FOLD
    if column == "ovl":
        caption += "OVL is undefined for the reference, which participants did not rate. "
    elif column == "ovl_predictive":
        caption += ("OVL of the predictive distribution of percepts (the predictions widened by the spread of people's "
                    "ratings, learnt from the other specimens; see Predictive distributions) with the people's. ")
    else:
        caption += "RMSE of the specimen's out-of-fold predictions against its perceived geometric mean. "
    if with_paper:
        caption += ("The paper's values are beneath ours; its summary rows are the ones it prints (Tables 3 and 6 print "
                    "only the overall row).")
    elif column == "ovl_predictive":
        caption += "The paper has no predictive OVL; the Predictive distributions section computes it for its predictions."
    elif model != PLS:
        caption += f"The paper has no {model} model."
    elif cv == "loo":
        caption += "The paper's values are not shown (see the note at the top)."
    else:
        caption += "The paper reports no leave-one-specimen-out results."
    caption += _flag_caption(flags)
    return {
        "title": _titled(f"{name}, {pad} pad, {cv.upper()}", model),
        "caption": caption,
        "columns": ["Specimen"] + _flagged_columns(conditions, flags),
        "rows": rows,
    }


def components_table(chosen: pd.DataFrame, nested: dict | None = None, paper_pads=None) -> dict:
    """Chosen counts per pad and condition; ``nested`` maps (pad, condition) to the nested-LOSO counts.

    ``paper_pads``: the pads whose paper values may be shown (None: all).
    """
    nested = nested or {}
    rows = []
    for (pad, condition), group in chosen.groupby(["pad", "condition"], sort=False):
        cells = [_cell(pad), _cell(condition)]
        for cv in ("loo", "loso"):
            g = group[group.cv == cv]
            if not len(g):
                cells += [_cell("—")] * 3
                continue
            best, one_se, rmse = g.iloc[0][["best_n_components", "one_se_n_components", "cv_rmse"]]
            allowed = paper_pads is None or pad in paper_pads
            paper_n = published.PAPER_BEST_N_COMPONENTS.get((pad, condition)) if cv == "loo" and allowed else None
            paper_rmse = (published.PAPER_FIG8_RMSE.get(paper_n) if cv == "loo" and (pad, condition) ==
                          (FINGERPRINT_PAD, COMBINED) else None)
            counts = sorted(nested.get((pad, condition), {}).values()) if cv == "loso" else []
            best_text = str(int(best)) + (f" (nested {counts[0]}–{counts[-1]})" if counts else "")
            cells.append(_cell(best_text, str(paper_n) if paper_n is not None else None))
            cells.append(_cell(str(int(one_se))))
            cells.append(_cell(f"{rmse:.4f}", f"{paper_rmse:.5f}" if paper_rmse is not None else None))
        rows.append(cells)
    return {
        "title": "Number of PLS components chosen by cross-validation",
        "caption": ("Argmin of the CV RMSE over 1..max (the paper's rule), the one-standard-error choice, and the CV RMSE at "
                    "the argmin. The paper's LOO choices (Section 4) and its Fig. 8 RMSE are beneath ours. LOSO predictions "
                    "are nested: each held-out specimen's count is chosen by LOSO over the other specimens only (the range "
                    "of those counts is in brackets); the plain LOSO argmin is what a model fitted to all specimens would use."),
        "columns": ["Pad", "Condition", "LOO: components", "LOO: 1-SE", "LOO: RMSE",
                    "LOSO: components", "LOSO: 1-SE", "LOSO: RMSE"],
        "rows": rows,
    }


def tests_table(tests: pd.DataFrame, paper_values: bool = True) -> dict:
    paper = published.PAPER_TESTS if paper_values else {}
    rows = []
    for _, t in tests.iterrows():
        comparison = str(t["comparison"])
        key = comparison
        paper_entry = paper.get(key) if t.get("cv", "loo") == "loo" else None
        paper_w = paper_p = paper_p_adjusted = None
        if paper_entry is not None:
            w, p, adjusted, relation = paper_entry
            printed = f"{'< ' if relation == '<' else ''}{p:.2g}"
            paper_w = f"{w:g}"
            if adjusted:
                paper_p_adjusted = printed
            else:
                paper_p = printed
        rows.append([
            _cell(str(t.get("cv", "loo")).upper()),
            _cell(comparison),
            _cell(f"{t['statistic']:g}", paper_w),
            _cell(f"{t['p']:.2g}", paper_p),
            _cell(f"{t['p_adjusted']:.2g}", paper_p_adjusted),
        ])
    return {
        "title": "Wilcoxon signed-rank tests on per-specimen RMSE",
        "caption": ("W is the sum of the ranks of positive differences (MATLAB signrank); p is exact for small n. "
                    "Combined vs single force: Bonferroni ×3 per pad. Smooth vs fingerprint: combined condition, as in the "
                    "paper. The paper's W and p are beneath ours, under p or adjusted p according to which one its "
                    "printed value is (recomputed from its Tables 3 and 6; docs/perception.md)."),
        "columns": ["CV", "Comparison", "W", "p", "p (adjusted)"],
        "rows": rows,
    }


def permutation_p_text(p, n_permutations, spec: str = ".3f", *, at_most: str = "≤") -> str:
    """A permutation p as a reader may quote it: never 0, and at its floor a bound naming the shufflings.

    With n shufflings p = (1 + shufflings as good) / (1 + n) is at least 1 / (n + 1); when none was as good the
    value says only that p is at most that ("≤ 0.005 (199 shufflings)"), not that it is 0.005 or 0.
    """
    if not n_permutations or pd.isna(p):
        return "—"
    floor = 1.0 / (int(n_permutations) + 1)
    if float(p) <= floor * (1 + 1e-9):
        return f"{at_most} {floor:.2g} ({int(n_permutations)} shufflings)"
    return f"{float(p):{spec}}"


def _p_phrase(row) -> str:
    """``p = 0.02`` or ``p ≤ 0.005, none of 199 shufflings as good``, for a row of controls.csv."""
    text = permutation_p_text(row["permutation_p"], row["n_permutations"], ".2g")
    if text.startswith("≤"):
        return f"p {text.split(' (')[0]}, none of {int(row['n_permutations'])} shufflings as good"
    return f"p = {text}"


def control_text(row, *, mean_rmse: float | None = None, null_mean_rmse: float | None = None) -> str:
    """'passes' or what the model fails, for a row of controls.csv.

    The controls compare pooled RMSE (over all trials), so the training mean quoted is the pooled one, named so;
    given the mean per-specimen RMSE of the model and of the training mean (a table showing those), a model that
    passes while its mean is not below the training mean's says so instead of reading a bare "passes".
    """
    if row is None:
        return "—"
    fails = []
    if not row["beats_null"]:
        fails.append(f"pooled RMSE {row['rmse']:.3f} not below the training mean's {row['null_rmse']:.3f}")
    if row["n_permutations"] and not row["beats_permutation"]:
        fails.append(f"no better than shuffled targets ({_p_phrase(row)})")
    if fails:
        return f"{FLAG} " + "; ".join(fails)
    text = "passes" + (f" ({_p_phrase(row)})" if row["n_permutations"] else " (training mean only; no permutations)")
    if mean_rmse is not None and null_mean_rmse is not None and mean_rmse >= null_mean_rmse:
        text += (f", on pooled RMSE only: its mean per-specimen RMSE {mean_rmse:.3f} is not below the training "
                 f"mean's {null_mean_rmse:.3f}")
    return text


def _of_model(controls: pd.DataFrame, model: str) -> pd.DataFrame:
    return controls[controls["model"] == model] if "model" in controls.columns else controls


def control_flags(controls: pd.DataFrame, pad: str, cv: str, model: str = PLS) -> dict:
    """Condition -> why the model fails its controls, for the pad, CV scheme and family (only failing ones)."""
    flags = {}
    if controls is None or controls.empty:
        return flags
    controls = _of_model(controls, model)
    for _, row in controls[(controls.pad == pad) & (controls.cv == cv)].iterrows():
        if not row["passes"] and (row["n_permutations"] or not row["beats_null"]):
            flags[row["condition"]] = control_text(row).lstrip(f"{FLAG} ")
    return flags


def _control_row(controls: pd.DataFrame, pad: str, condition: str, cv: str, model: str = PLS):
    if controls is None or controls.empty:
        return None
    controls = _of_model(controls, model)
    rows = controls[(controls.pad == pad) & (controls.condition == condition) & (controls.cv == cv)]
    return rows.iloc[0] if len(rows) else None


def headline_table(analysis, paper_pads=None, *, results: dict | None = None, unseen: pd.DataFrame | None = None) -> dict:
    """Mean per-specimen RMSE, OVL and predictive OVL per model x pad x condition, with the controls: LOO, LOSO.

    ``results`` (``{cv: analysis.results(cv)}``) and ``unseen`` (``analysis.unseen_summary()``): what the caller holds
    already, so a report computes each once."""
    rows = []
    has_loso = any(f.cv == "loso" for f in analysis.fits)
    results = results or {cv: analysis.results(cv) for cv in (("loo", "loso") if has_loso else ("loo",))}
    loo, loso = results["loo"], results.get("loso") if has_loso else None
    unseen = analysis.unseen_summary() if has_loso and unseen is None else unseen
    unseen = unseen.set_index(["model", "pad", "condition"]) if has_loso else None
    for (model, pad, condition), g in loo.groupby(["model", "pad", "condition"], sort=False):
        allowed = (paper_pads is None or pad in paper_pads) and model == PLS
        printed_rmse = published.PAPER_SUMMARIES.get((pad, "rmse", condition, "all")) if allowed else None
        printed_ovl = published.PAPER_SUMMARIES.get((pad, "ovl", condition, "all")) if allowed else None
        cells = [_cell(model), _cell(pad), _cell(condition),
                 _cell(_num(g["rmse"].mean()), _num(printed_rmse[0]) if printed_rmse else None),
                 _cell(_num(_quiet_nanmean(g["ovl"])), _num(printed_ovl[0]) if printed_ovl else None),
                 _cell(_num(_quiet_nanmean(g["ovl_predictive"]))),
                 _cell(control_text(_control_row(analysis.controls, pad, condition, "loo", model)))]
        if loso is not None:
            h = loso[(loso.model == model) & (loso.pad == pad) & (loso.condition == condition)]
            null = unseen["null_rmse"].get((model, pad, condition))
            cells += [_cell(_num(h["rmse"].mean())), _cell(_num(_quiet_nanmean(h["ovl"]))),
                      _cell(_num(_quiet_nanmean(h["ovl_predictive"]))),
                      _cell(control_text(_control_row(analysis.controls, pad, condition, "loso", model),
                                         mean_rmse=float(h["rmse"].mean()), null_mean_rmse=null))]
        rows.append(cells)
    columns = ["Model", "Pad", "Condition", "LOO: mean RMSE", "LOO: mean OVL", "LOO: mean predictive OVL",
               "LOO: controls"]
    if loso is not None:
        columns += ["LOSO: mean RMSE", "LOSO: mean OVL", "LOSO: mean predictive OVL", "LOSO: controls"]
    return {
        "title": "At a glance",
        "caption": ("Mean over specimens of the per-specimen RMSE (all specimens, the reference included), OVL and "
                    "predictive OVL (the reference excluded: it has no rating spread). LOO is the paper's protocol (the "
                    "other images of the held-out specimen stay in training, so it rewards recognising a specimen); "
                    "leave-one-specimen-out (LOSO) predicts a grating left out of training (nested: the component "
                    "count is chosen without it too) and is the honest estimate of generalisation. Controls: whether the "
                    f"model's CV RMSE beats the training mean and specimen-shuffled targets (p < 0.05); {FLAG} marks a "
                    "model that does not. The paper's printed LOO means are beneath ours (PLS rows) where its design "
                    "matches."),
        "columns": columns,
        "rows": rows,
    }


def unseen_table(unseen: pd.DataFrame, controls: pd.DataFrame) -> dict:
    """analysis.unseen_summary() as a table: nested LOSO error, the training mean's, the controls and Spearman's rho."""
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


def _quiet_nanmean(values) -> float:
    """Mean of the non-NaN values, NaN (without NumPy's RuntimeWarning on stderr) if there are none."""
    array = np.asarray(values, dtype=float)
    finite = array[~np.isnan(array)]
    return float(finite.mean()) if finite.size else float("nan")


def controls_report_table(controls: pd.DataFrame) -> dict:
    """controls.csv as a table: CV RMSE, the training mean's, the shuffled targets' and the permutation p."""
    rows = []
    for _, r in controls.iterrows():
        rows.append([_cell(r.get("model", PLS)), _cell(r["pad"]), _cell(r["condition"]), _cell(str(r["cv"]).upper()),
                     _cell(f"{r['rmse']:.3f}"),
                     _cell(f"{r['null_rmse']:.3f}"),
                     _cell(f"{r['permuted_rmse_median']:.3f}" if r["n_permutations"] else "—"),
                     _cell(permutation_p_text(r["permutation_p"], r["n_permutations"])),
                     _cell(str(int(r["n_permutations"]))), _cell(control_text(r))])
    return {
        "title": "Controls: training mean and specimen-shuffled targets",
        "caption": ("CV RMSE over all trials of the out-of-fold predictions (LOO at the count the CV chose; LOSO nested). "
                    "Training mean: the RMSE of predicting each training fold's mean under the same folds. Shuffled: the "
                    "perceived values are permuted across specimens (every repetition of a specimen keeps one shared, "
                    "wrong value; drawn from numpy's default_rng(--seed), the seed column of controls.csv) and the "
                    "whole CV, the choice of the number of components included, is rerun; p = "
                    "(1 + shufflings at least as good) / (1 + shufflings). A LOO model that does no better on shuffled "
                    "targets is recognising specimens, not reading roughness. With n shufflings the smallest attainable p is "
                    "1/(n + 1), so p < 0.05 needs at least 20 (the default is 199). The peak law faces the same test with "
                    "the same shufflings (it chooses nothing from the targets, so its fit on each fold is all that is "
                    "rerun)."),
        "columns": ["Model", "Pad", "Condition", "CV", "CV RMSE", "Training mean RMSE", "Shuffled: median RMSE",
                    "Permutation p", "Shufflings", "Verdict"],
        "rows": rows,
    }


def _verdict_text(c) -> str:
    """The verdict, with what decided it where a reader would ask: the failed control, the training mean."""
    if c["verdict"] == "premise failed" and isinstance(c.get("failed_controls"), str) and c["failed_controls"]:
        return f"premise failed: fails its controls: {c['failed_controls']}"
    if c["verdict"] == "not evidence":
        return "not evidence: the training mean meets it too"
    return str(c["verdict"])


def _claim_p(c, controls: pd.DataFrame | None) -> str:
    """A claim's p as printed: a permutation p through :func:`permutation_p_text`, a p that underflowed to 0 as a bound."""
    if pd.isna(c["p"]):
        return "—"
    if c.get("key") == "beats_controls" and controls is not None:
        row = _control_row(controls, c["pad"], COMBINED, c["cv"])
        if row is not None:
            return permutation_p_text(row["permutation_p"], row["n_permutations"], ".2g")
    return "< 0.0001" if c["p"] == 0 else f"{c['p']:.2g}"


def claims_table(claims: pd.DataFrame, paper_pads=None, controls: pd.DataFrame | None = None) -> dict:
    """claims.csv as a table: each claim once per pad and CV scheme, our statistic, p, margin and verdict.

    The paper's own figure for a claim is shown only where the study's design is the paper's (``paper_pads``:
    the pads that qualify; None: all).
    ``controls``: controls.csv, to print the permutation claim's p with its shufflings.
    """
    rows = []
    for _, c in claims.iterrows():
        pads = {"both": set(published.PAPER_PADS), "": set()}.get(c["pad"], {c["pad"]})
        allowed = paper_pads is None or (bool(paper_pads) and pads <= set(paper_pads))
        p = _claim_p(c, controls)
        statistic = "—" if pd.isna(c["statistic"]) else f"{c['statistic']:.3g}"
        margin = c.get("equivalence_margin", float("nan"))
        tost = "—" if pd.isna(margin) else f"±{margin:.3g}" + (
            "" if pd.isna(c["equivalence_p"]) else f" (TOST p {c['equivalence_p']:.2g})")
        rows.append([_cell(c["claim"]), _cell(c["pad"] or "—"), _cell(str(c["cv"]).upper() if c["cv"] != "none" else "—"),
                     _cell(statistic), _cell(p), _cell(tost), _cell(_verdict_text(c)),
                     _cell(c["detail"] or "", (c["paper"] or None) if allowed else None),
                     _cell(c["basis"])])
    return {
        "title": "The paper's claims, checked",
        "caption": ("Each claim of the paper's Results, Discussion and Conclusions (Tables 1-6), tested on this study "
                    "under LOO (the paper's protocol) and nested LOSO, on the paper's PLS model. p is after the claim's "
                    "stated correction (claims.csv: correction); descriptive claims have no p. Equivalence: the margin "
                    "a claim of no difference or of flatness must be shown to lie within (TOST p). The verdict follows "
                    "the rule above; claims.csv holds every column it reads (rests_on, premise_passes, failed_controls, "
                    "holds, equivalence_margin, equivalence_p, null_meets, alpha). The paper's own figure is beneath the "
                    "detail. Basis: whether a result is a finding or a property the simulator was given."),
        "columns": ["Claim", "Pad", "CV", "Statistic", "p", "Equivalence", "Verdict", "Detail", "Basis"],
        "rows": rows,
        "css": "text",
    }


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
    """analysis.unseen.unsure_specimens() as a table: the held-out surfaces the default model is least sure of."""
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
