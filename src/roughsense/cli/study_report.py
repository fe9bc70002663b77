"""``roughsense study``: the paper's whole analysis of a study folder, written as a report."""
from __future__ import annotations

import math
import time
from pathlib import Path

import typer

from .._util.text import counted
from ..paper import COMBINED
from ._common import DEFAULT_DPI, Dpi, FigureFormat, Jobs, check_figure_format, number_option, progress, run_inputs, stage
from ._defaults import MAX_PERMUTATIONS
from ._studies import STUDY_METAVAR, builtin_study, checked_scale, echo_scale, is_builtin, resolve_study

ORDER = 5
DEFAULT_SEED = 0


def _source_label(simulation: dict | None, *, builtin: bool, synthetic: str | None = None) -> str:
    """"simulated" whenever study.toml has a [simulation] table, with its seed; "synthetic" where [study] synthetic
    says so; "user data" otherwise."""
    if simulation is None and synthetic:
        return f"synthetic images, not measurements: {synthetic}"
    if simulation is None:
        return "user data (no [simulation] table in study.toml)"
    where = "built-in simulated study (digital twin)" if builtin else "simulated study (digital twin)"
    return f"simulated: {where}, simulation seed {simulation.get('seed', 'not recorded')}"


def register(app: typer.Typer) -> None:
    @app.command("study")
    def study_command(
        data: str = typer.Option(None, "--data", metavar=STUDY_METAVAR, show_default=False,
                                 help="Study folder (study.toml, specimens.csv, manifest.csv, ratings.csv, images/), "
                                 "or builtin (the default): the paper's study simulated with --seed, generated on "
                                 "first use and cached (a folder named builtin: ./builtin)."),
        out: Path = typer.Option(Path("report"), "--out", help="Report folder to write (index.html, CSV tables, PNG figures)."),
        seed: int = typer.Option(DEFAULT_SEED, "--seed", parser=number_option("--seed", quantity="seed"),
                                 help="Seed of the built-in simulated study (and any random draw)."),
        # 20 is model.pls_cv.DEFAULT_MAX_COMPONENTS (tests/test_architecture.py checks it): a literal keeps --help light.
        max_components: int = typer.Option(20, "--max-components",
                                           parser=number_option("--max-components", whole=True, low=1),
                                           help="Largest number of PLS components tried by CV."),
        no_loso: bool = typer.Option(
            False, "--no-loso",
            help="Skip the leave-one-specimen-out analysis (LOO only, as the paper)."),
        jobs: Jobs = None,
        force: bool = typer.Option(
            False, "--force",
            help="Replace an earlier report in a non-empty --out folder as a whole (files you added to it are kept)."),
        permutations: int = typer.Option(199, "--permutations", parser=number_option(
            "--permutations", whole=True, low=0, high=MAX_PERMUTATIONS),
            help="Specimen-level shufflings per model for the permutation control "
            f"(0: skip it; at least 199 for p-values to 0.005; at most {MAX_PERMUTATIONS})."),
        figure_format: FigureFormat = "png",
        dpi: Dpi = DEFAULT_DPI,
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

        refuse_inputs(out, run_inputs(study=data))  # a report swapped in over its own study: refused, --force or not
        started = time.perf_counter()
        # The report is built beside --out and swapped in whole; making that folder now fails an unwritable or
        # occupied --out (or one another run is writing) before minutes of work, not after.
        with output_lock(out, command="study"), staged_folder(open_report_dir(out, force)) as staging:
            index, root, builtin, summary = _analyse(
                staging, data=data, out=out, seed=seed, max_components=max_components, no_loso=no_loso, jobs=jobs,
                permutations=permutations, style=FigureStyle(check_figure_format(figure_format), dpi))
        for line in summary:  # once the report is in place: nothing is announced that was not written
            typer.echo(line)
        where = f' (built-in, seed {seed}; "builtin" names it in --data and --study)' if builtin else ""
        typer.echo(f"Study folder: {Path(root).resolve()}{where}")
        typer.echo(f"Report written to {index} in {time.perf_counter() - started:.1f} s")


def _analyse(staging, *, data: str | None, out: Path, seed: int, max_components: int, no_loso: bool,
             jobs: int, permutations: int, style) -> tuple[Path, Path, bool, list[str]]:
    """The analysis of a study (``--data`` or the built-in one), its report written into the folder ``staging``.

    Returns index.html, the study folder, whether it is the built-in study, and the summary lines to print.
    """
    import warnings

    from .._util import cache
    from ..analysis import dataset
    from ..analysis.study_analysis import CV_SCHEMES, analyse_study
    from ..errors import RoughsenseWarning
    from ..report import write_report_files

    builtin = data is None or is_builtin(data)
    root = builtin_study(seed, jobs) if data is None else resolve_study(data, seed=seed, jobs=jobs)
    study, scale = checked_scale(_read_folder(root, builtin=builtin))
    definition = dataset.spectrum_for(study).feature_definition()
    features, was_cached = cache.cached_frame(
        cache.features_key(study, definition),
        lambda: dataset.study_features(study, n_jobs=jobs, progress=progress),
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RoughsenseWarning)
        analysis = analyse_study(
            study, features=features, max_components=max_components,
            cv_schemes=("loo",) if no_loso else CV_SCHEMES, progress=progress,
            n_permutations=permutations, seed=seed, n_jobs=jobs,
        )
    for warning in caught:  # shown once on the terminal, and kept in the report
        warnings.showwarning(warning.message, warning.category, warning.filename, warning.lineno)
    meta = {
        "study folder": str(Path(root).resolve()),
        "source": _source_label(study.simulation, builtin=builtin, synthetic=study.synthetic),
        "images": f"{len(study.manifest)} ({', '.join(study.pads)} {'pad' if len(study.pads) == 1 else 'pads'}; "
                  f"{counted(len(study.specimens), 'specimen')})",
        "features": "from cache" if was_cached else "extracted",
        "scale": scale,
    }
    if caught:
        meta["warnings"] = "; ".join(str(w.message) for w in caught)
    with stage("writing the report"):
        write_report_files(analysis, staging, meta=meta, style=style, n_jobs=jobs)
    summary = list(unseen_lines(analysis))
    loo = analysis.results("loo")
    loo = loo[loo["model"] == "pls"]
    for (pad, condition), group in loo.groupby(["pad", "condition"], sort=False):
        summary.append(f"{pad:>12} {condition:>9}: mean RMSE {group['rmse'].mean():.3f}, mean OVL "
                       f"{group['ovl'].mean():.3f}, "
                       f"{counted(analysis.condition_fit(pad, condition, 'loo').best_n_components, 'component')} "
                       "(pls, LOO)")
    echo_scale(scale)
    return out / "index.html", root, builtin, summary


def which_model_line(unseen) -> str:
    """Which model to use for what, in one sentence: the report's own verdict (``report.answer.recommended_model``),
    so the console and the report never disagree; PLS reproduces the paper."""
    from ..model.families import DEFAULT_MODEL, PAPER_MODEL
    from ..report.answer import NO_MODEL, recommended_model

    passes = unseen["passes"].fillna(False).astype(bool)
    below = unseen["rmse"] < unseen["null_rmse"]  # a pass on pooled RMSE alone is not counted as one
    parts = []
    for name, rows in unseen.groupby("model", sort=False):
        pooled_only = int((passes[rows.index] & ~below[rows.index]).sum())
        parts.append(f"{name} passes in {int((passes[rows.index] & below[rows.index]).sum())} of {len(rows)}"
                     + (f" (and in {pooled_only} on pooled RMSE only)" if pooled_only else ""))
    controls = f"Controls with a grating left out, per pad x condition: {', '.join(parts)}."
    model = recommended_model(unseen)
    if model is None:
        return f"Which model to use: none. {NO_MODEL} {PAPER_MODEL} reproduces the paper. {controls}"
    default = " (roughsense fit's default)" if model == DEFAULT_MODEL else f" (roughsense fit --model {model})"
    return (f"Which model to use: {model}{default} to score surfaces left out of training, where it passes its "
            f"controls; {PAPER_MODEL} to reproduce the paper. {controls}")


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


def unseen_lines(analysis) -> list[str]:
    """The question users ask first, in a headline and one line per pad: how well each model predicts an unseen
    surface (nested LOSO mean per-specimen RMSE against the training mean's, permutation p, Spearman's rho)."""
    from ..report.tables import permutation_p_text

    unseen = analysis.unseen_summary()
    if unseen.empty:
        return ["Held-out surfaces: not estimated (--no-loso); the LOO lines below describe specimens seen in training."]
    condition = COMBINED if (unseen["condition"] == COMBINED).any() else str(unseen["condition"].iloc[-1])
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
    return [*lines, which_model_line(unseen)]
