"""Report tables in the paper's layout, each of our values next to the paper's where it reports one.

A table is a plain dict (title, caption, columns, rows of cells); a cell is ``{"ours": str, "paper": str}``
so the template can show both without knowing what the numbers mean.
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .. import reference

CONDITION_TITLES = {"1N": "Dataset 1 N", "2N": "Dataset 2 N", "3N": "Dataset 3 N", "combined": "Dataset combination"}


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


def _paper_lookup() -> pd.DataFrame:
    return reference.paper_results().set_index(["pad", "specimen", "condition"])


def _paper_value(paper: pd.DataFrame, key: tuple, column: str):
    if key in paper.index:
        return paper.loc[key, column]
    return None


def prediction_table(results: pd.DataFrame, perceived: pd.DataFrame, pad: str, specimens: list[str],
                     cv: str = "loo") -> dict:
    """Tables 1/4: perceived and predicted roughness, mean ± SD (the paper's predictions only beside LOO)."""
    paper = _paper_lookup()
    paper_perceived = reference.perceived_roughness().set_index("specimen")
    conditions = list(dict.fromkeys(results["condition"]))
    ours = results[results.pad == pad].set_index(["specimen", "condition"])
    human = perceived.set_index("specimen")
    rows = []
    for specimen in specimens:
        row = [_cell(specimen)]
        h = human.loc[specimen] if specimen in human.index else None
        p = paper_perceived.loc[specimen] if specimen in paper_perceived.index else None
        row.append(_cell(_pm(h["gmean"], h["sd"]) if h is not None else "—",
                         _pm(p["perceived_gmean"], p["perceived_sd"]) if p is not None else None))
        for condition in conditions:
            key = (specimen, condition)
            value = _pm(ours.loc[key, "pred_mean"], ours.loc[key, "pred_sd"]) if key in ours.index else "—"
            pm = _paper_value(paper, (pad, specimen, condition), "pred_mean") if cv == "loo" else None
            ps = _paper_value(paper, (pad, specimen, condition), "pred_sd")
            row.append(_cell(value, _pm(pm, ps) if pm is not None else None))
        rows.append(row)
    caption = ("Perceived: geometric mean over participants of each participant's median over sessions ± the sample SD "
               "of those medians. Predicted: mean ± population SD of the specimen's out-of-fold predictions. ")
    caption += ("The paper's values (Tables 1 and 4) are beneath ours." if cv == "loo" else
                "The paper reports no leave-one-specimen-out results; only its perceived values are shown.")
    return {
        "title": f"Perceived and predicted roughness, {pad} pad, {cv.upper()} (mean ± SD)",
        "caption": caption,
        "columns": ["Specimen", "Perceived"] + [CONDITION_TITLES.get(c, c) for c in conditions],
        "rows": rows,
    }


def metric_table(results: pd.DataFrame, summary: pd.DataFrame, pad: str, specimens: list[str], column: str,
                 cv: str = "loo") -> dict:
    """Tables 2/5 (OVL) and 3/6 (RMSE) with the rectangular / circular / overall summary rows.

    Beside LOO results the paper's per-specimen values and its *printed* summary rows are shown
    (``reference.PAPER_SUMMARIES``), not summaries recomputed from its rounded per-specimen values.
    """
    paper = _paper_lookup()
    with_paper = cv == "loo"
    conditions = list(dict.fromkeys(results["condition"]))
    ours = results[results.pad == pad].set_index(["specimen", "condition"])
    rows = []
    for specimen in specimens:
        row = [_cell(specimen)]
        for condition in conditions:
            key = (specimen, condition)
            value = _num(ours.loc[key, column]) if key in ours.index else "—"
            pv = _paper_value(paper, (pad, specimen, condition), column) if with_paper else None
            row.append(_cell(value, _num(pv) if pv is not None else None))
        rows.append(row)
    order = {"rectangular": 0, "circular": 1, "all": 99}
    for group in sorted(summary["group"].drop_duplicates(), key=lambda g: (order.get(g, 50), g)):
        row = [_cell(f"{GROUP_TITLES.get(group, group.capitalize())}: mean ± SD")]
        for condition in conditions:
            s = summary[(summary.pad == pad) & (summary.condition == condition) & (summary.group == group)]
            value = _pm(s["mean"].iloc[0], s["sd"].iloc[0]) if len(s) else "—"
            printed = reference.PAPER_SUMMARIES.get((pad, column, condition, group)) if with_paper else None
            row.append(_cell(value, _pm(*printed) if printed else None))
        rows.append(row)
    name = {"ovl": "Overlap coefficient (OVL)", "rmse": "Root mean squared error (RMSE)"}[column]
    caption = "Per specimen, then mean ± sample SD over specimens. "
    if column == "ovl":
        caption += "OVL is undefined for the reference, which participants did not rate. "
    else:
        caption += "RMSE of the specimen's out-of-fold predictions against its perceived geometric mean. "
    caption += ("The paper's values are beneath ours; its summary rows are the ones it prints (Tables 3 and 6 print "
                "only the overall row)." if with_paper else "The paper reports no leave-one-specimen-out results.")
    return {
        "title": f"{name}, {pad} pad, {cv.upper()}",
        "caption": caption,
        "columns": ["Specimen"] + [CONDITION_TITLES.get(c, c) for c in conditions],
        "rows": rows,
    }


def components_table(chosen: pd.DataFrame, nested: dict | None = None) -> dict:
    """Chosen counts per pad and condition; ``nested`` maps (pad, condition) to the nested-LOSO counts."""
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
            paper_n = reference.PAPER_BEST_N_COMPONENTS.get((pad, condition)) if cv == "loo" else None
            paper_rmse = (reference.PAPER_FIG8_RMSE.get(paper_n) if cv == "loo" and (pad, condition) ==
                          ("fingerprint", "combined") else None)
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


def tests_table(tests: pd.DataFrame) -> dict:
    paper = reference.PAPER_TESTS
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


def headline_table(analysis) -> dict:
    """Mean per-specimen RMSE and OVL per pad x condition: LOO, LOSO and the paper's."""
    rows = []
    loo = analysis.results("loo")
    has_loso = any(f.cv == "loso" for f in analysis.fits)
    loso = analysis.results("loso") if has_loso else None
    for (pad, condition), g in loo.groupby(["pad", "condition"], sort=False):
        printed_rmse = reference.PAPER_SUMMARIES.get((pad, "rmse", condition, "all"))
        printed_ovl = reference.PAPER_SUMMARIES.get((pad, "ovl", condition, "all"))
        cells = [_cell(pad), _cell(condition),
                 _cell(_num(g["rmse"].mean()), _num(printed_rmse[0]) if printed_rmse else None),
                 _cell(_num(_quiet_nanmean(g["ovl"])), _num(printed_ovl[0]) if printed_ovl else None)]
        if loso is not None:
            h = loso[(loso.pad == pad) & (loso.condition == condition)]
            cells += [_cell(_num(h["rmse"].mean())), _cell(_num(_quiet_nanmean(h["ovl"])))]
        rows.append(cells)
    columns = ["Pad", "Condition", "LOO: mean RMSE", "LOO: mean OVL"]
    if loso is not None:
        columns += ["LOSO: mean RMSE", "LOSO: mean OVL"]
    return {
        "title": "At a glance",
        "caption": ("Mean over specimens of the per-specimen RMSE (all specimens, the reference included) and OVL "
                    "(the reference excluded: it has no rating spread). LOO is the paper's protocol (nine other images of "
                    "the held-out specimen stay in training); leave-one-specimen-out (LOSO) predicts a specimen never seen "
                    "in training (nested: the component count is chosen without it too) and is the honest estimate of generalisation. "
                    "The paper's printed LOO means are beneath ours."),
        "columns": columns,
        "rows": rows,
    }


def _quiet_nanmean(values) -> float:
    """Mean of the non-NaN values, NaN (without NumPy's RuntimeWarning on stderr) if there are none."""
    array = np.asarray(values, dtype=float)
    finite = array[~np.isnan(array)]
    return float(finite.mean()) if finite.size else float("nan")
