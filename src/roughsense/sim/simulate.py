"""Run the simulated experiment and write it as a study folder (the same contract the rig writes).

Randomness: every mount, exposure and each specimen's panel ratings get their own ``SeedSequence`` child keyed by
the master seed and the *names* of pad, specimen, repetition and force, so results do not depend on ``jobs``, on
scheduling, or on which other specimens are in the run.
"""
from __future__ import annotations

import functools
import math
import os
import re
import tomllib
import zlib
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from .._util import atomic
from .._util.checks import MAX_SEED, POSITIVE, POSITIVE_INT, SEED, Integer, check
from .._util.workers import process_pool
from ..errors import ConfigError, OutputExistsError
from ..io.names import check_name
from ..io.protocol import check_force, check_repetitions, nominal_force_label
from ..io.sensor_settings import DEFAULT_ROI, SensorSettings
from ..io.study import COMPLETE_MARKER, IMAGES_DIR, MANIFEST_CSV, RATINGS_CSV, SPECIMENS_CSV, STUDY_TOML
from ..io.writer import StudyWriter, captured_images, refuse_captured
from ..paper import (
    PAPER_FORCES_N,
    PAPER_PARTICIPANTS,
    PAPER_REPETITIONS,
    PAPER_SESSIONS,
    PAPER_SPECIMENS,
    REFERENCE_SPECIMEN,
)
from . import contact
from .bench import BenchNoise, Exposure, Mount, draw_exposure, draw_mount
from .limits import pad_problem, panel_problem, specimen_problem
from .optics import Camera, bin_to_pixels, render
from .pads import DEFAULT_FINGERPRINT_PERIOD_MM, DEFAULT_RIDGE_HEIGHT_MM, PAD_NAMES, Pad, make_pad
from .panel import PANEL_SPAWN_KEY, check_ratings_from, percept, simulate_panel
from .specimens import SPECIMEN_LENGTH_MM, Specimen, parse_specimen

SUBSAMPLES_PER_PX = 7
NO_CONTACT_GAP_MM = 1e3  # beyond the specimen's ends nothing touches the pad
SIMULATION_FILES = (STUDY_TOML, SPECIMENS_CSV, MANIFEST_CSV, RATINGS_CSV, COMPLETE_MARKER)
_IMAGE_NAME = re.compile(r"^[A-Za-z0-9.\-_]+_[0-9.e+\-]+N_r[0-9]+\.png$")  # plan_trials' names
PRESSURE_LEVELS = 5  # local pressures solved per trial at most; the line blends them (see trial_line)
WARM_MAX_ITER = 500  # a warm-started solve needs tens of steps; past this it is cycling and restarts cold
SOLVER_TOL = 1e-5  # relative pressure change at convergence: lines within 1e-4 of 1e-6's (< 0.01 DN), BENCHMARKS.md


