"""The sweep's report: summarise the stored rows (explore.summary) and render index.html through report/."""
from __future__ import annotations

import math
import os
from pathlib import Path

import pandas as pd

from .._util import atomic
from ..report.explore_page import axis_figure_files, html_table, render_explore
from ..report.html import FigureStyle
from ..report.provenance import SWEEP_LIMITS
from .paired import MARGINS, MIN_SEEDS, too_few
from .store import FAILURES_CSV, REPORT, SPECIMENS_DIR, ResultStore
from .summary import (
    COMPARISON_COLUMNS,
    DESIGN,
    _match,
    axis_slice,
    best_per_model,
    comparisons,
    judge_cv,
    models_in,
    paper_questions,
    seed_table,
    side_by_side,
    with_null,
)
from .sweep import Sweep
from .sweep_cells import MODEL_KEY

SUMMARY_CSV = "summary.csv"


def _varying(results: pd.DataFrame) -> list[str]:
    return [c for c in DESIGN if results[c].nunique(dropna=False) > 1]


def _describe(anchor: dict, skip: str | None = None) -> str:
    parts = []
    for key, value in anchor.items():
        if key == skip or (isinstance(value, float) and math.isnan(value)):
            continue
        parts.append(f"{key} = {value:.4g}" if isinstance(value, float) else f"{key} = {value}")
    return ", ".join(parts)


def write_explore_report(sweep: Sweep, out: str | os.PathLike[str], *, meta: dict | None = None,
                         style: FigureStyle = FigureStyle()) -> Path:
    """Write index.html, summary.csv and each axis's figure (``style``: format and resolution) from the rows stored
    under ``out`` (finished cells only)."""
    out = Path(out)
    store = ResultStore.reader(out, sweep)
    results = store.read()
    specimens = store.read(SPECIMENS_DIR)
    failures = pd.read_csv(out / FAILURES_CSV) if (out / FAILURES_CSV).is_file() else pd.DataFrame()
    meta = dict(meta or {})
    meta.setdefault("sweep", str(sweep.path))
    meta.setdefault("cells", f"{results['cell'].nunique()} of {len(sweep.cells)} finished"
                    + (f", {len(failures)} failed" if len(failures) else ""))
    meta.setdefault("axes", "; ".join(f"{k}: {', '.join(map(str, v))}" for k, v in sweep.axes.items()) or "none")
    results = with_null(results, specimens) if not results.empty else results
    table = comparisons(results, seed_table(results)) if not results.empty \
        else pd.DataFrame(columns=DESIGN + ["condition", "cv"])
    varying = _varying(results) if not results.empty else []
    shown = varying or ["pad"]
    best_frame, axes, questions = None, [], []
    if not results.empty:
        best_frame = _best_frame(table, shown)
        axes = _axis_sections(sweep, results, table, varying)
        for q in paper_questions(results, specimens, table):
            item = {"title": q.title, "covered": q.covered, "answer": q.answer, "how_to_cover": q.how_to_cover}
            if q.covered:
                item["table"] = html_table(q.table, "", "")
            questions.append(item)
    summary = _summary_view(table, shown)
    fail_view = failures[["cell", "seed", *[c for c in shown if c in failures.columns], "error"]] \
        if not failures.empty else failures
    figure_files, shown = axis_figure_files(axes, style)
    html = render_explore(name=sweep.name, meta=meta, best=best_frame, axes=axes, questions=questions,
                          summary=summary, failures=fail_view, limits=SWEEP_LIMITS,
                          notes=_best_flags(table), rule=_rule(results), shown=shown)
    for name, data in figure_files.items():
        atomic.write_bytes(out / name, data)
    if not table.empty:  # every design per model; ``model`` last, as columns are only ever added
        atomic.write_csv(out / SUMMARY_CSV, _csv_columns(table), float_format="%.6g")
    atomic.write_bytes(out / REPORT, html)
    return out / REPORT


def _rule(results: pd.DataFrame) -> str:
    """The verdict rule in one line, with the margins and (below MIN_SEEDS) why there are no intervals."""
    n = int(results["seed"].nunique()) if not results.empty else 0
    if n < MIN_SEEDS:
        return too_few(n)
    margins = ", ".join(f"{k.upper()} ±{v:.2f}" for k, v in MARGINS.items())
    return (f"paired by seed over {n} seeds; better/worse when the 95 % interval of the difference excludes 0, "
            f"equivalent when it lies within the margin ({margins}, fixed in advance), otherwise undetermined "
            f"within ±(its farthest end); mde_80: the smallest difference {n} seeds detect with 80 % power")


