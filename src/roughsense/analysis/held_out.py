"""Stricter held-out schemes: a whole period, shape or land/groove geometry left out of training, beside one grating.

Leave-one-specimen-out (LOSO) keeps the other shape of the held-out period in training, so a model that reads only
the period is rewarded for it: the rectangular 3 mm grating is predicted from a fit that saw the circular 3 mm one.
Two stricter schemes say how far that carries:

- **period**: both shapes of a period held out together (leave-one-period-out), so the period itself is new;
- **shape**: the model fitted on one shape predicts every grating of the other (leave-one-shape-out), so the shape
  is new; a model that cannot tell shapes apart shows it as a bias of one sign per shape.
- **geometry**: every grating of one land/groove geometry (analysis/geometry.py: a rectangle's land as a fraction of
  its period, rounded; each other shape its own) held out together and predicted from the rest, so the groove width
  at a known period is new; formed only where the study has two or more rectangular geometries (the paper's 14 have
  one: every rectangle is half land), else skipped, ``StudyFacts.geometry_note`` saying why.

Each row gives, per model x pad x condition x scheme, the mean per-specimen RMSE beside the training mean's under
the same folds, the mean bias (rating units) and the mean log bias of each shape (a shape or a geometry left out:
one row per held-out group, its specimens only), Spearman's rho over the rated
specimens, the permutation p (of a family whose batched CV refits every shuffled target at no cost, the peak law's;
PLS's nested search would double the study's controls) and the share of presses the applicability flag fell on. The
``specimen`` rows are the study's own LOSO fits and controls, repeated here so the three schemes stand side by side.
"""
from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
from scipy import stats

from ..model.family import FoldSettings
from ..model.registry import engine, paper_family
from .controls import fold_mean_predictions, permutation_p, permuted_targets
from .metrics import ALPHA
from .presses import presses_analysis, presses_needed_by_curve
from .results import Controls, RunSettings, StricterSchemes, StudyFacts

#: The schemes, strictest last, and what each holds out in a user's words.
SCHEME_WORDS = {"specimen": "a grating left out of training", "period": "a period left out (both shapes)",
                "shape": "a shape left out (fitted on the other)",
                "geometry": "a land/groove geometry left out"}
#: The schemes whose every held-out group is its own experiment, reported one row each (so that one group's bias
#: cannot cancel another's).
PER_GROUP_SCHEMES = ("shape", "geometry")
SCHEMES = tuple(SCHEME_WORDS)
HELD_OUT_COLUMNS = ["model", "pad", "condition", "scheme", "held_out", "n_folds", "rmse", "null_rmse", "bias", "spearman_rho",
                    "permutation_p", "n_permutations", "passes", "flagged_share"]


def scheme_folds(scheme: str, specimens: np.ndarray, shapes: dict, wavelengths: dict,
                 geometries: dict | None = None) -> np.ndarray | None:
    """Each trial's fold label under ``scheme``; None where the study cannot form it (fewer than 2 folds, or a
    specimen without a period, shape or geometry: ``geometries`` is empty where the study has none to hold out)."""
    specimens = np.asarray(specimens).astype(str)
    if scheme == "specimen":
        return specimens
    source = {"period": wavelengths, "shape": shapes, "geometry": geometries or {}}[scheme]
    labels = pd.Series(specimens).map(lambda s: source.get(s, np.nan))
    if labels.isna().any() or labels.nunique() < 2:
        return None
    return labels.astype(str).to_numpy()


def judged(prediction: np.ndarray, y: np.ndarray, specimens: np.ndarray, folds: np.ndarray, shapes: dict,
           reference: str, rows=None) -> dict:
    """RMSE (mean per specimen) beside the training mean's, bias, log bias per shape and rho of one scheme, over
    ``rows`` (a boolean mask; default every row)."""
    frame = pd.DataFrame({"specimen": specimens, "prediction": prediction, "target": y,
                          "null": fold_mean_predictions(y, folds)})
    if rows is not None:
        frame = frame[np.asarray(rows, dtype=bool)]
    frame["error2"] = (frame["prediction"] - frame["target"]) ** 2
    frame["null2"] = (frame["null"] - frame["target"]) ** 2
    per = frame.groupby("specimen", sort=False).mean()
    per["shape"] = [shapes.get(s, "") for s in per.index]
    log_bias = np.log(per["prediction"].clip(lower=1e-9)) - np.log(per["target"])
    rated = per[per.index != reference]
    with warnings.catch_warnings():  # a constant prediction: NaN says it
        warnings.simplefilter("ignore")
        rho = float(stats.spearmanr(rated["prediction"], rated["target"])[0]) if len(rated) >= 3 else float("nan")
    row = {"rmse": float(np.sqrt(per["error2"]).mean()), "null_rmse": float(np.sqrt(per["null2"]).mean()),
           "bias": float((per["prediction"] - per["target"]).mean()), "spearman_rho": rho}
    for shape, values in log_bias.groupby(per["shape"], sort=False):
        row[f"log_bias_{shape}"] = float(values.mean())
    return row