@dataclass(frozen=True)
class SimulationConfig:
    """Everything that defines a simulated study. Defaults are the paper's full study (840 images)."""

    pads: tuple[str, ...] = PAD_NAMES
    specimens: tuple[str, ...] = PAPER_SPECIMENS
    forces_n: tuple[float, ...] = PAPER_FORCES_N
    repetitions: int = PAPER_REPETITIONS
    seed: int = 0
    fingerprint_period_mm: float = DEFAULT_FINGERPRINT_PERIOD_MM
    ridge_height_mm: float = DEFAULT_RIDGE_HEIGHT_MM
    participants: int = PAPER_PARTICIPANTS
    sessions: int = PAPER_SESSIONS
    name: str = "simulated"
    ratings_from: str = "paper"  # "paper": the paper's values for its presets, the finger model otherwise; "physics"
    camera: Camera = field(default_factory=Camera)
    bench: BenchNoise = field(default_factory=BenchNoise)

    def validate(self) -> tuple[list[Pad], list[Specimen]]:
        """Check every option before anything is written; returns the resolved pads and specimens."""
        if not self.pads:
            raise ConfigError("--pads: give at least one pad (smooth, fingerprint)")
        if not self.specimens:
            raise ConfigError("--specimens: give at least one specimen")
        if not self.forces_n:
            raise ConfigError("--forces: give at least one force")
        for f in self.forces_n:
            check_force(f, option="--forces: every force")
        _check_nominal_force_labels(self.forces_n)
        check_ratings_from(self.ratings_from)
        # Every numeric option, whether or not the pads use it: it is written to study.toml either way.
        for option, value in (("--fingerprint-period-mm", self.fingerprint_period_mm),
                              ("--ridge-height-mm", self.ridge_height_mm)):
            check(value, POSITIVE, name=option, must="a positive number of mm")
        check_repetitions(self.repetitions)
        check(self.seed, SEED, name="--seed", must=f"a whole number from 0 to {MAX_SEED}")
        for option, value, least in (("participants", self.participants, 2), ("sessions", self.sessions, 1)):
            check(value, Integer(least), name=option, must=f"a whole number, at least {least}")
        pads = [make_pad(p, fingerprint_period_mm=self.fingerprint_period_mm, ridge_height_mm=self.ridge_height_mm)
                for p in self.pads]
        specimens = [parse_specimen(s) for s in self.specimens]
        problem = (pad_problem(period_mm=self.fingerprint_period_mm, ridge_height_mm=self.ridge_height_mm,
                               names=("--fingerprint-period-mm", "--ridge-height-mm", "pad modulus"))
                   or next((f"--specimens: {p}" for p in map(specimen_problem, specimens) if p), None)
                   or panel_problem(self.participants, self.sessions))  # what the twin computes (sim.limits)
        if problem:
            raise ConfigError(problem)
        for kind, names in (("pad", [p.name for p in pads]), ("specimen", [s.name for s in specimens])):
            dup = {n for n in names if names.count(n) > 1}
            if dup:
                raise ConfigError(f"{kind} {sorted(dup)[0]!r} is listed twice")
        return pads, specimens

    def toml_table(self) -> dict:
        cam, bench = asdict(self.camera), asdict(self.bench)
        table = {"seed": int(self.seed), "simulator": "roughsense.sim", "pads": list(self.pads),
                 "repetitions": int(self.repetitions), "fingerprint_period_mm": float(self.fingerprint_period_mm),
                 "ridge_height_mm": float(self.ridge_height_mm), "participants": int(self.participants),
                 "sessions": int(self.sessions), "ratings_from": str(self.ratings_from)}
        table.update({f"camera_{k}": v for k, v in cam.items()})
        table.update({f"bench_{k}": v for k, v in bench.items()})
        return table


def ridge_periods(pads: Sequence[Pad]) -> dict[str, float]:
    """The ridge period (mm) of every pad with ridges: study.toml's ``[pads.NAME] ridge_period_mm``, as a rig's user
    writes it for a real pad."""
    return {pad.name: float(pad.period_mm) for pad in pads if pad.has_ridges}


@dataclass(frozen=True)
class Trial:
    """One exposure, fully specified: a worker renders it without drawing anything but sensor noise."""

    image: str
    pad: Pad
    specimen: Specimen
    nominal_force_n: float
    repetition: int
    mount: Mount
    exposure: Exposure
    noise_key: tuple[int, ...]
    seed: int
    camera: Camera


def _key(text: str) -> int:
    return zlib.crc32(text.encode("utf-8"))


def force_key(force_n: float) -> int:
    """A force's part of the seed keys (micronewtons)."""
    return int(round(force_n * 1e6))


def _check_nominal_force_labels(forces_n: Sequence[float]) -> None:
    """Two forces that share an image name or a seed key would overwrite each other's images (or draws)."""
    for what, label in (("image name", nominal_force_label), ("seed key", force_key)):
        seen: dict[object, float] = {}
        for f in forces_n:
            if label(f) in seen:
                other = seen[label(f)]
                if other == f:
                    raise ConfigError(f"--forces: {f:g} N is listed twice")
                raise ConfigError(f"--forces: {other!r} N and {f!r} N are too close to tell apart (both give the "
                                  f"{what} {label(f)!r}); give forces that differ in their first six significant digits")
            seen[label(f)] = f


def _check_unique_images(trials: Sequence[Trial]) -> None:
    """Planned image names must differ (also in case: a case-insensitive disk would merge them)."""
    seen: dict[str, str] = {}
    for t in trials:
        key = t.image.casefold()
        if key in seen:
            raise ConfigError(f"two trials would write the same image {t.image!r} (and {seen[key]!r}): "
                              "give specimens whose names differ by more than case or punctuation")
        seen[key] = t.image


def _rng(seed: int, *key: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=tuple(key)))


