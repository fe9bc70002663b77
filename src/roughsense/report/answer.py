"""The report's first screen and the console's summary: the answer to the question users ask, in a few lines.

Which model to use for a new surface, how wrong it is with a grating, a period and a shape left out of training
against the training mean, how often its 90 % interval held the panel's value, where it passes its controls, and
how far to trust it (whose images these are). Every number comes from the analysis's held-out summaries
(analysis/unseen.py, analysis/held_out.py), the same tables the report shows below, so the first screen, the
console and the tables cannot disagree.
"""
from __future__ import annotations

import math

import pandas as pd

from .._util.text import counted
from ..analysis.held_out import PER_GROUP_SCHEMES, SCHEME_WORDS
from ..model.registry import DEFAULT_MODEL, PAPER_MODEL, names
from ..paper import press_meaning
from . import provenance as source
from .control_tables import permutation_p_text
from .paper_tables import is_paper_model, model_title
from .unseen_tables import jackknife_phrase


def answer_lines(analysis) -> list[str]:
    """Three or four sentences: the model to use and its error, where it passes its controls, how far to trust it
    (and which surfaces the evidence covers: ``analysis.evidence``, from the study's specimens)."""
    unseen = analysis.unseen
    if unseen.empty:
        return [source.NO_LOSO_ANSWER]
    passes = unseen["passes"].fillna(False).astype(bool)
    lines = [_use_line(unseen, passes, analysis.headline_condition, analysis.fit_default), _passes_line(unseen, passes),
             source.trust_line(analysis.provenance) + evidence_sentence(analysis)]
    return [line for line in lines if line]


def evidence_sentence(analysis) -> str:
    """' The evidence covers surfaces like ...' (``analysis.evidence``, from the study's rated specimens; '' where
    there is none): one wording for the first screen, the console and the section on surfaces held out."""
    return f" The evidence covers surfaces like {analysis.evidence}." if analysis.evidence else ""


#: What the report and the console say when no family passes its controls for surfaces left out of training.
NO_MODEL = ("No model here passes its controls for surfaces left out of training: this study supports no roughness "
            "score for a new surface.")


def recommended_model(unseen: pd.DataFrame, default: str = DEFAULT_MODEL) -> str | None:
    """The family to use for surfaces left out of training: fit's ``default`` on this study (``fit_default``) if it
    passes its controls in some pad x condition, else the first that does, else None. The one verdict the report's
    first screen and the console both state."""
    passes = unseen["passes"].fillna(False).astype(bool)
    passing = list(dict.fromkeys(unseen.loc[passes, "model"]))
    if not passing:
        return None
    return default if default in passing else passing[0]


def _use_line(unseen: pd.DataFrame, passes: pd.Series, condition: str, default: str = DEFAULT_MODEL) -> str:
    """The model to use for new surfaces and, per pad, its error beside the training mean's and its coverage, quoted
    at the headline ``condition`` (what a press is there, where it is no single image)."""
    model = recommended_model(unseen, default)
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
    how = ", what roughsense fit writes by default" if model == default else f", roughsense fit --model {model}"
    meaning = press_meaning(condition)
    return (f"To score a new surface, use the {model_title(model)} ({model}{how}) on the pads and "
            f"conditions where it passes its controls (next line). Its error with a grating left out of training "
            f"({condition}{f', where {meaning}' if meaning else ''}; mean per-specimen RMSE vs the training mean's): "
            f"{per_pad}. The table says how it does with a period or a shape left out.")


def first_screen_models(unseen: pd.DataFrame, default: str = DEFAULT_MODEL) -> tuple[str, ...]:
    """The families the first screen's table compares, in the registry's order: the paper's, fit's default and the
    one it recommends (:func:`recommended_model`): the choice a reader makes. Every family's rows are in the
    held-out table below, so the first screen stays one screen however many families are registered."""
    wanted = {PAPER_MODEL, default, recommended_model(unseen, default)} if not unseen.empty else {PAPER_MODEL,
                                                                                                  default}
    return tuple(name for name in names() if name in wanted)


