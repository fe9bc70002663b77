"""What a sweep found: per-design means with 95 % intervals over seeds, the best design, slices through it along
each axis, and the paper's open questions answered from paired intervals where the sweep covers them.

A design is every design column (sweep.COLUMN_KINDS, the model family included) plus the predictor set (condition);
seeds are replicates. Designs are ranked per model family, so a sweep of two families shows the best of each.
Designs are compared on the same seeds (the twin keys its draws by names, so two designs with one seed share their
mounts, exposures and panel: common random numbers), so every comparison is a paired interval worded by
explore.paired (better / worse / equivalent within a stated margin / undetermined, with what the seeds could detect).
Every design carries the training mean's RMSE under the same CV (its null) beside its own.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..analysis.metrics import mean_interval
from ..model.registry import names
from ..paper import FINGERPRINT_PAD, SMOOTH_PAD
from .paired import MIN_SEEDS, Paired, judge, level, null_rmse, paired, too_few
from .sweep import COLUMN_KINDS, DEFAULTS
from .sweep_cells import FINGERPRINT_ONLY, MODEL_KEY

DESIGN = list(COLUMN_KINDS)
METRICS = ("rmse", "ovl")
#: The columns summary.csv adds for each design's comparison with its family's best design and with its null.
COMPARISON_COLUMNS = ["diff_mean", "ci_low", "ci_high", "margin", "mde_80", "verdict", "n_paired",
                      "null_diff_mean", "null_ci_low", "null_ci_high", "null_verdict"]


def with_null(results: pd.DataFrame, specimens: pd.DataFrame) -> pd.DataFrame:
    """The result rows with ``null_rmse``: the training mean's RMSE under the same CV (explore.paired.null_rmse)."""
    if specimens.empty or "null_rmse" in results.columns:
        return results
    null = null_rmse(specimens).reset_index()
    keys = ["cell", "pad", "condition", "cv", "model"]
    return results.merge(null, on=keys, how="left")


def _match(frame: pd.DataFrame, values: dict) -> pd.Series:
    mask = pd.Series(True, index=frame.index)
    for column, value in values.items():
        if isinstance(value, float) and math.isnan(value):
            mask &= frame[column].isna()
        else:
            mask &= frame[column] == value
    return mask


def seed_table(results: pd.DataFrame) -> pd.DataFrame:
    """One row per design x condition x CV scheme: mean over seeds of RMSE, OVL (and the null's RMSE), each with
    the half-width of its 95 % t-interval and the interval's ends clipped to the quantity's range (``_ci_low``,
    ``_ci_high``); below MIN_SEEDS seeds no interval (NaN)."""
    rows = []
    keys = DESIGN + ["condition", "cv"]
    metrics = [*METRICS, *(m for m in ("ovl_predictive", "null_rmse") if m in results.columns)]
    for key, group in results.groupby(keys, dropna=False, sort=False):
        row = dict(zip(keys, key))
        for metric in metrics:
            mean, half, n = mean_interval(group[metric])
            _, low, high, _ = level(group[metric], metric)
            row[metric], row[f"{metric}_ci95"] = mean, half if n >= MIN_SEEDS else math.nan
            row[f"{metric}_ci_low"], row[f"{metric}_ci_high"] = low, high
        row["n_seeds"] = int(group["seed"].nunique())
        rows.append(row)
    columns = keys + [c for m in metrics for c in (m, f"{m}_ci95")] + ["n_seeds"]
    return pd.DataFrame(rows, columns=columns + [f"{m}_ci_{e}" for m in metrics for e in ("low", "high")])


def _seeds(frame: pd.DataFrame, metric: str = "rmse") -> pd.Series:
    return frame.groupby("seed")[metric].mean()


