"""``roughsense study``: the paper's whole analysis of a study folder, written as a report."""
from __future__ import annotations

import time
from pathlib import Path

import typer

from ._common import progress, stage
from ._studies import STUDY_METAVAR, builtin_study, is_builtin, resolve_study

ORDER = 5
DEFAULT_SEED = 0


def register(app: typer.Typer) -> None:
    @app.command("study")
    def study_command(
        data: str = typer.Option(None, "--data", metavar=STUDY_METAVAR, show_default=False,
                                 help="Study folder (study.toml, specimens.csv, manifest.csv, ratings.csv, images/), "
                                 "or builtin (the default): the paper's study simulated with --seed, generated on "
                                 "first use and cached (a folder named builtin: ./builtin)."),
        out: Path = typer.Option(Path("report"), "--out", help="Report folder to write (index.html, CSV tables, PNG figures)."),
        seed: int = typer.Option(DEFAULT_SEED, "--seed", help="Seed of the built-in simulated study (and any random draw)."),
        max_components: int = typer.Option(20, "--max-components", min=1, help="Largest number of PLS components tried by CV."),
        no_loso: bool = typer.Option(False, "--no-loso", help="Skip the leave-one-specimen-out analysis (LOO only, as the paper)."),
        jobs: int = typer.Option(2, "--jobs", min=1, help="Worker threads/processes for image decoding and simulation."),
        force: bool = typer.Option(False, "--force", help="Replace the report files in an existing, non-empty --out folder."),
    ) -> None:
        """Reproduce the paper's analysis on a study folder and write a report.

        For each pad and predictor set (1N, 2N, 3N, combined): spectral features, the cross-validated RMSE over
        1..max components and the chosen count, out-of-fold predictions, per-specimen mean ± SD, OVL and RMSE with
        rectangular / circular / overall summaries, and Wilcoxon signed-rank tests -- under the paper's leave-one-out CV
        and under leave-one-specimen-out CV, side by side with the paper's published values.
        """
        import warnings

        from .. import cache, dataset
        from ..errors import RoughsenseWarning
        from ..evaluation import CV_SCHEMES, analyse_study
        from ..report import write_report
        from ..report.html import check_report_dir
        from ..study import read_study

        started = time.perf_counter()
        check_report_dir(out, force)  # fail before minutes of work, not after
        builtin = data is None or is_builtin(data)
        root = builtin_study(seed, jobs) if data is None else resolve_study(data, seed=seed, jobs=jobs)
        study = read_study(root, require_ratings=True)
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
            )
        for warning in caught:  # shown once on the terminal, and kept in the report
            warnings.showwarning(warning.message, warning.category, warning.filename, warning.lineno)
        meta = {
            "study folder": str(Path(root).resolve()),
            "source": "built-in simulated study (digital twin), seed %d" % seed if builtin else "user data",
            "images": f"{len(study.manifest)} ({', '.join(study.pads)} pads; {len(study.specimens)} specimens)",
            "features": "from cache" if was_cached else "extracted",
        }
        if caught:
            meta["warnings"] = "; ".join(str(w.message) for w in caught)
        with stage("writing the report"):
            index = write_report(analysis, out, meta=meta, force=force)
        loo = analysis.results("loo")
        for (pad, condition), group in loo.groupby(["pad", "condition"], sort=False):
            typer.echo(f"{pad:>12} {condition:>9}: mean RMSE {group['rmse'].mean():.3f}, mean OVL {group['ovl'].mean():.3f}, "
                       f"{analysis.fit(pad, condition, 'loo').best_n_components} components (LOO)")
        where = f' (built-in, seed {seed}; "builtin" names it in --data and --study)' if builtin else ""
        typer.echo(f"Study folder: {Path(root).resolve()}{where}")
        typer.echo(f"Report written to {index} in {time.perf_counter() - started:.1f} s")