def plan_trials(config: SimulationConfig, pads: Sequence[Pad], specimens: Sequence[Specimen]) -> list[Trial]:
    """All exposures in acquisition order: per pad and specimen, mount ``repetition`` times, step the forces up."""
    trials = []
    forces = sorted(config.forces_n)
    for pad in pads:
        for specimen in specimens:
            for rep in range(1, config.repetitions + 1):
                mount_key = (1, _key(pad.name), _key(specimen.name), rep)
                mount = draw_mount(_rng(config.seed, *mount_key), config.bench, pad.period_mm if pad.has_ridges else None,
                                   ridges=_ridges_in_domain(pad, specimen))
                for force in forces:
                    fkey = force_key(force)
                    exposure = draw_exposure(_rng(config.seed, 2, *mount_key[1:], fkey), config.bench, force)
                    name = f"{check_name(pad.name, what='pad')}_{check_name(specimen.name, what='specimen')}_" \
                           f"{nominal_force_label(force)}_r{rep:02d}.png"
                    trials.append(Trial(name, pad, specimen, float(force), rep, mount, exposure,
                                        (3, *mount_key[1:], fkey), config.seed, config.camera))
    return trials


def _ridges_in_domain(pad: Pad, specimen: Specimen) -> int:
    """Fingerprint ridges in the periodic contact domain: each needs its own height error per mount."""
    if not pad.has_ridges:
        return 0
    length, pad_period = contact.periodic_domain(specimen.period_mm, pad.period_mm, max_length_mm=SPECIMEN_LENGTH_MM)
    return max(1, round(length / pad_period))


def _contact_surface(pad: Pad, specimen: Specimen, mount: Mount) -> tuple[float, np.ndarray, tuple]:
    """The periodic domain's length, the combined relief on its grid, and a key naming the surfaces in contact."""
    length, pad_period = contact.periodic_domain(specimen.period_mm, pad.period_mm if pad.has_ridges else None,
                                                 max_length_mm=SPECIMEN_LENGTH_MM)
    n = contact.grid_points(length)
    x = np.arange(n) * (length / n)
    height = specimen.height_mm(x)
    if pad.has_ridges:
        ridges = _ridges_in_domain(pad, specimen)
        if len(mount.ridge_offsets_mm) < ridges:  # plan_trials draws one per ridge: never silently drop them
            raise RuntimeError(f"mount has {len(mount.ridge_offsets_mm)} ridge height errors for {ridges} ridges")
        offsets = np.asarray(mount.ridge_offsets_mm[:ridges])
        height = height + pad.height_mm(x - mount.pad_phase_mm, period_mm=pad_period, ridge_offsets_mm=offsets)
    # The pad's relief depends on the mount only for a ridged pad.
    key = (repr(pad), repr(specimen), mount.pad_phase_mm, mount.ridge_offsets_mm) if pad.has_ridges else \
        (repr(pad), repr(specimen))
    return length, height, key


def _solve_levels(pad: Pad, specimen: Specimen, mount: Mount, pressures_pa: np.ndarray,
                  warm: dict | None = None) -> tuple[float, list[contact.ContactSolution]]:
    """The contact at each of a trial's pressure levels, solved together (one batched solve).

    ``warm`` (see :func:`trial_line`) holds the last solution of each set of surfaces across trials and starts
    every level from it. A warm start that has not converged after ``WARM_MAX_ITER`` steps (it can cycle when far
    from the answer) is dropped and the levels start afresh from uniform pressure.
    """
    length, height, key = _contact_surface(pad, specimen, mount)
    initial = warm.get(key) if warm is not None else None
    try:
        solutions = None
        if initial is not None:
            try:
                solutions = contact.solve_periodic_many(height, length, pressures_pa, pad.contact_modulus_pa,
                                                        tol=SOLVER_TOL, initial_pressure_pa=initial,
                                                        max_iter=WARM_MAX_ITER)
            except contact.ContactNotConverged:
                solutions = None
        if solutions is None:
            solutions = contact.solve_periodic_many(height, length, pressures_pa, pad.contact_modulus_pa, tol=SOLVER_TOL)
    except contact.ContactNotConverged as exc:
        raise ConfigError(f"pad {pad.name!r} on specimen {specimen.name!r} at {float(np.max(pressures_pa)):.0f} Pa: "
                          f"{exc.message}; try a smoother specimen or a different pad") from None
    if warm is not None:
        warm[key] = solutions[-1].pressure_pa
    return length, solutions


