"""``roughsense explore``: sweep designs of the twin on Dask and report what they change (docs/explore.md)."""
from __future__ import annotations

from pathlib import Path

import typer

from .. import defaults
from .._util.text import counted
from ._common import JOBS_HELP, Dpi, FigureFormat, check_figure_format, number_option, progress

_JOBS = number_option("--jobs", whole=True)

ORDER = 45


def register(app: typer.Typer) -> None:
    @app.command("explore")
    def explore(
        sweep_file: Path = typer.Argument(
            ..., metavar="SWEEP.toml",
            help="The sweep file: settings in \\[sweep], the grid in \\[axes] (docs/explore.md)."),
        out: Path = typer.Option(..., "--out", "-o",
                                 help="Output folder: results/ (Parquet), specimens/, sweep.toml, index.html."),
        jobs: int | None = typer.Option(None, "--jobs", "-j", parser=_JOBS, show_default=False, help=JOBS_HELP),
        scheduler: str | None = typer.Option(None, "--scheduler", help="Address (tcp://host:8786) or scheduler file (.json) "
                                             "of an existing Dask cluster, or slurm, pbs or sge: --jobs workers as "
                                             "batch jobs (default 1; dask-jobqueue, configured in Dask's jobqueue.yaml), "
                                             "instead of a local cluster of one worker process per core (at most 4 per "
                                             "core)."),
        force: bool = typer.Option(False, "--force", help="Use a folder that holds another sweep's results (they are "
                                   "replaced) or other files (kept)."),
        figure_format: FigureFormat = "png",
        dpi: Dpi = defaults.DPI,
        yes: bool = typer.Option(False, "--yes", help="Run a sweep of more than 1000 cells (its estimate is shown; "
                                 "without --yes it is refused)."),
    ) -> None:
        """Run every cell (grid point x seed) of a sweep of the digital twin, then write the sweep's report.

        Each cell simulates its study in memory and runs the paper's analysis (LOO and nested LOSO).

        Finished cells are kept: rerunning the same sweep computes only what is missing. A failing cell is recorded
        and skipped. The report (index.html) ranks the designs and answers the paper's open questions.
        """
        from .._util.lock import output_lock
        from .._util.workers import usable_cores
        from ..explore.runner import check_options, run_sweep
        from ..explore.sweep import check_size_confirmed, read_sweep
        from ..explore.write_report import write_explore_report
        from ..report.html import FigureStyle

        style = FigureStyle(check_figure_format(figure_format), dpi)
        check_options(jobs, scheduler)  # bounds and an empty address: before the sweep is even read
        sweep = read_sweep(sweep_file)
        estimate = check_size_confirmed(sweep, yes=yes, workers=jobs or usable_cores())
        if estimate is not None:
            typer.echo(f"roughsense: {estimate}", err=True)
        with output_lock(out, command="explore"):  # two sweeps into one --out would mix their cells
            outcome = run_sweep(sweep, out, n_jobs=jobs, scheduler=scheduler, force=force, progress=progress)
            index = write_explore_report(sweep, out, style=style)
        line = f"{counted(outcome.computed, 'cell')} computed, {outcome.skipped} already finished"
        if outcome.failures:
            line += f", {len(outcome.failures)} failed (see {Path(out) / 'failures.csv'})"
        typer.echo(f"{line}; {outcome.seconds:.1f} s. Results in {Path(out) / 'results'}, report {index}")