def comparisons(results: pd.DataFrame, table: pd.DataFrame) -> pd.DataFrame:
    """``table`` with COMPARISON_COLUMNS: each design's RMSE paired over seeds against its family's best design
    (same condition rules: the best's own condition, the row's CV scheme) and against its own null."""
    keys = DESIGN + ["condition", "cv"]
    anchors = {anchor[MODEL_KEY]: anchor for anchor in best_per_model(table)}
    best = {(m, cv): _seeds(results[_match(results, a) & (results["cv"] == cv)])
            for m, a in anchors.items() for cv in set(results["cv"])}
    out = []
    for key, group in results.groupby(keys, dropna=False, sort=False):
        row = dict(zip(keys, key))
        own = _seeds(group)
        anchor = anchors.get(row[MODEL_KEY])
        is_best = anchor is not None and bool(_match(pd.DataFrame([row]), anchor).iloc[0])
        to_best = judge([]) if is_best else paired(own, best.get((row[MODEL_KEY], row["cv"]), pd.Series(dtype=float)))
        to_null = paired(own, _seeds(group, "null_rmse")) if "null_rmse" in group.columns else judge([])
        row.update(diff_mean=to_best.mean, ci_low=to_best.low, ci_high=to_best.high, margin=to_best.margin,
                   mde_80=to_best.mde, verdict="the best design" if is_best else to_best.words(), n_paired=to_best.n,
                   null_diff_mean=to_null.mean, null_ci_low=to_null.low, null_ci_high=to_null.high,
                   null_verdict=_null_words(to_null))
        out.append(row)
    found = pd.DataFrame(out, columns=keys + COMPARISON_COLUMNS)
    return table.merge(found, on=keys, how="left")


def _null_words(p: Paired) -> str:
    """Against the training mean: only a difference that excludes 0 below it beats the null."""
    if p.verdict == "too few seeds":
        return ("below the training mean (" if p.mean < 0 else "not below the training mean (") + too_few(p.n) + ")"
    return "beats the training mean" if p.verdict == "better" else "does not beat the training mean"


def judge_cv(table: pd.DataFrame) -> str:
    """Designs are ranked under LOSO (a specimen never seen in training) where the sweep has it, else LOO."""
    return "loso" if (table["cv"] == "loso").any() else "loo"


def best_design(table: pd.DataFrame, mask: pd.Series | None = None) -> dict | None:
    """The design x condition with the lowest mean RMSE under the judging CV scheme (optionally among ``mask``).

    Only designs with the most seeds compete: one whose other seeds failed would win on luck more often. The
    winner's numbers are still optimistic (it was chosen on the same seeds it is reported on).
    """
    cv = judge_cv(table)
    pool = table[(table["cv"] == cv) & (mask if mask is not None else True)]
    pool = pool[np.isfinite(pool["rmse"])]
    if pool.empty:
        return None
    pool = pool[pool["n_seeds"] == pool["n_seeds"].max()]
    row = pool.loc[pool["rmse"].idxmin()]
    return {k: row[k] for k in DESIGN + ["condition"]}


def models_in(frame: pd.DataFrame) -> list[str]:
    """The model families present, the paper's PLS first (the registry's order, unknown names after)."""
    present = list(dict.fromkeys(frame[MODEL_KEY].dropna())) if MODEL_KEY in frame.columns else []
    known = names()
    return [m for m in known if m in present] + [m for m in present if m not in known]


def best_per_model(table: pd.DataFrame) -> list[dict]:
    """The best design of each model family (families with no finished design are left out)."""
    found = [best_design(table, table[MODEL_KEY] == model) for model in models_in(table)]
    return [anchor for anchor in found if anchor is not None]