def trial_line(trial: Trial, *, warm: dict | None = None) -> tuple[np.ndarray, float]:
    """Brightness of each pixel column of the line (0..1) and the fraction of the line in contact.

    ``warm``: a dict the caller keeps across the trials of one run; a trial's contact levels then start from the
    last solution of the same surfaces in an earlier trial (same answer within the solver's tolerance, in fewer
    steps). The result then depends, at that tolerance, on
    which trials came before, so the study path leaves it off (its images must not depend on ``jobs``); a sweep
    cell, which runs its trials in one fixed order, uses it.

    A tilted or warped specimen presses harder in some places. The pressure varies slowly compared with the
    grating period, so the line is treated as locally periodic: the contact is solved at a few pressures spanning
    the local range (together, :func:`contact.solve_periodic_many`), and each point blends the two nearest
    solutions by its local pressure (hat weights).
    """
    cam, pad, spec, mount = trial.camera, trial.pad, trial.specimen, trial.mount
    p_mean = contact.nominal_pressure_pa(trial.exposure.force_true_n)
    w_px = cam.width_px
    x_mm, u, on, local = _mount_geometry(cam, mount)
    lo, hi = float(local[on].min()) if on.any() else 1.0, float(local[on].max()) if on.any() else 1.0
    count = 1 if hi - lo < 0.02 else int(min(PRESSURE_LEVELS, 2 + math.ceil((hi - lo) / 0.2)))
    levels = np.linspace(lo, hi, count) if count > 1 else np.array([1.0])
    brightness = np.zeros_like(x_mm)
    touching = np.zeros_like(x_mm)
    length, solutions = _solve_levels(pad, spec, mount, p_mean * levels, warm=warm)
    for level, solution in zip(levels, solutions):
        if count == 1:
            weight = np.ones_like(x_mm)
        else:  # piecewise-linear (hat) weights in local pressure
            weight = np.clip(1.0 - np.abs(local - level) / (levels[1] - levels[0]), 0.0, 1.0)
        gap = solution.gap_mm
        grid = np.arange(gap.size + 1) * (length / gap.size)
        g = np.interp(np.mod(u, length), grid, np.append(gap, gap[0]))
        g = np.where(on, g, NO_CONTACT_GAP_MM)
        brightness += weight * cam.contrast(g)
        touching += weight * (g <= 0)
    if pad.has_ridges and trial.exposure.ridge_visibility > 0:
        # Where the pad is not in optical contact, its ridged surface is still seen through the pad: each ridge is a
        # small cylindrical lens that bends light into the camera, a flat groove bottom is not (a 1 mm^-1 pattern
        # along the whole pad, which is longer than the field). Optical contact wipes it out (index-matched there).
        # Its fundamental sits at the band's upper edge, so its exposure-to-exposure strength rescales the whole
        # area-normalised spectrum (docs/simulator.md, noise calibration).
        crests = _ridge_crests(cam, mount, pad, spec)  # 1 on the crests, 0 in the grooves
        brightness += trial.exposure.ridge_visibility * crests * np.clip(1.0 - brightness, 0.0, 1.0)
    return bin_to_pixels(brightness, w_px), float(touching.mean())


@functools.lru_cache(maxsize=8)
def _mount_geometry(cam: Camera, mount: Mount) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sub-pixel positions on the frame (mm) and on the specimen, where the specimen is, and the local pressure
    relative to the mean: all fixed by the mount, so a mount's forces (consecutive trials) compute them once."""
    w_px = cam.width_px
    px_per_mm = cam.px_per_mm * mount.magnification
    x_mm = (np.arange(w_px * SUBSAMPLES_PER_PX) + 0.5) / (px_per_mm * SUBSAMPLES_PER_PX)
    start = (w_px / px_per_mm - SPECIMEN_LENGTH_MM) / 2.0 + mount.shift_mm
    u = x_mm - start  # position along the specimen
    on = (u >= 0) & (u <= SPECIMEN_LENGTH_MM)
    u_spec = np.linspace(0.0, SPECIMEN_LENGTH_MM, 501)
    mean = float(mount.local_pressure(u_spec, SPECIMEN_LENGTH_MM).mean())
    local = mount.local_pressure(np.clip(u, 0.0, SPECIMEN_LENGTH_MM), SPECIMEN_LENGTH_MM) / mean
    return _read_only(x_mm, u, on, local)


