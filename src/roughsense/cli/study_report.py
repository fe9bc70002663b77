"""``roughsense study``: the paper's whole analysis of a study folder, written as a report.

The command computes nothing and words nothing of its own: it runs :func:`analyse_study`, has the report package
write the folder, and echoes the lines that package builds (roughsense.report.answer, roughsense.report.provenance).
"""
from __future__ import annotations

import time
from pathlib import Path

import typer

from .. import defaults
from ._common import Dpi, FigureFormat, Jobs, check_figure_format, number_option, progress, run_inputs, stage
from ._studies import STUDY_METAVAR, builtin_study, checked_scale, echo_scale, is_builtin, resolve_study

ORDER = 5


def register(app: typer.Typer) -> None:
    @app.command("study")
    def study_command(
        study: str = typer.Option(None, "--study", metavar=STUDY_METAVAR, show_default=False,
                                 help="Study folder (study.toml, specimens.csv, manifest.csv, ratings.csv, images/), "
                                 "or builtin (the default): the paper's study simulated with --seed, generated on "
                                 "first use and cached (a folder named builtin: ./builtin); builtin:SET simulates "
                                 "it on a specimen set of the twin, e.g. builtin:paper+grooves (the paper's 14 and "
                                 "8 rectangles whose land is not half the period)."),
        out: Path = typer.Option(Path("report"), "--out", "-o",
                                 help="Report folder to write (index.html, CSV tables, PNG figures)."),
        seed: int = typer.Option(defaults.SEED, "--seed", parser=number_option("--seed", quantity="seed"),
                                 help="Seed of the built-in simulated study (and any random draw)."),
        max_components: int = typer.Option(defaults.MAX_COMPONENTS, "--max-components",
                                           parser=number_option("--max-components", whole=True, low=1),
                                           help="Largest number of PLS components tried by CV."),
        no_loso: bool = typer.Option(
            False, "--no-loso",
            help="Skip the leave-one-specimen-out analysis (LOO only, as the paper)."),
        jobs: Jobs = None,
        force: bool = typer.Option(
            False, "--force",
            help="Replace an earlier report in a non-empty --out folder as a whole (files you added to it are kept)."),
        permutations: int = typer.Option(defaults.PERMUTATIONS, "--permutations", parser=number_option(
            "--permutations", whole=True, low=0, high=defaults.MAX_PERMUTATIONS),
            help="Specimen-level shufflings per model for the permutation control "
            f"(0: skip it; at least 199 for p-values to 0.005; at most {defaults.MAX_PERMUTATIONS})."),
        figure_format: FigureFormat = "png",
        dpi: Dpi = defaults.DPI,
    ) -> None:
        """Reproduce the paper's analysis on a study folder and write a report.

        For each pad and predictor set (1N, 2N, 3N, combined): spectral features, the cross-validated RMSE over
        1..max components and the chosen count, out-of-fold predictions, per-specimen mean ± SD, OVL and RMSE with
        rectangular / circular / overall summaries, and Wilcoxon signed-rank tests -- under the paper's leave-one-out CV
        and under leave-one-specimen-out CV, side by side with the paper's published values.
        """
        from .._util.atomic import refuse_inputs, staged_folder
        from .._util.lock import output_lock
        from ..report import FigureStyle, open_report_dir

        refuse_inputs(out, run_inputs(study=study))  # a report swapped in over its own study: refused, --force or not
        started = time.perf_counter()
        # The report is built beside --out and swapped in whole; making that folder now fails an unwritable or
        # occupied --out (or one another run is writing) before minutes of work, not after.
        with output_lock(out, command="study"), staged_folder(open_report_dir(out, force)) as staging:
            index, root, builtin, summary = _analyse(
                staging, study=study, out=out, seed=seed, max_components=max_components, no_loso=no_loso, jobs=jobs,
                permutations=permutations, style=FigureStyle(check_figure_format(figure_format), dpi))
        for line in summary:  # once the report is in place: nothing is announced that was not written
            typer.echo(line)
        where = f' (built-in, seed {seed}; "{study or "builtin"}" names it in --study)' if builtin else ""
        typer.echo(f"Study folder: {Path(root).resolve()}{where}")
        typer.echo(f"Report written to {index} in {time.perf_counter() - started:.1f} s")


def _analyse(staging, *, study: str | None, out: Path, seed: int, max_components: int, no_loso: bool,
             jobs: int, permutations: int, style) -> tuple[Path, Path, bool, list[str]]:
    """The analysis of a study (``--study`` or the built-in one), its report written into the folder ``staging``.

    Returns index.html, the study folder, whether it is the built-in study, and the summary lines to print.
    """
    import warnings

    from .._util import cache
    from .._util.text import counted
    from ..analysis import dataset
    from ..analysis.results import CV_SCHEMES
    from ..analysis.study_analysis import analyse_study
    from ..errors import RoughsenseWarning
    from ..report import write_report_files
    from ..report.answer import console_lines
    from ..report.provenance import source_label

    builtin = study is None or is_builtin(study)
    root = builtin_study(seed, jobs) if study is None else resolve_study(study, seed=seed, jobs=jobs)
    folder, scale = checked_scale(_read_folder(root, builtin=builtin))
    definition = dataset.spectrum_for(folder).feature_definition()
    features, was_cached = cache.cached_frame(
        cache.features_key(folder, definition),
        lambda: dataset.study_features(folder, n_jobs=jobs, progress=progress),
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RoughsenseWarning)
        analysis = analyse_study(
            folder, features=features, max_components=max_components,
            cv_schemes=("loo",) if no_loso else CV_SCHEMES, progress=progress,
            n_permutations=permutations, seed=seed, n_jobs=jobs,
        )
    for warning in caught:  # shown once on the terminal, and kept in the report
        warnings.showwarning(warning.message, warning.category, warning.filename, warning.lineno)
    meta = {
        "study folder": str(Path(root).resolve()),
        "source": source_label(analysis.provenance, builtin=builtin),
        "images": f"{len(folder.manifest)} ({', '.join(folder.pads)} {'pad' if len(folder.pads) == 1 else 'pads'}; "
                  f"{counted(len(folder.specimens), 'specimen')})",
        "features": "from cache" if was_cached else "extracted",
        "scale": scale,
    }
    if caught:
        meta["warnings"] = "; ".join(str(w.message) for w in caught)
    with stage("writing the report"):
        write_report_files(analysis, staging, meta=meta, style=style, n_jobs=jobs)
    echo_scale(scale)
    return out / "index.html", root, builtin, console_lines(analysis)


def _read_folder(root, *, builtin: bool):
    """read_study, which stops at the first problem: its line says how to see them all (``roughsense check``)."""
    import shlex

    from ..errors import RoughsenseError
    from ..io.study import read_study

    try:
        return read_study(root, require_ratings=True)
    except RoughsenseError as exc:
        if not builtin and Path(root).is_dir():  # a missing folder has nothing for check to list
            exc.message = f"{exc.message}; run `roughsense check {shlex.quote(str(root))}` to list every problem"
        raise