def answer_table(analysis) -> dict | None:
    """The first screen's table: per model (:func:`first_screen_models`) and held-out scheme (combined condition),
    each pad's mean per-specimen RMSE beside the training mean's and its verdict, and the nested jackknife+ surface
    interval where there is one.

    A verdict rests on the mean per-specimen RMSE *and* the controls: a model whose controls pass on the pooled RMSE
    while its mean per-specimen RMSE is not below the training mean's reads "pooled RMSE only", never "passes".
    """
    held = getattr(analysis, "held_out", None)
    if held is None or held.empty:
        return None
    condition = analysis.headline_condition
    unseen = analysis.unseen.set_index(["model", "pad", "condition"])
    needed = [analysis.presses_needed.get(tuple(map(str, key))) for key in unseen.index]
    unseen["presses_needed"] = [float("nan") if n is None else float(n) for n in needed]
    pads = list(dict.fromkeys(held["pad"]))
    shown = first_screen_models(analysis.unseen, analysis.fit_default)
    # The paper's model, when it is not the one to use, keeps its one row of a grating left out: its stricter schemes
    # are in the held-out table below, and the first screen stays one screen with the geometry scheme's rows.
    chosen = {analysis.fit_default, recommended_model(analysis.unseen, analysis.fit_default)}
    rows = []
    for (model, scheme, part), group in held[held["condition"].eq(condition) & held["model"].isin(shown)].groupby(
            ["model", "scheme", "held_out"], sort=False):
        if model == PAPER_MODEL and model not in chosen and scheme != "specimen":
            continue
        words = SCHEME_WORDS[scheme] + ("" if part == "all" else f": {part}")
        cells = [model_title(model), words]
        for pad in pads:
            r = group[group["pad"] == pad]
            cells.append(_verdict_cell(r.iloc[0], unseen, model, pad, condition, scheme) if len(r) else "—")
        rows.append(cells)
    if getattr(analysis, "geometry_note", ""):  # the scheme the study cannot form, said beside the others
        rows.append(["every model", SCHEME_WORDS["geometry"], f"not applicable: {analysis.geometry_note}",
                     *["not applicable"] * (len(pads) - 1)])
    return {"columns": ["Model", "Held out", *[f"{pad} pad: RMSE vs training mean" for pad in pads]],
            "rows": rows, "condition": condition}


#: A shape (or a land/groove geometry) left out is answered honestly when its bias stays within this (ratings) or the
#: applicability check flags at least SHAPE_FLAGGED_ENOUGH of its presses; otherwise its "passes" needs a warning.
SHAPE_BIAS_LIMIT = 0.15
SHAPE_FLAGGED_ENOUGH = 0.8


def _verdict_cell(row, unseen: pd.DataFrame, model: str, pad: str, condition: str, scheme: str) -> str:
    below = row["rmse"] < row["null_rmse"]
    verdict = "fails" if not row["passes"] else "passes" if row["n_permutations"] else \
        "below the mean, not permutation-tested"
    if scheme in PER_GROUP_SCHEMES:  # one direction: its bias, and how much of it the applicability check flags
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
            verdict += f"; 90 % surface interval held {_held_count(control) or held}" if held[0].isdigit() else \
                "; no 90 % surface interval (too few specimens)"
        if pd.notna(control.get("presses_needed")):
            verdict += f"; needs {counted(int(control['presses_needed']), 'press', 'presses')} per surface"
    return f"{row['rmse']:.2f} vs {row['null_rmse']:.2f}, {verdict}"


def _held_count(control) -> str:
    """'13 of 14 specimens (misses C2), x/÷ 1.54': what the jackknife+ check held, as the one count it is over the
    study's specimens (never a share alone), those it missed named from the check ('' where it gave no count)."""
    checked = control.get("jackknife_plus_specimens", 0)
    if not checked or pd.isna(checked):
        return ""
    missed = [name for name in str(control.get("jackknife_plus_missed", "") or "").split(", ") if name]
    misses = f" (misses {', '.join(missed)})" if missed else ""
    return (f"{int(checked) - len(missed)} of {counted(int(checked), 'specimen')}{misses}, "
            f"x/÷ {control['jackknife_plus_median_factor']:.2f}")


#: The first screen names the pad x conditions where a family fails its controls only up to this many.
FAILS_NAMED = 2


def _passes_line(unseen: pd.DataFrame, passes: pd.Series) -> str:
    """Where each model passes its controls (training mean and shuffled targets), pad x condition. A pass whose mean
    per-specimen RMSE is not below the training mean's rests on the pooled RMSE alone and is counted apart."""
    parts = []
    for model, rows in unseen.groupby("model", sort=False):
        ok = passes[rows.index]
        pooled_only = ok & ~(rows["rmse"] < rows["null_rmse"])
        failed = rows[~ok]
        # A family that passes nowhere is said so in three words, and the cells it fails are named only where they
        # are few (the table below has every one): the first screen stays one screen.
        where = ", ".join(f"{r.pad} {r.condition}" for r in failed.itertuples()) if len(failed) <= FAILS_NAMED else ""
        part = (f"{model_title(model)} passes in none of {len(rows)}" if not ok.any() else
                f"{model_title(model)} passes in {int((ok & ~pooled_only).sum())} of {len(rows)}"
                + (f" (not {where})" if where else ""))
        if pooled_only.any():
            part += (", and in " + ", ".join(f"{r.pad} {r.condition}" for r in rows[pooled_only].itertuples())
                     + " on pooled RMSE only (its mean per-specimen RMSE is not below the training mean's)")
        parts.append(part)
    shuffled = " and better than specimen-shuffled targets" if unseen["n_permutations"].max() > 0 else \
        " (no shuffled targets: --permutations 0)"
    return (f"Which model passes its controls for new surfaces (below the training mean{shuffled}, nested "
            f"leave-one-specimen-out), per pad x condition: {'; '.join(parts)}.")