@functools.lru_cache(maxsize=8)
def _ridge_crests(cam: Camera, mount: Mount, pad: Pad, specimen: Specimen) -> np.ndarray:
    """Where the pad's ridges are along the line, 1 on the crests and 0 in the grooves (per mount, like the above)."""
    _, u, _, _ = _mount_geometry(cam, mount)
    _, pad_period = contact.periodic_domain(specimen.period_mm, pad.period_mm, max_length_mm=SPECIMEN_LENGTH_MM)
    return _read_only(1.0 + pad.height_mm(u - mount.pad_phase_mm, period_mm=pad_period) / pad.ridge_height_mm)[0]


def _read_only(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """Cached arrays are shared by the trials of a mount: no caller may change them."""
    for array in arrays:
        array.flags.writeable = False
    return arrays


def render_trial(trial: Trial, *, rows: tuple[int, int] | None = None,
                 warm: dict | None = None) -> tuple[np.ndarray, float]:
    """The 8-bit frame of one trial and its ground-truth contact fraction.

    ``rows=(start, stop)`` renders only those rows, bit-identical to the same rows of the whole frame (for a
    reader that needs only the sensor's line); ``warm`` is passed to :func:`trial_line`.
    """
    line, fraction = trial_line(trial, warm=warm)
    center = trial.camera.height_px / 2.0 + trial.mount.band_shift_px
    frame = render(trial.camera, line, band_center_px=center, lighting=trial.exposure.lighting,
                   rng=_rng(trial.seed, *trial.noise_key), spots=trial.mount.spots, rows=rows)
    return frame, fraction


_WRITERS: dict[tuple[str, bool], StudyWriter] = {}


def _write_trial(args: tuple[str, bool, Trial]) -> tuple[str, float]:
    root, force, trial = args
    writer = _WRITERS.get((root, force))
    if writer is None:  # each worker reopens the folder the parent already checked and created
        writer = _WRITERS[(root, force)] = StudyWriter(root, force=force, resume=True)
    frame, fraction = render_trial(trial)
    return writer.write_image(trial.image, frame, params=png_params()), fraction


def png_params() -> tuple[int, ...]:
    """How frames are encoded: PNG, each row predicted by the "average" filter, Huffman coding only.

    A noisy camera frame has almost no repeated strings, so LZ77's match search costs time and saves nothing; and
    the mean of the left and upper neighbours predicts a pixel with less residual noise (variance 1.5 sigma^2) than
    OpenCV's default "sub" filter (2 sigma^2): ~4 % smaller at the same speed, lossless (BENCHMARKS.md, first run).
    """
    import cv2

    return (cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY,
            cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_AVG)


def simulate_study(out: str | os.PathLike[str], config: SimulationConfig | None = None, *,
                   seed: int | None = None, force: bool = False, jobs: int | None = None,
                   progress: Callable[..., Iterable] | None = None) -> Path:
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
    config = config if config is not None else SimulationConfig()
    if seed is not None:
        config = replace(config, seed=int(seed))
    run = SimulationRun(out, config, force=force, jobs=jobs)
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
                 force: bool = False, jobs: int | None = None) -> None:
        self.config = config
        self.pads, self.specimens = config.validate()
        self.jobs = (os.cpu_count() or 1) if jobs is None else check(jobs, POSITIVE_INT, name="--jobs", must="at least 1")
        self.trials = plan_trials(config, self.pads, self.specimens)
        _check_unique_images(self.trials)
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
                            sensor=SensorSettings(px_per_mm=config.camera.px_per_mm, roi=DEFAULT_ROI),
                            forces_n=sorted(config.forces_n),
                            extra={**pads, "simulation": config.toml_table()})
        table = pd.DataFrame([{**s.table_row(), "ratings_source": percept(s, ratings_from=config.ratings_from).source}
                              for s in self.specimens])
        writer.write_specimens(table)
        writer.write_ratings(simulate_panel(self.specimens, config.seed, spawn_key=PANEL_SPAWN_KEY,
                                            participants=config.participants, sessions=config.sessions,
                                            reference=REFERENCE_SPECIMEN, ratings_from=config.ratings_from))

    def __iter__(self) -> Iterator[str]:
        try:
            yield from self._build()
        except BaseException:
            self._swap.abort()
            raise
        self._swap.commit()

    def _build(self) -> Iterator[str]:
        staging = self.writer.root
        self._write_tables()
        tasks = [(str(staging), False, t) for t in self.trials]
        results: list[tuple[str, float]] = []
        if self.jobs == 1 or len(tasks) < 2:
            for result in map(_write_trial, tasks):
                results.append(result)
                yield result[0]
        else:
            with process_pool(min(self.jobs, len(tasks))) as pool:
                for result in pool.map(_write_trial, tasks, chunksize=4):
                    results.append(result)
                    yield result[0]
        trials = self.trials
        manifest = pd.DataFrame({
            "image": [r[0] for r in results],
            "specimen": [t.specimen.name for t in trials],
            "pad": [t.pad.name for t in trials],
            "force_n": [t.exposure.force_read_n for t in trials],
            "nominal_force_n": [t.nominal_force_n for t in trials],
            "repetition": [t.repetition for t in trials],
            "contact_fraction": [round(r[1], 6) for r in results],
            "true_force_n": [round(t.exposure.force_true_n, 6) for t in trials],
        })
        self.writer.write_manifest(manifest)
        atomic.write_text(staging / COMPLETE_MARKER, f"seed = {self.config.seed}\nimages = {len(results)}\n")