def _best_flags(table: pd.DataFrame) -> list[str]:
    """A warning for each family's best design that does not beat its training mean under the judging CV."""
    if table.empty or "null_verdict" not in table.columns:
        return []
    cv = judge_cv(table)
    flags = []
    for anchor in best_per_model(table):
        row = table[_match(table, anchor) & (table["cv"] == cv)].iloc[0]
        if not row["null_verdict"].startswith("beats"):
            flags.append(f"The best {anchor[MODEL_KEY]} design ({row['condition']}) {_null_clause(row)} under "
                         f"{cv.upper()}: RMSE {row['rmse']:.3f} against {row['null_rmse']:.3f}"
                         + (" (lower, but the paired 95 % interval of the difference includes 0)."
                            if row["null_verdict"].startswith("does not") and row["rmse"] < row["null_rmse"] else "."))
    return flags


def _null_clause(row) -> str:
    """The verdict against the training mean as a predicate: ``is below ...`` / ``does not beat ...``."""
    verdict = str(row["null_verdict"])
    return f"is {verdict}" if verdict.startswith(("below", "not below")) else verdict


SUMMARY_LEVELS = ["rmse", "rmse_ci95", "ovl", "ovl_ci95"]
SUMMARY_ADDED = ["null_rmse", "null_rmse_ci95", "rmse_ci_low", "rmse_ci_high", "ovl_ci_low", "ovl_ci_high",
                 "null_rmse_ci_low", "null_rmse_ci_high", *COMPARISON_COLUMNS]


def _csv_columns(table: pd.DataFrame) -> pd.DataFrame:
    """summary.csv: the columns it always had, in their order, then the interval and comparison columns, model last."""
    predictive = [c for c in ("ovl_predictive", "ovl_predictive_ci95") if c in table.columns]
    first = [*DESIGN, "condition", "cv", *SUMMARY_LEVELS, *predictive, "n_seeds"]
    first = [c for c in first if c != MODEL_KEY and c in table.columns]
    added = [c for c in table.columns if c not in first and c != MODEL_KEY and not c.startswith("ovl_predictive_ci_")]
    return table[[*first, *[c for c in SUMMARY_ADDED if c in added], *[c for c in added if c not in SUMMARY_ADDED],
                  MODEL_KEY]]


def _summary_view(table: pd.DataFrame, shown: list[str]) -> pd.DataFrame:
    """The report's table of all designs: levels with clipped intervals, the null, and the comparison with the best."""
    if table.empty:
        return pd.DataFrame(columns=["condition", "cv", "rmse", "rmse_ci95", "ovl", "ovl_ci95"])
    levels = [c for m in ("rmse", "null_rmse", "ovl") if m in table.columns
              for c in (m, f"{m}_ci95", f"{m}_ci_low", f"{m}_ci_high")]
    view = table[[*shown, "condition", "cv", *levels, "n_seeds", "null_verdict", "diff_mean", "ci_low", "ci_high",
                  "verdict"]].rename(columns={"diff_mean": "vs best", "ci_low": "vs best_ci_low",
                                              "ci_high": "vs best_ci_high", "verdict": "vs best: verdict",
                                              "null_verdict": "vs training mean"})
    if MODEL_KEY in shown:  # the families side by side, one row per design
        view = side_by_side(view, [c for c in shown if c != MODEL_KEY] + ["condition", "cv"])
    return view


def _best_frame(table: pd.DataFrame, shown: list[str]) -> pd.DataFrame | None:
    """The best design of each model family, with its rows under each CV scheme."""
    frames = [table[_match(table, anchor)] for anchor in best_per_model(table)]
    if not frames:
        return None
    levels = [c for m in ("rmse", "null_rmse", "ovl") if m in table.columns
              for c in (m, f"{m}_ci95", f"{m}_ci_low", f"{m}_ci_high")]
    best = pd.concat(frames)[[*DESIGN, "condition", "cv", *levels, "n_seeds", "null_verdict"]]
    best = best.rename(columns={"null_verdict": "vs training mean"})
    return best[[c for c in best.columns if c not in DESIGN or c in shown or c == "pad"]]


def _axis_sections(sweep: Sweep, results: pd.DataFrame, table: pd.DataFrame, varying: list[str]) -> list[dict]:
    """One slice per varying axis through the best design of each model family (the model axis: through the best)."""
    axes = []
    for axis in varying:
        order = list(dict.fromkeys(sweep.axes.get(axis, []))) or list(dict.fromkeys(results[axis].dropna()))
        if axis == "field_length_mm":
            order = sorted(dict.fromkeys(results[axis].dropna()))
        families = [None] if axis == MODEL_KEY else models_in(table)
        slices = [axis_slice(table if m is None else table[table[MODEL_KEY] == m], axis, order) for m in families]
        slices = [(rows, anchor) for rows, anchor in slices if not rows.empty and rows[axis].nunique() >= 2]
        if not slices:
            continue
        rows = pd.concat([r for r, _ in slices])
        axes.append({"axis": axis, "order": [v for v in order if v in set(rows[axis])] or list(rows[axis].unique()),
                     "rows": rows, "anchor": "; ".join(_describe(a, skip=axis) for _, a in slices)})
    return axes
