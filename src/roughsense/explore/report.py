"""The sweep's report: summarise the stored rows (explore.summary) and render index.html through report/."""
from __future__ import annotations

import math
import os
from pathlib import Path

import pandas as pd

from .._util import atomic
from ..report.explore_page import html_table, render_explore
from .store import FAILURES_CSV, REPORT, SPECIMENS_DIR, ResultStore
from .summary import (
    DESIGN,
    _match,
    axis_slice,
    best_per_model,
    models_in,
    paper_questions,
    seed_table,
    side_by_side,
)
from .sweep import MODEL_KEY, Sweep

SUMMARY_CSV = "summary.csv"
LIMITS = [
    "The twin was calibrated to reproduce the paper's error regime with the paper's two pads (smooth; 1 mm fingerprint, "
    "0.2 mm ridges) on the paper's fourteen gratings. Agreement with the paper there is a property of the calibration, "
    "not a finding; every other design is an extrapolation of the same physics (elastic half-space contact, gap-to-"
    "brightness optics, bench noise drawn as in the calibration).",
    "With ratings_from = \"paper\", only the paper's fourteen presets carry the paper's panel; every other specimen "
    "gets its perceived roughness from the twin's simulated finger (sim/finger.py: contact of a fingertip, SA1 "
    "strain readout, a fitted power law), which ratings_from = \"physics\" uses for every specimen. Those targets are "
    "not measurements, so 'can it be measured' means 'does the sensor track the model'.",
    "The spectrum covers 0.1-1 mm^-1 (wavelengths 1-10 mm): a grating whose fundamental lies above 1 mm^-1 "
    "(wavelength below 1 mm) is seen only through its contact pattern's harmonics and aliasing of the pad relief.",
    "A shorter field is modelled as a narrower camera view of the same 50 x 10 mm contact; a physically smaller pad "
    "would also change the nominal pressure and the edge effects, which the twin does not model.",
    "The pad modulus enters only the contact mechanics (how far the pad sinks into the grooves); its optical and "
    "frictional consequences and its ageing are not modelled.",
]


def _varying(results: pd.DataFrame) -> list[str]:
    return [c for c in DESIGN if results[c].nunique(dropna=False) > 1]


def _describe(anchor: dict, skip: str | None = None) -> str:
    parts = []
    for key, value in anchor.items():
        if key == skip or (isinstance(value, float) and math.isnan(value)):
            continue
        parts.append(f"{key} = {value:.4g}" if isinstance(value, float) else f"{key} = {value}")
    return ", ".join(parts)


def write_explore_report(sweep: Sweep, out: str | os.PathLike[str], *, meta: dict | None = None) -> Path:
    """Write index.html and summary.csv from the rows stored under ``out`` (finished cells only)."""
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
    table = seed_table(results) if not results.empty else pd.DataFrame(columns=DESIGN + ["condition", "cv"])
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
    predictive = [c for c in ("ovl_predictive", "ovl_predictive_ci95") if c in table.columns]
    summary = table[[*shown, "condition", "cv", "rmse", "rmse_ci95", "ovl", "ovl_ci95", *predictive, "n_seeds"]] \
        if not table.empty else pd.DataFrame(columns=["condition", "cv", "rmse", "rmse_ci95", "ovl", "ovl_ci95"])
    if MODEL_KEY in shown:  # the families side by side, one row per design
        summary = side_by_side(summary, [c for c in shown if c != MODEL_KEY] + ["condition", "cv"])
    fail_view = failures[["cell", "seed", *[c for c in shown if c in failures.columns], "error"]] \
        if not failures.empty else failures
    html = render_explore(name=sweep.name, meta=meta, best=best_frame, axes=axes, questions=questions,
                          summary=summary, failures=fail_view, limits=LIMITS)
    if not table.empty:  # every design per model; ``model`` last, as columns are only ever added
        atomic.write_csv(out / SUMMARY_CSV, table[[c for c in table.columns if c != MODEL_KEY] + [MODEL_KEY]],
                         float_format="%.6g")
    atomic.write_bytes(out / REPORT, html)
    return out / REPORT


def _best_frame(table: pd.DataFrame, shown: list[str]) -> pd.DataFrame | None:
    """The best design of each model family, with its rows under each CV scheme."""
    frames = [table[_match(table, anchor)] for anchor in best_per_model(table)]
    if not frames:
        return None
    best = pd.concat(frames)[[*DESIGN, "condition", "cv", "rmse", "rmse_ci95", "ovl", "ovl_ci95", "n_seeds"]]
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