def side_by_side(frame: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """One row per ``keys`` with each family's columns beside the others' (``rmse (pls)``, ``rmse (peak-law)``, ...).

    An interval column keeps its ``_ci95`` suffix last, so a table renderer still pairs it with its mean.
    """
    models = models_in(frame)
    if len(models) < 2:
        return frame
    values = [c for c in frame.columns if c not in keys and c != MODEL_KEY]
    wide = frame[keys].drop_duplicates()  # the designs in their first order; a left merge keeps it
    for model in models:
        part = frame[frame[MODEL_KEY] == model][[*keys, *values]]
        wide = wide.merge(part.rename(columns={c: _tagged(c, model) for c in values}), on=keys, how="left")
    return wide[[*keys, *(_tagged(c, m) for c in values for m in models)]].reset_index(drop=True)


SUFFIXES = ("_ci95", "_ci_low", "_ci_high")  # an interval column keeps its suffix last, beside its mean


def _tagged(column: str, model: str) -> str:
    for suffix in SUFFIXES:
        if column.endswith(suffix):
            return f"{column[:-len(suffix)]} ({model}){suffix}"
    return f"{column} ({model})"


def axis_slice(table: pd.DataFrame, axis: str, order: list) -> tuple[pd.DataFrame, dict | None]:
    """The axis's values with every other design column held at the best design that has this axis."""
    mask = table["pad"] == FINGERPRINT_PAD if axis in FINGERPRINT_ONLY else None
    anchor = best_design(table, mask)
    if anchor is None:
        return table.iloc[0:0], None
    held = {k: v for k, v in anchor.items() if k != axis}
    rows = table[_match(table, held)].copy()
    rank = {v: i for i, v in enumerate(order)}
    rows["_order"] = rows[axis].map(lambda v: rank.get(v, len(rank)))
    return rows.sort_values(["cv", "_order"]).drop(columns="_order"), anchor


@dataclass
class Question:
    title: str
    covered: bool
    answer: str
    table: pd.DataFrame = field(default_factory=pd.DataFrame)
    how_to_cover: str = ""


def compare(results: pd.DataFrame, designs: list[tuple[str, dict]], condition: str, cv: str) -> pd.DataFrame:
    """Each labelled design's RMSE, OVL and null RMSE over seeds and its paired difference from the first design."""
    at = results[(results["condition"] == condition) & (results["cv"] == cv)]
    base = None
    rows = []
    for label, design in designs:
        cells = at[_match(at, design)]
        if cells.empty:
            continue
        row = {"design": label, "cv": cv, "condition": condition, "n_seeds": int(cells["seed"].nunique())}
        for metric in (*METRICS, *(["null_rmse"] if "null_rmse" in cells.columns else [])):
            mean, low, high, _ = level(cells[metric], metric)
            row[metric], row[f"{metric}_ci_low"], row[f"{metric}_ci_high"] = mean, low, high
        if base is None:
            base = cells
        for metric in METRICS:
            d = paired(_seeds(cells, metric), _seeds(base, metric), metric) if cells is not base else None
            row[f"d_{metric}"] = d.mean if d else 0.0
            row[f"d_{metric}_ci_low"], row[f"d_{metric}_ci_high"] = (d.low, d.high) if d else (math.nan, math.nan)
            row[f"{metric}_verdict"] = d.words() if d else "(the reference)"
            row[f"{metric}_mde_80"] = d.mde if d else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def _fmt(mean: float, low: float = math.nan, high: float = math.nan) -> str:
    """``0.388 [0.350, 0.417]``, or the mean alone when there is no interval."""
    if not np.isfinite(mean):
        return "—"
    return f"{mean:.3f}" + (f" [{low:.3f}, {high:.3f}]" if np.isfinite(low) and np.isfinite(high) else "")


def _pair(results: pd.DataFrame, a: dict, b: dict, condition: str, cv: str, metric: str = "rmse") -> Paired:
    at = results[(results["condition"] == condition) & (results["cv"] == cv)]
    return paired(_seeds(at[_match(at, a)], metric), _seeds(at[_match(at, b)], metric), metric)


def _seeds_note(results: pd.DataFrame) -> str:
    n = int(results["seed"].nunique())
    return f" ({too_few(n)}.)" if n < MIN_SEEDS else ""


def _with(anchor: dict, **overrides) -> dict:
    design = {k: v for k, v in anchor.items() if k != "condition"}
    design.update(overrides)
    return design


def paper_questions(results: pd.DataFrame, specimens: pd.DataFrame, table: pd.DataFrame) -> list[Question]:
    """The paper's five open questions, each answered from the sweep's rows or marked as not covered.

    They are asked of the best design's model family (one family: the paper's PLS unless the sweep says otherwise).
    """
    cv = judge_cv(table)
    anchor = best_design(table)
    questions = [_fingerprint_question(results, anchor, cv)]
    for title, pick, cover in (
        ("Can gratings below 2 mm be measured?",
         lambda s: (s["wavelength_mm"] < 2.0) & (s["shape"] != "random"), 'specimens such as "rect:1.5", "sin:1.2:0.2"'),
        ("Do random gratings work?", lambda s: s["shape"] == "random", 'specimens such as "rand:1.5:0.2"'),
    ):
        questions.append(_specimen_question(results, specimens, cv, title, specimens[pick(specimens)], cover))
    for title, column, cover, base in (
        ("Can the pad (the field along the line) be made smaller?", "field_length_mm",
         "field_length_mm = [55.0, 40.0, 25.0] in [axes]", None),
        ("Do more forces help?", "forces_n", 'forces_n = [[1, 2, 3], [1, 2, 3, 4, 5]] in [axes]', "1,2,3"),
    ):
        questions.append(_axis_question(results, anchor, cv, title, column, cover, base))
    if anchor is not None and len(models_in(table)) > 1:
        for question in (questions[0], *questions[3:]):  # the specimen questions name their own family
            if question.covered:
                question.answer += f" Model family: {anchor[MODEL_KEY]} (the best design's)."
    return questions


def _level(row) -> str:
    """A design's RMSE with its interval and its null's beside it."""
    text = _fmt(row["rmse"], row["rmse_ci_low"], row["rmse_ci_high"])
    if "null_rmse" in row and np.isfinite(row["null_rmse"]):
        text += f" (training mean {row['null_rmse']:.3f})"
    return text


def _condition_of(results: pd.DataFrame, design: dict) -> str:
    """The condition a question judges: combined where the sweep has it, else the design's own."""
    return "combined" if (results["condition"] == "combined").any() else design["condition"]


def _fingerprint_question(results: pd.DataFrame, anchor: dict | None, cv: str) -> Question:
    """1. Would a fingerprint pad at human scale (0.5 mm) recover the smooth pad's accuracy?"""
    title = "Would a fingerprint pad at human scale (0.5 mm ridge period) recover the smooth pad's accuracy?"
    uncovered = Question(title, False, "", how_to_cover='pad = ["smooth", "fingerprint"] and '
                         'fingerprint_period_mm = [1.0, 0.5] in [axes]')
    has = (results["pad"] == SMOOTH_PAD).any() and (results["fingerprint_period_mm"] == 0.5).any()
    if not has or anchor is None:
        return uncovered
    ridge = anchor["ridge_height_mm"] if anchor["pad"] == FINGERPRINT_PAD else DEFAULTS["ridge_height_mm"]
    nan = math.nan
    designs = [("smooth", _with(anchor, pad=SMOOTH_PAD, fingerprint_period_mm=nan, ridge_height_mm=nan)),
               ("fingerprint, 1.0 mm", _with(anchor, pad=FINGERPRINT_PAD, fingerprint_period_mm=1.0, ridge_height_mm=ridge)),
               ("fingerprint, 0.5 mm", _with(anchor, pad=FINGERPRINT_PAD, fingerprint_period_mm=0.5, ridge_height_mm=ridge))]
    condition = _condition_of(results, anchor)
    frame = pd.concat([compare(results, designs, condition, c) for c in sorted(set(results["cv"]))])
    judged = frame[(frame["cv"] == cv)].set_index("design")
    if not {"smooth", "fingerprint, 0.5 mm"} <= set(judged.index):
        return uncovered
    d = _pair(results, designs[2][1], designs[0][1], condition, cv)
    answer = (f"{cv.upper()} RMSE, {condition} condition (95 % intervals over seeds): smooth "
              f"{_level(judged.loc['smooth'])}, fingerprint 0.5 mm {_level(judged.loc['fingerprint, 0.5 mm'])}. "
              f"0.5 mm minus smooth, paired by seed: {d.sentence()}.{_seeds_note(results)}")
    return Question(title, True, answer, frame)


def _group(specimen: str, shape: str, wavelength_mm: float, asked: set[str]) -> str:
    if specimen in asked:
        return "asked"
    return "paper range" if 2.0 <= wavelength_mm <= 5.0 and shape in ("rectangular", "circular") else "other"


def _specimen_rows(rows: pd.DataFrame, asked: set[str]) -> pd.DataFrame:
    """Per specimen and CV: RMSE and OVL over seeds (clipped intervals), grouped as asked, paper range, or other."""
    per = []
    for (specimen, cvs), group in rows.groupby(["specimen", "cv"], sort=False):
        first = group.iloc[0]
        row = {"specimen": specimen, "cv": cvs, "shape": first["shape"], "wavelength_mm": first["wavelength_mm"]}
        for metric in METRICS:
            mean, low, high, n = level(group[metric], metric)
            row.update({metric: mean, f"{metric}_ci_low": low, f"{metric}_ci_high": high})
        row.update(n_seeds=n, group=_group(specimen, first["shape"], first["wavelength_mm"], asked))
        per.append(row)
    return pd.DataFrame(per)


def _group_gap(rows: pd.DataFrame, asked: set[str], metric: str) -> Paired:
    """Per seed, the asked specimens' mean minus the paper-range specimens' mean, paired over seeds."""
    groups = [_group(s, sh, w, asked) for s, sh, w in zip(rows["specimen"], rows["shape"], rows["wavelength_mm"])]
    by = rows.assign(group=groups).groupby(["group", "seed"])[metric].mean()
    if "asked" not in by.index or "paper range" not in by.index:
        return judge([], metric)
    return paired(by.loc["asked"], by.loc["paper range"], metric)


def _specimen_question(results: pd.DataFrame, specimens: pd.DataFrame, cv: str, title: str,
                       chosen: pd.DataFrame, cover: str) -> Question:
    """2 and 3: specimens outside the paper's range, per specimen, against the paper's range in the same cells."""
    if chosen.empty:
        return Question(title, False, "", how_to_cover=cover)
    mask = results["cell"].isin(set(chosen["cell"]))
    sub_anchor = best_design(seed_table(results[mask])) if mask.any() else None
    rows = specimens[(specimens["cell"].isin(set(results.loc[mask & _match(results, _with(sub_anchor)), "cell"])))
                     & (specimens["condition"] == sub_anchor["condition"])
                     & (specimens[MODEL_KEY] == sub_anchor[MODEL_KEY])]
    asked_names = set(chosen["specimen"])
    frame = _specimen_rows(rows, asked_names)
    judged = frame[frame["cv"] == cv]
    asked = judged[judged["group"] == "asked"]
    paper = judged[judged["group"] == "paper range"]
    answer = (f"{cv.upper()}, {sub_anchor['pad']} pad, {sub_anchor['condition']}: mean RMSE "
              f"{asked['rmse'].mean():.3f} and OVL {asked['ovl'].mean():.3f} for "
              f"{', '.join(asked['specimen'])}")
    if not paper.empty:
        at = rows[rows["cv"] == cv]
        gaps = [f"{name} {_group_gap(at, asked_names, metric).sentence()}" for name, metric in
                (("RMSE", "rmse"), ("OVL", "ovl"))]
        answer += (f", against RMSE {paper['rmse'].mean():.3f} and OVL {paper['ovl'].mean():.3f} for the "
                   f"{len(paper)} specimens in the paper's range (2-5 mm) in the same cells; their difference "
                   f"(asked minus paper range), paired by seed: " + "; ".join(gaps))
    answer += ". Their 'perceived' roughness is the twin's model, not a measurement (see the limits below)."
    if len(models_in(results)) > 1:
        answer += f" Model family: {sub_anchor[MODEL_KEY]} (the best in these cells)."
    return Question(title, True, answer, frame)


def _axis_question(results: pd.DataFrame, anchor: dict | None, cv: str, title: str, column: str, cover: str,
                   base) -> Question:
    """4 and 5: a design axis swept around the best design, each value against the first."""
    values = list(dict.fromkeys(results[column]))
    if len(values) < 2 or anchor is None:
        return Question(title, False, "", how_to_cover=cover)
    if column == "field_length_mm":
        values = sorted(values, reverse=True)
    elif base in values:
        values = [base] + [v for v in values if v != base]
    designs = [(f"{column} = {v:.4g}" if isinstance(v, float) else f"{column} = {v}", _with(anchor, **{column: v}))
               for v in values]
    condition = _condition_of(results, anchor)
    frame = pd.concat([compare(results, designs, condition, c) for c in sorted(set(results["cv"]))])
    judged = frame[frame["cv"] == cv]
    parts = [f"{row['design'].split(' = ')[1]}: {_level(row)}" for _, row in judged.iterrows()]
    first = judged.iloc[0]["design"] if not judged.empty else ""
    verdicts = [f"{label.split(' = ')[1]}: " + _pair(results, design, designs[0][1], condition, cv).sentence()
                for label, design in designs[1:] if label in set(judged["design"])]
    answer = (f"{cv.upper()} RMSE ({condition}, other settings at the best design; 95 % intervals over seeds): "
              + "; ".join(parts) + f". Paired against {first.split(' = ')[-1]}: " + "; ".join(verdicts) + "."
              + _seeds_note(results))
    return Question(title, True, answer, frame)