def console_lines(analysis) -> list[str]:
    """What the study command prints once its report is written: surfaces left out (:func:`unseen_lines`), then the
    paper's model under the paper's protocol, per pad and condition."""
    lines = unseen_lines(analysis)
    loo = analysis.results("loo")
    loo = loo[loo["model"].map(is_paper_model).astype(bool)]
    for (pad, condition), group in loo.groupby(["pad", "condition"], sort=False):
        count = analysis.condition_fit(pad, condition, "loo", PAPER_MODEL).best
        lines.append(f"{pad:>12} {condition:>9}: mean RMSE {group['rmse'].mean():.3f}, mean OVL "
                     f"{group['ovl'].mean():.3f}, {counted(count, 'component')} ({PAPER_MODEL}, LOO)")
    return lines


def unseen_lines(analysis) -> list[str]:
    """The question users ask first, in a headline and one line per pad: how well each model predicts an unseen
    surface (nested LOSO mean per-specimen RMSE against the training mean's, permutation p, Spearman's rho)."""
    unseen = analysis.unseen
    if unseen.empty:
        return [source.NO_LOSO_CONSOLE]
    condition = analysis.headline_condition
    rows = unseen[unseen["condition"] == condition]
    best = rows.loc[rows["rmse"].idxmin()]
    lines = [f"Held-out surfaces (a grating left out of training: nested leave-one-specimen-out, {condition}; "
             "mean per-specimen RMSE, lower is better): "
             f"lowest {best['model']} on the {best['pad']} pad, {best['rmse']:.2f} vs the training mean's "
             f"{best['null_rmse']:.2f}."]
    for pad, group in rows.groupby("pad", sort=False):
        parts = []
        for r in group.itertuples():
            p = f"p {permutation_p_text(r.permutation_p, r.n_permutations, at_most='<=')}" if r.n_permutations \
                else "no permutations"
            verdict = "" if r.passes else ", fails controls"
            verdict += ", not below the training mean" if r.rmse >= r.null_rmse else ""
            cover = "" if math.isnan(r.pi90_coverage_trials) else f", 90 % interval covers {r.pi90_coverage_trials:.0%}"
            parts.append(f"{r.model} {r.rmse:.2f} ({p}, rho {r.spearman_rho:.2f}{cover}{verdict})")
        lines.append(f"  {pad} pad: {' / '.join(parts)} vs training mean {group['null_rmse'].iloc[0]:.2f}")
    return [*lines, which_model_line(unseen, analysis.fit_default) + evidence_sentence(analysis)]


def which_model_line(unseen: pd.DataFrame, default: str = DEFAULT_MODEL) -> str:
    """Which model to use for what, in one sentence: the first screen's verdict (:func:`recommended_model`), so the
    console and the report never disagree; the paper's model reproduces the paper."""
    passes = unseen["passes"].fillna(False).astype(bool)
    below = unseen["rmse"] < unseen["null_rmse"]  # a pass on pooled RMSE alone is not counted as one
    parts = []
    for name, rows in unseen.groupby("model", sort=False):
        pooled_only = int((passes[rows.index] & ~below[rows.index]).sum())
        parts.append(f"{name} passes in {int((passes[rows.index] & below[rows.index]).sum())} of {len(rows)}"
                     + (f" (and in {pooled_only} on pooled RMSE only)" if pooled_only else ""))
    controls = f"Controls with a grating left out, per pad x condition: {', '.join(parts)}."
    model = recommended_model(unseen, default)
    if model is None:
        return f"Which model to use: none. {NO_MODEL} {PAPER_MODEL} reproduces the paper. {controls}"
    how = " (roughsense fit's default)" if model == default else f" (roughsense fit --model {model})"
    return (f"Which model to use: {model}{how} to score surfaces left out of training, where it passes its "
            f"controls; {PAPER_MODEL} to reproduce the paper. {controls}")
