"""The report's first screen: the answer to the question users ask, in a few lines, before anything else.

Which model to use for a new surface, how wrong it is with a grating, a period and a shape left out of training
against the training mean, how often its 90 % interval held the panel's value, where it passes its controls, and
how far to trust it (whose images these are). Every number comes from the analysis's held-out summaries
(analysis/unseen.py, analysis/held_out.py), the same tables the report shows below, so the first screen and the
tables cannot disagree.
"""
from __future__ import annotations

import pandas as pd

from ..analysis.held_out import SCHEME_WORDS
from ..model.families import DEFAULT_MODEL, PAPER_MODEL
from ..paper import COMBINED
from .tables import jackknife_phrase, model_title


def answer_lines(analysis, unseen: pd.DataFrame | None = None) -> list[str]:
    """Three or four sentences: the model to use and its error, where it passes its controls, how far to trust it.

    ``unseen``: ``analysis.unseen_summary()`` if the caller holds it (a report reads it in four places)."""
    unseen = analysis.unseen_summary() if unseen is None else unseen
    if unseen.empty:
        return ["Not answered: leave-one-specimen-out was not run (--no-loso), so this report cannot say how well any "
                "model predicts a surface left out of training. The leave-one-out results below describe specimens "
                "seen in training."]
    passes = unseen["passes"].fillna(False).astype(bool)
    lines = [_use_line(unseen, passes), _passes_line(unseen, passes), _trust_line(analysis)]
    return [line for line in lines if line]


def _condition(unseen: pd.DataFrame) -> str:
    return COMBINED if (unseen["condition"] == COMBINED).any() else str(unseen["condition"].iloc[-1])


#: What the report and the console say when no family passes its controls for surfaces left out of training.
NO_MODEL = ("No model here passes its controls for surfaces left out of training: this study supports no roughness "
            "score for a new surface.")


def recommended_model(unseen: pd.DataFrame) -> str | None:
    """The family to use for surfaces left out of training: fit's default if it passes its controls in some pad x
    condition, else the first that does, else None. The one verdict the report's first screen and the console both
    state."""
    passes = unseen["passes"].fillna(False).astype(bool)
    passing = list(dict.fromkeys(unseen.loc[passes, "model"]))
    if not passing:
        return None
    return DEFAULT_MODEL if DEFAULT_MODEL in passing else passing[0]


def _use_line(unseen: pd.DataFrame, passes: pd.Series) -> str:
    """The model to use for new surfaces and, per pad, its error beside the training mean's and its coverage."""
    condition = _condition(unseen)
    model = recommended_model(unseen)
    if model is None:
        return NO_MODEL
    rows = unseen[(unseen["model"] == model) & (unseen["condition"] == condition) & passes]
    if rows.empty:  # it passes only in other conditions: quote those
        rows = unseen[(unseen["model"] == model) & passes].drop_duplicates("pad")
    per_pad = "; ".join(
        f"{r.pad} pad{'' if r.condition == condition else f' ({r.condition})'} {r.rmse:.2f} vs {r.null_rmse:.2f}" + (
            f", its 90 % interval held {r.pi90_coverage_trials:.0%} of held-out presses"
            if pd.notna(r.pi90_coverage_trials) else "")
        for r in rows.itertuples())
    default = ", what roughsense fit writes by default" if model == DEFAULT_MODEL else f", roughsense fit --model {model}"
    return (f"To score a new surface, use the {model_title(model)} ({model}{default}) on the pads and "
            f"conditions where it passes its controls (next line). Its error with a grating left out of training "
            f"({condition}, mean per-specimen RMSE vs the training mean's): {per_pad}. The table says how it does with "
            "a period or a shape left out.")


def answer_table(analysis, unseen: pd.DataFrame | None = None) -> dict | None:
    """The first screen's table: per model and held-out scheme (combined condition), each pad's mean per-specimen
    RMSE beside the training mean's and its verdict, and the nested jackknife+ surface interval where there is one.

    A verdict rests on the mean per-specimen RMSE *and* the controls: a model whose controls pass on the pooled RMSE
    while its mean per-specimen RMSE is not below the training mean's reads "pooled RMSE only", never "passes".
    """
    held = getattr(analysis, "held_out", None)
    if held is None or held.empty:
        return None
    condition = _condition(held)
    unseen = (analysis.unseen_summary() if unseen is None else unseen).set_index(["model", "pad", "condition"])
    presses = getattr(analysis, "presses", pd.DataFrame())
    unseen["presses_needed"] = [_presses_needed(presses, *key) for key in unseen.index]
    pads = list(dict.fromkeys(held["pad"]))
    rows = []
    for (model, scheme, part), group in held[held["condition"] == condition].groupby(
            ["model", "scheme", "held_out"], sort=False):
        words = SCHEME_WORDS[scheme] + ("" if part == "all" else f": {part}")
        cells = [model_title(model), words]
        for pad in pads:
            r = group[group["pad"] == pad]
            cells.append(_verdict_cell(r.iloc[0], unseen, model, pad, condition, scheme) if len(r) else "—")
        rows.append(cells)
    return {"columns": ["Model", "Held out", *[f"{pad} pad: RMSE vs training mean" for pad in pads]],
            "rows": rows, "condition": condition}


