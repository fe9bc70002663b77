"""The sweep report: figures of RMSE and OVL along each axis and one self-contained HTML page.

Receives plain tables from :mod:`roughsense.explore.summary` and only renders them (report/ never imports explore).
"""
from __future__ import annotations

import base64
import datetime as _dt

import numpy as np
import pandas as pd

from .. import __version__, paper
from .._util.checks import is_number
from . import figures
from .html import template_environment

CV_STYLE = {"loo": ("#2f5d8a", "o", "LOO"), "loso": ("#b5472b", "s", "LOSO")}
MODEL_LINES = ("-", "--", ":", "-.")  # one line style per model family, in the order the rows give them


def axis_figure(rows: pd.DataFrame, axis: str, order: list):
    """RMSE and OVL against the axis value, mean ± 95 % interval over seeds, one line per CV scheme (and per model
    family, by line style, when the rows hold several)."""
    import matplotlib.pyplot as plt

    fig, panels = plt.subplots(1, 2, figsize=(9.5, 3.4))
    labels = [str(v) for v in order]
    numeric = all(is_number(v) for v in order)
    models = list(dict.fromkeys(rows["model"])) if "model" in rows.columns and axis != "model" else []
    keys = ["cv", "model"] if len(models) > 1 else ["cv"]
    for key, group in rows.groupby(keys, sort=False):
        cv = key[0] if isinstance(key, tuple) else key
        colour, marker, name = CV_STYLE.get(cv, ("#444", "o", cv))
        line = MODEL_LINES[models.index(key[1]) % len(MODEL_LINES)] if len(keys) > 1 else "-"
        name = f"{name}, {key[1]}" if len(keys) > 1 else name
        position = {str(v): i for i, v in enumerate(order)}
        x = np.array([float(v) if numeric else position.get(str(v), np.nan) for v in group[axis]])
        for panel, metric in zip(panels, ("rmse", "ovl")):
            err = np.nan_to_num(group[f"{metric}_ci95"].to_numpy(float), nan=0.0)
            panel.errorbar(x, group[metric].to_numpy(float), yerr=err, color=colour, marker=marker, capsize=3,
                           linestyle=line, label=name)
    for panel, metric in zip(panels, ("RMSE (perceived units)", "OVL")):
        panel.set_xlabel(axis)
        panel.set_ylabel(metric)
        if not numeric:
            panel.set_xticks(range(len(labels)), labels, rotation=20 if max(map(len, labels)) > 8 else 0)
        panel.grid(alpha=0.3)
    panels[0].legend(frameon=False)
    fig.tight_layout()
    return fig


def _cell(value, digits: int = 3) -> str:
    if isinstance(value, (float, np.floating)):
        return "—" if not np.isfinite(value) else f"{value:.{digits}g}" if abs(value) >= 100 else f"{value:.{digits}f}"
    return str(value)


def html_table(frame: pd.DataFrame, title: str, caption: str = "") -> dict:
    """A table for the template: the metric and its interval joined as 'mean ± half-width'."""
    frame = frame.copy()
    columns = []
    for column in frame.columns:
        if column.endswith("_ci95"):
            continue
        if f"{column}_ci95" in frame.columns:
            frame[column] = [("—" if not np.isfinite(m) else f"{m:.3f}" + (f" ± {h:.3f}" if np.isfinite(h) else ""))
                             for m, h in zip(frame[column], frame[f"{column}_ci95"])]
        columns.append(column)
    rows = [[_cell(v) for v in row] for row in frame[columns].itertuples(index=False)]
    return {"title": title, "caption": caption, "columns": columns, "rows": rows}


def render_explore(*, name: str, meta: dict, best: pd.DataFrame | None, axes: list[dict], questions: list[dict],
                   summary: pd.DataFrame, failures: pd.DataFrame, limits: list[str],
                   generated: str | None = None) -> bytes:
    """index.html of a sweep; ``axes`` items hold axis, order, rows (a slice), anchor text; figures are embedded."""
    sections = []
    for item in axes:
        png = figures.png_bytes(axis_figure(item["rows"], item["axis"], item["order"]))
        rows = item["rows"]
        family = ["model"] if "model" in rows.columns and item["axis"] != "model" and rows["model"].nunique() > 1 else []
        sections.append({
            "axis": item["axis"], "anchor": item["anchor"],
            "image": base64.b64encode(png).decode("ascii"),
            "table": html_table(rows[[item["axis"], *family, "cv", "condition", "rmse", "rmse_ci95", "ovl", "ovl_ci95",
                                      "n_seeds"]], f"{item['axis']}: RMSE and OVL (mean ± 95 % over seeds)"),
        })
    template = template_environment().get_template("explore.html.j2")
    html = template.render(
        title=f"roughsense sweep: {name}", version=__version__, citation=paper.PAPER_CITATION,
        generated=generated or _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        meta=meta, best=html_table(best, "Best design found") if best is not None and not best.empty else None,
        axes=sections, questions=questions, limits=limits,
        summary=html_table(summary, "Every design (mean ± 95 % over seeds)"),
        failures=html_table(failures, "Failed cells") if not failures.empty else None,
    )
    return html.encode("utf-8")
