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
from .html import FigureStyle, template_environment

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
            panel.errorbar(x, group[metric].to_numpy(float), yerr=_bars(group, metric), color=colour, marker=marker,
                           capsize=3, linestyle=line, label=name)
    for panel, metric in zip(panels, ("RMSE (perceived units)", "OVL")):
        panel.set_xlabel(axis)
        panel.set_ylabel(metric)
        if not numeric:
            panel.set_xticks(range(len(labels)), labels, rotation=20 if max(map(len, labels)) > 8 else 0)
        panel.grid(alpha=0.3)
    panels[0].legend(frameon=False)
    fig.tight_layout()
    return fig


def _bars(group: pd.DataFrame, metric: str) -> np.ndarray:
    """Error bars from the interval's clipped ends where the rows have them (no bar below 0 RMSE or outside OVL's
    [0, 1]); none without an interval (too few seeds)."""
    mean = group[metric].to_numpy(float)
    if f"{metric}_ci_low" in group.columns:
        low, high = group[f"{metric}_ci_low"].to_numpy(float), group[f"{metric}_ci_high"].to_numpy(float)
        return np.nan_to_num(np.vstack([mean - low, high - mean]), nan=0.0)
    return np.nan_to_num(group[f"{metric}_ci95"].to_numpy(float), nan=0.0)


def _cell(value, digits: int = 3) -> str:
    if isinstance(value, (float, np.floating)):
        return "—" if not np.isfinite(value) else f"{value:.{digits}g}" if abs(value) >= 100 else f"{value:.{digits}f}"
    return str(value)


def _interval(mean: float, low: float, high: float, half: float) -> str:
    """``0.388 [0.350, 0.417]``; ``(clipped)`` when the range cut the t-interval; the mean alone without one."""
    if not np.isfinite(mean):
        return "—"
    if not (np.isfinite(low) and np.isfinite(high)):
        return f"{mean:.3f}"
    clipped = np.isfinite(half) and (low > mean - half + 1e-12 or high < mean + half - 1e-12)
    return f"{mean:.3f} [{low:.3f}, {high:.3f}]" + (" (clipped)" if clipped else "")


def _joined(frame: pd.DataFrame, column: str) -> list[str] | None:
    """A metric joined with its interval columns (``_ci_low``/``_ci_high``, else ``_ci95``), or None."""
    low, high, half = (f"{column}_ci_low", f"{column}_ci_high", f"{column}_ci95")
    nan = pd.Series(np.nan, index=frame.index)
    if low in frame.columns and high in frame.columns:
        return [_interval(m, lo, hi, h) for m, lo, hi, h in
                zip(frame[column], frame[low], frame[high], frame.get(half, nan))]
    if half in frame.columns:
        return [("—" if not np.isfinite(m) else f"{m:.3f}" + (f" ± {h:.3f}" if np.isfinite(h) else ""))
                for m, h in zip(frame[column], frame[half])]
    return None


SUFFIXES = ("_ci95", "_ci_low", "_ci_high")


def html_table(frame: pd.DataFrame, title: str, caption: str = "") -> dict:
    """A table for the template: each metric joined with its interval as 'mean [low, high]' (or 'mean ± half')."""
    frame = frame.copy()
    columns = []
    for column in list(frame.columns):
        if column.endswith(SUFFIXES) and any(column[:-len(s)] in frame.columns for s in SUFFIXES if column.endswith(s)):
            continue
        joined = _joined(frame, column)
        if joined is not None:
            frame[column] = joined
        columns.append(column)
    rows = [[_cell(v) for v in row] for row in frame[columns].itertuples(index=False)]
    return {"title": title, "caption": caption, "columns": columns, "rows": rows}


def axis_figure_files(axes: list[dict], style: FigureStyle = FigureStyle()) -> tuple[dict[str, bytes], list[dict]]:
    """Each axis's figure as a file in ``style``'s format (``axis_<name>.<ext>``) and its page entry (what the page
    embeds: the file itself, or for PDF a PNG of it; name; MIME type)."""
    files, shown = {}, []
    for item in axes:
        fig = axis_figure(item["rows"], item["axis"], item["order"])
        name = f"axis_{item['axis']}.{style.figure_format}"
        files[name] = figures.figure_bytes(fig, style.figure_format, dpi=style.dpi, close=False)
        kind = "png" if style.figure_format == "pdf" else style.figure_format
        page = files[name] if kind == style.figure_format else figures.figure_bytes(fig, kind, dpi=style.dpi, close=False)
        figures.plt.close(fig)
        shown.append({"name": name, "mime": figures.MIME_TYPES[kind],
                      "data": base64.b64encode(figures.page_preview(page) if kind == "png" else page).decode("ascii")})
    return files, shown


def render_explore(*, name: str, meta: dict, best: pd.DataFrame | None, axes: list[dict], questions: list[dict],
                   summary: pd.DataFrame, failures: pd.DataFrame, limits: list[str],
                   generated: str | None = None, notes: list[str] | None = None, rule: str = "",
                   shown: list[dict] | None = None) -> bytes:
    """index.html of a sweep; ``axes`` items hold axis, order, rows (a slice), anchor text; ``shown``: each axis's
    figure as :func:`axis_figure_files` gives it (PNG at the default resolution when None)."""
    shown = shown if shown is not None else axis_figure_files(axes)[1]
    sections = []
    for item, figure in zip(axes, shown):
        rows = item["rows"]
        family = ["model"] if "model" in rows.columns and item["axis"] != "model" and rows["model"].nunique() > 1 else []
        sections.append({
            "axis": item["axis"], "anchor": item["anchor"], "figure": figure,
            "table": html_table(rows[[item["axis"], *family, "cv", "condition",
                                      *[c for m in ("rmse", "null_rmse", "ovl") for c in rows.columns
                                        if c == m or c.startswith(f"{m}_ci")],
                                      "n_seeds"]], f"{item['axis']}: RMSE, the training mean's RMSE and OVL "
                                                   "(mean [95 % interval] over seeds)"),
        })
    template = template_environment().get_template("explore.html.j2")
    html = template.render(
        title=f"roughsense sweep: {name}", version=__version__, citation=paper.PAPER_CITATION,
        generated=generated or _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        meta=meta, notes=notes or [], rule=rule,
        best=html_table(best, "Best design found") if best is not None and not best.empty else None,
        axes=sections, questions=questions, limits=limits,
        summary=html_table(summary, "Every design (mean [95 % interval] over seeds)"),
        failures=html_table(failures, "Failed cells") if not failures.empty else None,
    )
    return html.encode("utf-8")
