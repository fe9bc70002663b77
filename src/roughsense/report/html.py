"""Write a study analysis as a report folder: a self-contained index.html, CSV tables and PNG figures.

Everything is rendered in memory, written into a folder beside ``--out`` and swapped in whole
(:class:`roughsense._util.atomic.FolderSwap`), so a failure or a kill never leaves a half-written report, and a
report replaced with ``--force`` keeps no file of the earlier one. index.html embeds its figures as data
URIs so it opens offline and can be mailed as one file.

The page leads with the question a user asks (how well does each model predict a surface left out of training?), then
the paper's own protocol (LOO) and tables, which keep showing the paper's PLS as the paper did; every other model
family gets its own, labelled tables beside them.
"""
from __future__ import annotations

import base64
import datetime as _dt
import os
import re
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import jinja2
import pandas as pd

from .. import __version__, defaults, paper
from .._util import atomic, interrupt
from .._util.text import spreadsheet_safe
from .._util.workers import process_pool, results_in_order, stop_pool
from ..analysis.claims import VERDICT_RULE, VERDICTS
from ..analysis.held_out import SCHEME_WORDS
from ..errors import PASS_FORCE, OutputExistsError
from ..io.names import check_name
from ..model.registry import PAPER_MODEL, registry
from . import control_tables, figures, paper_tables, unseen_tables
from . import provenance as source
from .answer import answer_lines, answer_table, evidence_sentence
from .paper_tables import is_paper_model
from .presses import combined_press_words, presses_figure, presses_table