#: A shape left out is answered honestly when its bias stays within this (ratings) or the applicability check
#: flags at least SHAPE_FLAGGED_ENOUGH of its presses; otherwise its "passes" needs a warning beside it.
SHAPE_BIAS_LIMIT = 0.15
SHAPE_FLAGGED_ENOUGH = 0.8


def _verdict_cell(row, unseen: pd.DataFrame, model: str, pad: str, condition: str, scheme: str) -> str:
    below = row["rmse"] < row["null_rmse"]
    verdict = "fails" if not row["passes"] else "passes" if row["n_permutations"] else \
        "below the mean, not permutation-tested"
    if scheme == "shape":  # one direction: its bias, and how much of it the applicability check flags
        flagged = row.get("flagged_share")
        verdict += f", bias {row['bias']:+.2f}" + (f", {flagged:.0%} of presses flagged" if pd.notna(flagged) else "")
        unwarned = abs(row["bias"]) > SHAPE_BIAS_LIMIT and not (pd.notna(flagged) and flagged >= SHAPE_FLAGGED_ENOUGH)
        if unwarned and row["passes"]:  # a pass that would mislead: a failing row needs no second warning
            verdict += ": biased, mostly unflagged"
    if scheme == "specimen" and (model, pad, condition) in unseen.index:  # the controls' own verdict on LOSO
        control = unseen.loc[(model, pad, condition)]
        verdict = "passes" if control["passes"] and below else ("pooled RMSE only" if control["passes"] else "fails")
        held = jackknife_phrase(control.get("jackknife_plus_coverage", float("nan")),
                                control.get("jackknife_plus_median_factor", float("nan")))
        if held:
            verdict += f"; 90 % surface interval held {held}" if held[0].isdigit() else \
                "; no 90 % surface interval (too few specimens)"
        if pd.notna(control.get("presses_needed")):
            verdict += f"; needs {int(control['presses_needed'])} press(es) per surface"
    return f"{row['rmse']:.2f} vs {row['null_rmse']:.2f}, {verdict}"


def _presses_needed(presses: pd.DataFrame, model: str, pad: str, condition: str) -> float:
    """The presses a surface needs (analysis/presses.py), NaN where the study has no such curve."""
    from ..analysis.presses import presses_needed

    if presses is None or presses.empty:
        return float("nan")
    mine = presses[(presses["model"] == model) & (presses["pad"] == pad) & (presses["condition"] == condition)]
    needed = presses_needed(mine) if len(mine) else None
    return float("nan") if needed is None else float(needed)


def _passes_line(unseen: pd.DataFrame, passes: pd.Series) -> str:
    """Where each model passes its controls (training mean and shuffled targets), pad x condition. A pass whose mean
    per-specimen RMSE is not below the training mean's rests on the pooled RMSE alone and is counted apart."""
    parts = []
    for model, rows in unseen.groupby("model", sort=False):
        ok = passes[rows.index]
        pooled_only = ok & ~(rows["rmse"] < rows["null_rmse"])
        where = ", ".join(f"{r.pad} {r.condition}" for r in rows[~ok].itertuples())
        part = f"{model_title(model)} passes in {int((ok & ~pooled_only).sum())} of {len(rows)}" + (
            f" (not {where})" if where else "")
        if pooled_only.any():
            part += (", and in " + ", ".join(f"{r.pad} {r.condition}" for r in rows[pooled_only].itertuples())
                     + " on pooled RMSE only (its mean per-specimen RMSE is not below the training mean's)")
        parts.append(part)
    shuffled = " and better than specimen-shuffled targets" if unseen["n_permutations"].max() > 0 else \
        " (no shuffled targets: --permutations 0)"
    return (f"Which model passes its controls for new surfaces (below the training mean{shuffled}, nested "
            f"leave-one-specimen-out), per pad x condition: {'; '.join(parts)}. The paper's {PAPER_MODEL} is for "
            "reproducing the paper, not for new surfaces where it fails them.")


def _trust_line(analysis) -> str:
    """How far to trust the numbers: whose images and ratings these are."""
    if analysis.simulation is None and getattr(analysis, "synthetic", None):
        return (f"How far to trust it: the images are synthetic ({analysis.synthetic}), not measurements; the numbers "
                "illustrate the analysis, they are no finding about a real sensor.")
    if analysis.simulation is None:
        return ("How far to trust it: these are your images and ratings; the numbers are findings about them, for "
                "surfaces like the ones held out here.")
    seed = analysis.simulation.get("seed", "not recorded")
    return (f"How far to trust it: SIMULATED data (the digital twin, seed {seed}), not measurements. The numbers hold "
            "for the twin; a real rig confirms them only with real images and ratings of surfaces held out of training.")