def is_simulated_study(root: str | os.PathLike[str]) -> bool:
    """True if ``root`` holds a study.toml with a ``[simulation]`` table (the simulator wrote it)."""
    try:
        with (Path(root) / STUDY_TOML).open("rb") as handle:
            return isinstance(tomllib.load(handle).get("simulation"), dict)
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError):
        return False


def is_complete_simulation(root: str | os.PathLike[str]) -> bool:
    return is_simulated_study(root) and (Path(root) / COMPLETE_MARKER).is_file()


def check_overwritable(root: str | os.PathLike[str], *, force: bool = True) -> None:
    """May a simulation replace ``root``? Refuses with :class:`OutputExistsError` if not.

    Free to replace: a missing or empty folder (an empty ``images/`` counts as empty), one holding only
    roughsense's own temporary files, or an interrupted simulation (a [simulation] table but no completion
    marker). ``force`` also replaces a complete simulation -- never a real study or a folder of other files, nor a
    simulation the rig has captured real frames into (an older roughsense allowed it): they are refused, --force or not.
    """
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise OutputExistsError("exists and is not a folder", path=root)
    if not root.is_dir():
        return
    refuse_captured(root, "a simulation never replaces real frames, --force or not; choose a new folder")
    images = root / IMAGES_DIR
    entries = [p for p in root.iterdir()
               if not (p == images and p.is_dir() and not any(p.iterdir())) and not atomic.is_temporary(p)]
    if not entries:
        return
    simulated = is_simulated_study(root)
    if simulated and not (root / COMPLETE_MARKER).is_file():
        return  # roughsense's own interrupted run: replaced without --force (other files in it are kept)
    if not force:
        raise OutputExistsError("folder exists and is not empty; pass --force to write into it", path=root)
    if not simulated:
        raise OutputExistsError("folder is not empty and is not a simulated study (no study.toml with a "
                                "[simulation] table); --force only replaces an earlier simulation, so choose a new "
                                "or empty folder", path=root)


def simulation_owned(root: Path) -> Callable[[Path], bool]:
    """Which entries of an earlier simulation in ``root`` are its own (replaced); the rest is a user's (kept).

    Its tables and marker, and the images its manifest lists or that carry the simulator's image names -- never
    an image of a row the rig wrote (a captured frame is kept, whatever its name).
    """
    listed: set[str] = set()
    try:
        manifest = pd.read_csv(root / MANIFEST_CSV, usecols=["image"], dtype=str, keep_default_na=False)
        listed = {str(Path(p)) for p in manifest["image"]}
    except (OSError, ValueError, pd.errors.ParserError, UnicodeDecodeError):
        pass
    captured = {str(Path(p)) for p in captured_images(root / MANIFEST_CSV) if p}

    def owned(rel: Path) -> bool:
        parts = rel.parts
        if len(parts) == 1:
            return parts[0] in SIMULATION_FILES
        return (len(parts) == 2 and parts[0] == IMAGES_DIR and str(rel) not in captured
                and (str(rel) in listed or bool(_IMAGE_NAME.match(parts[1]))))

    return owned


def with_image_size(config: SimulationConfig, width_px: int, height_px: int) -> SimulationConfig:
    """Same study on a smaller frame (tests): the field shrinks, the scale in px/mm stays."""
    return replace(config, camera=replace(config.camera, width_px=int(width_px), height_px=int(height_px)))