def template_environment() -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.PackageLoader("roughsense.report", "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )


REPORT_TABLES = ("index.html", "results.csv", "results_loso.csv", "cv.csv", "tests.csv", "predictions.csv",
                 "components.csv", "controls.csv", "claims.csv", "paper_predictive.csv", "held_out.csv", "presses.csv")
_REPORT_FIGURE = re.compile(r"^(spectra_.+|ovl_sd_.+|cv_curves|predicted_vs_perceived_.+|unseen_surfaces|presses_per_surface)"
                            r"\.(png|svg|pdf)$")


@dataclass(frozen=True)
class FigureStyle:
    """How the report's figures are written: ``png``, ``svg`` or ``pdf``, at ``dpi`` for raster parts.

    The page embeds PNG and SVG figures as they are; a browser does not show a PDF in <img>, so a PDF report
    embeds a PNG of the same figure and links the PDF file beside index.html.
    """

    figure_format: str = "png"
    dpi: int = defaults.DPI


def report_owned(rel: Path) -> bool:
    """Is this entry of a report folder one the report writes? (Everything else is a user's and is kept.)"""
    return len(rel.parts) == 1 and (rel.name in REPORT_TABLES or bool(_REPORT_FIGURE.match(rel.name)))


def check_report_dir(out_dir: Path, force: bool) -> None:
    """A non-empty folder needs ``force``, unless it holds only an unfinished report of roughsense's own."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise OutputExistsError("exists and is not a folder", path=out_dir)
    if not out_dir.is_dir() or force:
        return
    entries = [p for p in out_dir.iterdir() if not atomic.is_temporary(p)]
    unfinished = not (out_dir / "index.html").exists() and all(report_owned(Path(p.name)) for p in entries)
    if entries and not unfinished:
        raise OutputExistsError(f"report folder exists and is not empty; {PASS_FORCE} to replace the report in it", path=out_dir)


def open_report_dir(out_dir: str | os.PathLike[str], force: bool) -> atomic.FolderSwap:
    """Check ``out_dir`` and create its staging folder: an unwritable place fails here, before any analysis."""
    atomic.clean_leftovers(out_dir)  # first: a killed swap's old folder may have to come back
    check_report_dir(Path(out_dir), force)
    return atomic.FolderSwap(out_dir, owned=report_owned)


def _csv_bytes(frame: pd.DataFrame) -> bytes:
    """A report table as CSV, its text cells formula-safe: it is opened in a spreadsheet."""
    return spreadsheet_safe(frame).to_csv(index=False, lineterminator="\n", float_format="%.6g").encode("utf-8")


def plain_words(analysis) -> list[str]:
    """The report's opening paragraphs: what is a property of the simulator, what is a finding, what failed."""
    lines = source.source_paragraphs(analysis.provenance)
    if not analysis.controls.empty:
        failing = failing_models(analysis)
        if failing:
            lines.append(f"{len(failing)} of {len(analysis.controls)} models fail their controls (no better than "
                         "specimen-shuffled targets and/or the training mean; listed below). A LOO model that fails is "
                         "recognising specimens rather than reading roughness; a LOSO model that fails does not "
                         "predict a grating left out of training. Their RMSE and OVL are no evidence for the method.")
        else:
            lines.append("Every model beats both its controls (specimen-shuffled targets and the training mean).")
    if not analysis.claims.empty:
        counts = analysis.claims["verdict"].value_counts()
        lines.append(", ".join(f"{int(counts.get(v, 0))} {v}" for v in VERDICTS if counts.get(v, 0))
                     + " of the paper's claims, by pad and CV scheme (Claims below).")
    return lines


def failing_models(analysis) -> list[str]:
    """Every model that fails its controls, as "model pad condition (CV)": listed once, collapsed, on the page."""
    if analysis.controls.empty:
        return []
    failing = analysis.controls[~analysis.controls["passes"].astype(bool)]
    return [f"{getattr(r, 'model', PAPER_MODEL)} {r.pad} {r.condition} ({str(r.cv).upper()})" for r in failing.itertuples()]


def unseen_words(analysis) -> list[str]:
    """What the "held out of training" section can and cannot claim: whose images and ratings these are."""
    if not any(f.cv == "loso" for f in analysis.fits):
        return [source.NO_LOSO_SECTION]
    lines = ["Each specimen here is predicted by models fitted without any of its images: the estimate of what the "
             "sensor would say about a new surface. A model is worth using on new surfaces only where its error is "
             "clearly below the training mean's and it beats specimen-shuffled targets." + evidence_sentence(analysis)]
    return [*lines, *source.unseen_source_words(analysis.provenance)]


def render_report(analysis, *, meta: dict | None = None, style: FigureStyle = FigureStyle(),
                  n_jobs: int = 1) -> dict[str, bytes]:
    """Every file of the report, by name, as bytes; ``style``: the figures' format and resolution; ``n_jobs``:
    processes drawing the figures (the same bytes for any number).

    The figures are handed to the worker processes first and the tables built while they draw, so the page's two
    halves overlap instead of following each other."""
    meta = dict(meta or {})
    has_loso = any(f.cv == "loso" for f in analysis.fits)
    cv_schemes = ["loo", "loso"] if has_loso else ["loo"]
    results = {cv: analysis.results(cv) for cv in cv_schemes}
    chosen = analysis.chosen_components()
    files = _data_files(analysis, results, chosen)
    unseen_job = _unseen_figure(results, analysis.perceived, analysis.headline_condition)
    presses_job = _presses_figure(analysis)
    jobs = [job for job in (unseen_job, presses_job) if job] + _figures(analysis, results, chosen, cv_schemes)
    with _figure_renderer(analysis, jobs, style, n_jobs) as rendered:
        page = _page_context(analysis, results, chosen, cv_schemes, meta)
        figure_list = rendered()
    for entry in figure_list:
        files[entry.pop("file")] = entry.pop("bytes")
    page["unseen_figure"] = figure_list.pop(0) if unseen_job else None
    page["presses_figure"] = figure_list.pop(0) if presses_job else None
    template = template_environment().get_template("report.html.j2")
    files["index.html"] = template.render(**page, figures=figure_list).encode("utf-8")
    return files


def _page_context(analysis, results: dict[str, pd.DataFrame], chosen: pd.DataFrame, cv_schemes: list[str],
                  meta: dict) -> dict:
    """Everything the page's template shows but the figures: its tables and words."""
    paper_pads = tuple(analysis.paper_pads)
    paper_chosen = chosen[chosen["model"].map(is_paper_model).astype(bool)]
    return dict(
        title=f"roughsense report: {analysis.study_name}",
        study_name=analysis.study_name,
        version=__version__,
        generated=meta.pop("generated", _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")),
        meta=meta,
        citation=paper.PAPER_CITATION,
        headline=control_tables.headline_table(analysis, paper_pads, results=results),
        unseen=unseen_tables.unseen_table(analysis.unseen, analysis.controls),
        unseen_words=unseen_words(analysis),
        held_out=unseen_tables.held_out_table(analysis.held_out, SCHEME_WORDS),
        presses=presses_table(analysis.presses, analysis.presses_needed),
        unsure=unseen_tables.unsure_table(analysis.unsure),
        components=paper_tables.components_table(
            paper_chosen.drop(columns="model"),
            {(f.pad, f.condition): f.per_specimen for f in analysis.fits
             if f.cv == "loso" and is_paper_model(f.model)},
            paper_pads,
        ),
        tests=paper_tables.tests_table(analysis.tests, paper_values=set(paper_pads) == set(paper.PAPER_PADS)),
        claims=control_tables.claims_table(analysis.claims, paper_pads, analysis.controls),
        verdict_rule=VERDICT_RULE,
        controls=control_tables.controls_report_table(analysis.controls),
        paper_predictive=unseen_tables.paper_predictive_table(analysis.paper_predictive),
        simulation=analysis.provenance.settings,
        simulated_banner=source.simulated_banner(analysis.provenance),
        paper_note=analysis.paper_note,
        findings=plain_words(analysis),
        failing=failing_models(analysis),
        answer=answer_lines(analysis),
        answer_table=answer_table(analysis),
        sections=_sections(analysis, results, cv_schemes),
        max_components=analysis.max_components,
        reference_specimen=analysis.reference_specimen,
        method_families=[f for f in registry() if f.name in analysis.models and not f.paper and f.description],
    )


def _data_files(analysis, results: dict[str, pd.DataFrame], chosen: pd.DataFrame) -> dict[str, bytes]:
    """The report's CSV files: every number behind its tables and figures."""
    files = {"results.csv": _csv_bytes(results["loo"])}
    if "loso" in results:
        files["results_loso.csv"] = _csv_bytes(results["loso"])
    files["cv.csv"] = _csv_bytes(analysis.cv_table())
    files["tests.csv"] = _csv_bytes(analysis.tests)
    files["predictions.csv"] = _csv_bytes(analysis.predictions())
    files["components.csv"] = _csv_bytes(chosen)
    files["controls.csv"] = _csv_bytes(analysis.controls)
    files["claims.csv"] = _csv_bytes(analysis.claims)
    files["paper_predictive.csv"] = _csv_bytes(analysis.paper_predictive)
    if not analysis.held_out.empty:
        files["held_out.csv"] = _csv_bytes(analysis.held_out)
    if not analysis.presses.empty:
        files["presses.csv"] = _csv_bytes(analysis.presses)
    return files


class FigureJob(NamedTuple):
    """One figure of the page, drawn where it is rendered (a worker process or here): ``draw(*args, **kwargs)``."""

    stem: str
    draw: Callable
    args: tuple
    kwargs: dict
    caption: str


def _render_figure(job: FigureJob, stamp: str | None, style: FigureStyle) -> dict:
    """Draw and render one figure (``style``'s format), stamped if the data are simulated: its page entry, with its
    file's name and bytes (``file``, ``bytes``)."""
    name = f"{job.stem}.{style.figure_format}"
    fig = job.draw(*job.args, **job.kwargs)
    caption = job.caption
    if stamp is not None:
        figures.mark_simulated(fig, stamp)
        caption = source.STAMPED_CAPTION_PREFIX + caption
    data = figures.figure_bytes(fig, style.figure_format, dpi=style.dpi, close=False)
    shown = "png" if style.figure_format == "pdf" else style.figure_format
    page = data if shown == style.figure_format else figures.figure_bytes(fig, shown, dpi=style.dpi, close=False)
    if shown == "png":
        page = figures.page_preview(page)
    figures.plt.close(fig)
    return {"name": name, "caption": caption, "mime": figures.MIME_TYPES[shown],
            "data": base64.b64encode(page).decode("ascii"), "file": name, "bytes": data}


@contextmanager
def _figure_renderer(analysis, jobs: list[FigureJob], style: FigureStyle, n_jobs: int):
    """Start rendering every figure once, in ``n_jobs`` worker processes when there are more than one (matplotlib
    draws one figure per process at a time); yields a call that waits for them and returns their page entries in
    the jobs' order (the bytes the same for any ``n_jobs``). In one process the figures are drawn by that call."""
    for job in jobs:
        check_name(f"{job.stem}.{style.figure_format}", what="report file name")  # built from pad names
    stamp = source.figure_stamp(analysis.provenance)
    n_jobs = min(n_jobs, len(jobs))
    if n_jobs <= 1:
        yield lambda: [_checked(_render_figure, job, stamp, style) for job in jobs]
        return
    pool = process_pool(n_jobs)
    pending = [pool.submit(_render_figure, job, stamp, style) for job in jobs]
    try:
        yield lambda: results_in_order(pending)  # a stop is honoured while they draw
    except BaseException:  # the page failed or the run was stopped: its figures are neither waited for nor kept
        stop_pool(pool)
        raise
    pool.shutdown(wait=True)


def _checked(render: Callable, *args):
    """One figure drawn in this process, after a safe point: a stop waits for one figure at most."""
    interrupt.check()
    return render(*args)


def _unseen_figure(results: dict[str, pd.DataFrame], perceived: pd.DataFrame, condition: str) -> FigureJob | None:
    """Predicted against perceived per specimen under LOSO, every model, the headline condition."""
    if "loso" not in results:
        return None
    models = ", ".join(dict.fromkeys(results["loso"]["model"]))
    return FigureJob("unseen_surfaces", figures.unseen_figure, (results["loso"], perceived, condition), {},
                     f"A grating left out of training: each specimen's leave-one-specimen-out prediction (mean ± SD over "
                     f"its repetitions) against its perceived roughness, {condition} condition, {models}; grey: identity.")


def _presses_figure(analysis) -> FigureJob | None:
    if analysis.presses.empty:
        return None
    return FigureJob("presses_per_surface", presses_figure, (analysis.presses,), {},
                     "Presses per surface: the peak law's error on a grating left out of training, read from k of its "
                     "presses, per pad and condition; dashed: the training mean's."
                     + combined_press_words(analysis.presses["condition"]))


def _figures(analysis, results: dict[str, pd.DataFrame], chosen: pd.DataFrame, cv_schemes: list[str]) -> list[FigureJob]:
    """Every figure of the Figures section, to be drawn (:func:`_render_figures`)."""
    paper_pads = tuple(analysis.paper_pads)
    freq_columns = [c for c in analysis.mean_spectra.columns if c not in ("pad", "specimen", "condition")]
    paper_model = next((model for model in analysis.models if is_paper_model(model)), None)
    paper_rows = {cv: frame[frame["model"] == paper_model] for cv, frame in results.items()}
    cv_table = analysis.cv_table()
    jobs = [FigureJob(f"spectra_{pad}", figures.spectra_figure, (analysis.mean_spectra, freq_columns, pad,
                                                                 analysis.shapes), {},
                      f"Mean normalised amplitude spectra per specimen and force, {pad} pad (cf. the paper's Fig. 7).")
            for pad in analysis.pads]
    if paper_model is not None:
        jobs.append(FigureJob(
            "cv_curves", figures.cv_curves_figure,
            (cv_table[cv_table["model"] == paper_model], chosen[chosen["model"] == paper_model]),
            {}, "Cross-validated RMSE of PLS against the number of components, LOO (top) and LOSO (bottom); red circles "
            "mark the chosen count (cf. Fig. 8). At 0 components (not drawn; in cv.csv) the model predicts the "
            "training mean."))
        jobs += [FigureJob(f"ovl_sd_{pad}", figures.ovl_sd_figure, (paper_rows["loo"], analysis.perceived, pad, analysis.shapes),
                           {"paper": pad in paper_pads},
                           f"OVL per specimen and SD of participants vs predictions, {pad} pad, PLS, LOO (cf. Fig. 9).")
                 for pad in analysis.pads]
    for model in analysis.models:
        for cv in cv_schemes:
            rows = results[cv][results[cv]["model"] == model]
            suffix = "" if is_paper_model(model) else f"_{model}"
            jobs.append(FigureJob(
                f"predicted_vs_perceived_{cv}{suffix}", figures.predicted_vs_perceived_figure,
                (rows, analysis.perceived, cv), {"paper": paper_pads if is_paper_model(model) else False},
                f"Predicted (mean ± SD over repetitions) against perceived roughness, {model}, {cv.upper()}; "
                "grey: identity."))
    return jobs


def _sections(analysis, results: dict[str, pd.DataFrame], cv_schemes: list[str]) -> list[dict]:
    """Per CV scheme and pad, the paper's Tables 1-6 layout: predictions, OVL, RMSE and predictive OVL.

    The paper's PLS first, as the paper showed it; every other family's tables follow, titled with its name.
    """
    specimens = figures._specimen_order(analysis.perceived["specimen"], analysis.shapes)
    paper_pads = tuple(analysis.paper_pads)
    sections = []
    columns = ("ovl", "rmse", "ovl_predictive")
    for cv in cv_schemes:
        pads = []
        summary = {(model, column): analysis.summary(cv, column, model, results[cv])  # every pad's rows at once
                   for model in analysis.models for column in columns}
        for pad in analysis.pads:
            pad_tables = []
            for model in analysis.models:
                rows = results[cv][results[cv]["model"] == model]
                summaries = {column: summary[(model, column)] for column in columns}
                flags = control_tables.control_flags(analysis.controls, pad, cv, model)
                kwargs = {"paper_values": pad in paper_pads, "flags": flags, "model": model}
                pad_tables.append(paper_tables.prediction_table(rows, analysis.perceived, pad, specimens, cv, **kwargs))
                pad_tables += [paper_tables.metric_table(rows, summaries[column], pad, specimens, column, cv, **kwargs)
                               for column in columns]
            pads.append({"pad": pad, "tables": pad_tables})
        sections.append({"cv": cv, "pads": pads})
    return sections


def write_report(analysis, out_dir: str | os.PathLike[str], *, meta: dict | None = None, force: bool = False,
                 style: FigureStyle = FigureStyle(), n_jobs: int = 1) -> Path:
    """Write the report folder whole: built beside ``out_dir`` and swapped in, so a failure leaves it as it was."""
    with atomic.staged_folder(open_report_dir(out_dir, force)) as folder:
        write_report_files(analysis, folder, meta=meta, style=style, n_jobs=n_jobs)
    return Path(out_dir) / "index.html"


def write_report_files(analysis, folder: Path, *, meta: dict | None = None, style: FigureStyle = FigureStyle(),
                       n_jobs: int = 1) -> None:
    """The report's files into ``folder``, a staging folder whose swap the caller owns (the study command opens it
    before the analysis, so an unwritable ``--out`` fails before minutes of work)."""
    for name, data in render_report(analysis, meta=meta, style=style, n_jobs=n_jobs).items():
        atomic.write_bytes(folder / name, data)
