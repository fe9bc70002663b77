"""The report's tables of the controls (training mean, specimen-shuffled targets) and what they decide: the
at-a-glance table, controls.csv and the paper's claims with their verdicts.

A control's words (``control_text``, ``permutation_p_text``) are built here once, for the tables, the first screen
and the console alike.
"""
from __future__ import annotations

import pandas as pd

from .. import defaults
from .. import paper as published
from ..model.registry import PAPER_MODEL
from ..paper import COMBINED
from .paper_tables import FLAG, _cell, _num, _quiet_nanmean, is_paper_model


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


def control_flags(controls: pd.DataFrame, pad: str, cv: str, model: str = PAPER_MODEL) -> dict:
    """Condition -> why the model fails its controls, for the pad, CV scheme and family (only failing ones)."""
    flags = {}
    if controls is None or controls.empty:
        return flags
    controls = _of_model(controls, model)
    for _, row in controls[(controls.pad == pad) & (controls.cv == cv)].iterrows():
        if not row["passes"] and (row["n_permutations"] or not row["beats_null"]):
            flags[row["condition"]] = control_text(row).lstrip(f"{FLAG} ")
    return flags


def _control_row(controls: pd.DataFrame, pad: str, condition: str, cv: str, model: str = PAPER_MODEL):
    if controls is None or controls.empty:
        return None
    controls = _of_model(controls, model)
    rows = controls[(controls.pad == pad) & (controls.condition == condition) & (controls.cv == cv)]
    return rows.iloc[0] if len(rows) else None


def headline_table(analysis, paper_pads=None, *, results: dict | None = None, unseen: pd.DataFrame | None = None) -> dict:
    """Mean per-specimen RMSE, OVL and predictive OVL per model x pad x condition, with the controls: LOO, LOSO.

    ``results`` (``{cv: analysis.results(cv)}``): what the caller holds already, so a report arranges each once;
    ``unseen``: ``analysis.unseen`` unless given."""
    rows = []
    has_loso = any(f.cv == "loso" for f in analysis.fits)
    results = results or {cv: analysis.results(cv) for cv in (("loo", "loso") if has_loso else ("loo",))}
    loo, loso = results["loo"], results.get("loso") if has_loso else None
    unseen = analysis.unseen if has_loso and unseen is None else unseen
    unseen = unseen.set_index(["model", "pad", "condition"]) if has_loso else None
    for (model, pad, condition), g in loo.groupby(["model", "pad", "condition"], sort=False):
        allowed = (paper_pads is None or pad in paper_pads) and is_paper_model(model)
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


def controls_report_table(controls: pd.DataFrame) -> dict:
    """controls.csv as a table: CV RMSE, the training mean's, the shuffled targets' and the permutation p."""
    rows = []
    for _, r in controls.iterrows():
        rows.append([_cell(r.get("model", PAPER_MODEL)), _cell(r["pad"]), _cell(r["condition"]), _cell(str(r["cv"]).upper()),
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
                    f"1/(n + 1), so p < 0.05 needs at least 20 (the default is {defaults.PERMUTATIONS}). The peak law faces "
                    "the same test with "
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
