"""Run the simulated experiment and write it as a study folder (the same contract the rig writes).

The run checks every option (:mod:`.config`), plans the trials and their seeds (:mod:`.plan`), refuses a folder it
may not replace (:mod:`.overwrite`), renders and writes the frames in worker processes (:mod:`.frames`, :mod:`.png`)
and swaps the finished folder in.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import replace
from pathlib import Path

import pandas as pd

from .._util import atomic
from .._util.checks import POSITIVE_INT, check
from .._util.workers import process_pool, usable_cores
from ..defaults import ROI
from ..errors import ConfigError
from ..io.sensor_settings import SensorSettings
from ..io.study import COMPLETE_MARKER
from ..io.writer import StudyWriter
from ..paper import REFERENCE_SPECIMEN
from .config import SimulationConfig, ridge_periods
from .manifest import trial_manifest
from .overwrite import check_overwritable, simulation_owned
from .panel import PANEL_SPAWN_KEY, percept, simulate_panel
from .plan import check_unique_images, mount_groups, plan_trials
from .png import write_mount

__all__ = ["SimulationRun", "simulate_study"]


def simulate_study(out: str | os.PathLike[str], config: SimulationConfig | None = None, *,
                   seed: int | None = None, force: bool = False, jobs: int | None = None,
                   progress: Callable[..., Iterable] | None = None, markers: Mapping[str, str] | None = None) -> Path:
    """Simulate the experiment and write the study folder ``out``; returns its path.

    ``seed`` overrides ``config.seed``. ``progress(iterable, total=, description=)`` may wrap the image loop
    (the CLI passes its progress bar, ``roughsense.cli._common.progress``); the library itself prints nothing.

    Parameters
    ----------
    out : str or os.PathLike
        The study folder to write; built beside it and swapped in when complete.
    config : SimulationConfig, optional
        Pads, specimens, forces, repetitions, panel, camera and bench noise (roughsense.sim); default the
        paper's full study (840 images).
    seed : int, optional
        Overrides ``config.seed``.
    force : bool
        Replace an existing study folder.
    jobs : int, optional
        Worker processes rendering images (default: one per core).
    progress : callable, optional
        Wraps the image loop, e.g. a progress bar.
    markers : mapping, optional
        Files (name -> text) written into the folder before anything else: the cache's key of the built-in study
        (``_util/cache.key_files``), by which the cache knows the folder as its own.

    Returns
    -------
    pathlib.Path
        The study folder, ready for :func:`read_study`.

    Examples
    --------
    >>> import roughsense as rs
    >>> from roughsense.sim import SimulationConfig
    >>> config = SimulationConfig(pads=("smooth",), specimens=("R2", "C4"), forces_n=(2.0,), repetitions=1)
    >>> path = rs.simulate_study("simulated", config, seed=1)
    >>> sorted(p.name for p in path.iterdir())
    ['.simulation-complete', 'images', 'manifest.csv', 'ratings.csv', 'specimens.csv', 'study.toml']
    >>> sorted(p.name for p in (path / "images").iterdir())
    ['smooth_C4_2N_r01.png', 'smooth_R2_2N_r01.png']
    """
    from .._util.arguments import callable_argument, jobs_argument, path_argument

    path_argument(out, "out", "a folder to write")
    if config is not None and not isinstance(config, SimulationConfig):
        raise ConfigError(f"config must be a SimulationConfig, got {type(config).__name__}")
    if jobs is not None:
        jobs_argument(jobs, "jobs")
    callable_argument(progress)
    config = config if config is not None else SimulationConfig()
    if seed is not None:
        config = replace(config, seed=int(seed))
    run = SimulationRun(out, config, force=force, jobs=jobs, markers=markers)
    steps = progress(run, total=run.total, description="simulating") if progress else run
    for _ in steps:
        pass
    return run.root


class SimulationRun:
    """A simulation checked and ready to run: iterate it to render the images (one item per image written).

    Construction validates every option and refuses a non-empty folder (without ``force``) before anything is
    written, so a bad call leaves no partial output. The CLI wraps the iteration in its progress bar.
    """

    def __init__(self, out: str | os.PathLike[str], config: SimulationConfig = SimulationConfig(), *,
                 force: bool = False, jobs: int | None = None, markers: Mapping[str, str] | None = None) -> None:
        self.config = config
        self.markers = dict(markers or {})
        self.pads, self.specimens = config.validate()
        self.jobs = usable_cores() if jobs is None else check(jobs, POSITIVE_INT, name="--jobs", must="at least 1")
        self.trials = plan_trials(config, self.pads, self.specimens)
        check_unique_images(self.trials)
        self.force = force
        self.root = Path(out)
        atomic.clean_leftovers(self.root)  # first: a killed swap's old folder may have to come back
        check_overwritable(self.root, force=force)
        # Built beside the target and swapped in whole when complete; creating it now checks the place is writable.
        self._swap = atomic.FolderSwap(self.root, owned=simulation_owned(self.root))
        self.writer = StudyWriter(self._swap.path)

    @property
    def total(self) -> int:
        return len(self.trials)

    def _write_tables(self) -> None:
        config, writer = self.config, self.writer
        pads = {f"pads.{name}": {"ridge_period_mm": period} for name, period in ridge_periods(self.pads).items()}
        writer.write_config(name=config.name, reference_specimen=REFERENCE_SPECIMEN,
                            sensor=SensorSettings(px_per_mm=config.camera.px_per_mm, roi=ROI),
                            forces_n=sorted(config.forces_n),
                            extra={**pads, "simulation": config.toml_table()})
        table = pd.DataFrame([{**s.table_row(), "ratings_source": percept(s, ratings_from=config.ratings_from).source}
                              for s in self.specimens])
        writer.write_specimens(table)
        writer.write_ratings(simulate_panel(self.specimens, config.seed, spawn_key=PANEL_SPAWN_KEY,
                                            participants=config.participants, sessions=config.sessions,
                                            reference=REFERENCE_SPECIMEN, ratings_from=config.ratings_from))

    def __iter__(self) -> Iterator[str]:
        with atomic.staged_folder(self._swap):
            yield from self._build()

    def _build(self) -> Iterator[str]:
        staging = self.writer.root
        for name, text in self.markers.items():  # first: a killed run's partial folder is known by them too
            atomic.write_text(staging / name, text)
        self._write_tables()
        # One task per mount: its forces' contacts are solved together (the same pixels, less time).
        tasks = [(str(staging), False, group) for group in mount_groups(self.trials)]
        results: list[tuple[str, float]] = []
        if self.jobs == 1 or len(tasks) < 2:
            for written in map(write_mount, tasks):
                results += written
                yield from (image for image, _ in written)
        else:
            with process_pool(min(self.jobs, len(tasks))) as pool:
                for written in pool.map(write_mount, tasks):
                    results += written
                    yield from (image for image, _ in written)
        manifest = trial_manifest(self.trials, [r[0] for r in results], [r[1] for r in results])
        self.writer.write_manifest(manifest)
        atomic.write_text(staging / COMPLETE_MARKER, f"seed = {self.config.seed}\nimages = {len(results)}\n")