def stricter_schemes(facts: StudyFacts, run: RunSettings, controls: Controls, jobs) -> StricterSchemes:
    """The study's stage of stricter schemes: a period and a shape left out (this module), and presses per surface
    (presses.py), from the LOSO fits among the controls' ``jobs``."""
    held_out = held_out_analysis(facts, controls.controls, jobs, run.max_components)
    presses = presses_analysis(jobs, run.seed)
    return StricterSchemes(held_out, presses, presses_needed_by_curve(presses))


def held_out_analysis(facts: StudyFacts, controls: pd.DataFrame, jobs, max_components: int) -> pd.DataFrame:
    """The held-out table of a study: every LOSO fit among the controls' ``jobs`` (fit, X, y, specimens,
    shufflings, law) under every scheme, run after the controls so the LOSO rows quote their permutation p
    (``controls``: controls.csv). ``facts`` give each specimen's period and shape."""
    rows = []
    for fit, X, y, specimens, permutations, law in jobs:
        if fit.cv != "loso":
            continue
        shuffled = permuted_targets(y, specimens, permutations) if len(permutations) else None
        for scheme in SCHEMES:
            folds = scheme_folds(scheme, specimens, facts.shapes, facts.wavelengths, facts.geometries)
            scored = _scheme_predictions(fit, scheme, folds, X, y, specimens, shuffled, law, controls, max_components)
            if scored is None:
                continue
            prediction, p, n_perm, flags = scored
            parts = _parts(scheme, folds, set(facts.shapes.values()))
            for held, mask in parts:
                chosen = np.ones(len(y), bool) if mask is None else mask
                row = {"model": fit.model, "pad": fit.pad, "condition": fit.condition, "scheme": scheme,
                       "held_out": held, "n_folds": int(pd.Series(folds).nunique()),
                       **judged(prediction, y, specimens, folds, facts.shapes, facts.reference_specimen, chosen),
                       "permutation_p": p, "n_permutations": n_perm,
                       "flagged_share": float(np.mean(flags[chosen])) if flags is not None else float("nan")}
                row["passes"] = bool(row["rmse"] < row["null_rmse"] and (not n_perm or p < ALPHA))
                rows.append(row)
    return held_out_table(rows)


def _parts(scheme: str, folds: np.ndarray, shapes: set) -> list[tuple[str, np.ndarray | None]]:
    """The rows of one scheme: (held-out label, its rows' mask). A shape (geometry) left out is one experiment per
    shape (geometry), a row each, so that one direction's bias cannot cancel another's; a geometry that is a whole
    shape (the circles) is held out on its own but not reported twice: its row is the shape left out's."""
    if scheme not in PER_GROUP_SCHEMES:
        return [("all", None)]
    groups = [f for f in pd.unique(folds) if scheme != "geometry" or f not in shapes]
    return [(str(f), folds == f) for f in groups]


def _scheme_predictions(fit, scheme: str, folds, X, y, specimens, shuffled, law: dict, controls: pd.DataFrame,
                        max_components: int):
    """(predictions, permutation p, shufflings, held-out flags) of one fit under one scheme; None where the scheme
    cannot be formed or the family has none."""
    if folds is None:
        return None
    if scheme == "specimen":  # the study's own LOSO fit and its control
        control = _control(controls, fit)
        p, n_perm = (float("nan"), 0) if control is None else (float(control["permutation_p"]),
                                                              int(control["n_permutations"]))
        return fit.predictions["prediction"].to_numpy(dtype=float), p, n_perm, fit.held_out_flags
    targets = y[:, None] if shuffled is None else np.column_stack([y, shuffled])
    scored = engine(fit.model).scheme_predictions(X, targets, specimens, folds, FoldSettings.of(law), max_components)
    if scored is None:
        return None
    every, flags = scored
    p, n_perm = float("nan"), 0
    if len(every) > 1:  # the family refitted the shufflings too
        real = np.sqrt(np.mean((every[0] - y) ** 2))
        p = permutation_p(real, np.sqrt(np.mean((every[1:] - shuffled.T) ** 2, axis=1)))
        n_perm = int(shuffled.shape[1])
    return every[0], p, n_perm, flags


def _control(controls: pd.DataFrame, fit) -> pd.Series | None:
    if controls is None or controls.empty:
        return None
    named = controls["model"] if "model" in controls else pd.Series(paper_family().name, index=controls.index)
    rows = controls[(controls["pad"] == fit.pad) & (controls["condition"] == fit.condition)
                    & (controls["cv"] == "loso") & named.eq(fit.model)]
    return None if rows.empty else rows.iloc[0]


def held_out_table(rows: list[dict]) -> pd.DataFrame:
    """The rows as one table: HELD_OUT_COLUMNS, then one ``log_bias_<shape>`` column per shape."""
    frame = pd.DataFrame(rows)
    if frame.empty:
        return pd.DataFrame(columns=HELD_OUT_COLUMNS)
    shape_columns = [c for c in frame.columns if c.startswith("log_bias_")]
    return frame[HELD_OUT_COLUMNS + shape_columns]
