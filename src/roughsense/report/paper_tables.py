"""The paper's tables in its layout (Tables 1-6, its component counts and signed-rank tests), each of our values
next to the paper's where it reports one, and the cells every report table is made of.

A table is a plain dict (title, caption, columns, rows of cells); a cell is ``{"ours": str, "paper": str}``
so the template can show both without knowing what the numbers mean.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pandas as pd

from .. import paper as published
from ..model.registry import PAPER_MODEL, registry
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


def model_title(model: str) -> str:
    """How a model family is named in titles (the registry's title; a name it does not know, as it is)."""
    return {f.name: f.title for f in registry()}.get(model, model)


def is_paper_model(model: str) -> bool:
    """Whether ``model`` names the paper's family: its tables keep the paper's titles and stand beside its values."""
    return any(f.paper and f.name == model for f in registry())


def _titled(title: str, model: str) -> str:
    """A per-specimen table's title: the paper's for PLS, the same with the family's name for any other model."""
    return title if is_paper_model(model) else f"{title}, {model} model"


def _flagged_columns(conditions: list[str], flags: dict | None) -> list[str]:
    flags = flags or {}
    return [CONDITION_TITLES.get(c, c) + (f" {FLAG}" if c in flags else "") for c in conditions]


def _flag_caption(flags: dict | None) -> str:
    if not flags:
        return ""
    return (f" {FLAG} Fails its controls (no better than shuffled targets and/or the training mean; see Controls): "
            + "; ".join(f"{c}: {why}" for c, why in flags.items()) + ".")


def prediction_table(results: pd.DataFrame, perceived: pd.DataFrame, pad: str, specimens: list[str],
                     cv: str = "loo", *, paper_values: bool = True, flags: dict | None = None, model: str = PAPER_MODEL) -> dict:
    """Tables 1/4: perceived and predicted roughness, mean ± SD (the paper's predictions only beside LOO).

    ``paper_values=False`` leaves out every paper value (the study's design is not the paper's);
    ``flags`` maps a condition to why its model fails the controls (marked in the column heading); ``model``: the
    family of ``results`` (one only), named in the title unless it is the paper's PLS.
    """
    show_perceived = paper_values
    paper_values = paper_values and is_paper_model(model)  # the paper's predictions are its PLS's, beside ours only
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
    elif not is_paper_model(model):
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
                 cv: str = "loo", *, paper_values: bool = True, flags: dict | None = None, model: str = PAPER_MODEL) -> dict:
    """Tables 2/5 (OVL) and 3/6 (RMSE) with the rectangular / circular / overall summary rows; also ovl_predictive.

    Beside LOO results of the paper's PLS the paper's per-specimen values and its *printed* summary rows are shown
    (``published.PAPER_SUMMARIES``), not summaries recomputed from its rounded per-specimen values.
    """
    paper = _paper_lookup()
    with_paper = paper_values and cv == "loo" and column in ("ovl", "rmse") and is_paper_model(model)
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
    elif not is_paper_model(model):
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


def _quiet_nanmean(values) -> float:
    """Mean of the non-NaN values, NaN (without NumPy's RuntimeWarning on stderr) if there are none."""
    array = np.asarray(values, dtype=float)
    finite = array[~np.isnan(array)]
    return float(finite.mean()) if finite.size else float("nan")
