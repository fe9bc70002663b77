"""Reading a study folder: the one data contract between the sources (simulator, rig) and the analysis.

Layout (docs/study.md)::

    study.toml      [study] name, reference_specimen, synthetic; [sensor] px_per_mm, roi; [protocol] forces_n;
                    [pads.NAME] ridge_period_mm (a pad with fingerprint-like ridges)
    specimens.csv   specimen, shape, wavelength_mm, geometry columns
    manifest.csv    image, specimen, pad, force_n, repetition [, nominal_force_n, contact_fraction, timestamp]
    ratings.csv     participant, session, specimen, rating
    images/         image files; manifest paths are relative to the folder

study.toml's tables are read by :mod:`.study_config`. Every reader validates and raises
:class:`~roughsense.errors.InputError` naming the file and line, so nothing downstream has to re-check. Writing a
folder is :mod:`roughsense.io.writer`'s job, atomic file by file.
"""
from __future__ import annotations

import os
import re
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath, PureWindowsPath

import pandas as pd

from .._util.checks import short_repr
from .._util.files import open_regular
from ..errors import InputError, RoughsenseWarning
from ..paper import PAPER_FORCES_N, REFERENCE_SPECIMEN
from .csv_read import csv_line, read_table, refuse_unknown
from .names import check_name, check_name_column
from .problems import Problems, attempt, flag, report, same_but_case
from .protocol import MAX_FORCE_N, MAX_REPETITION, assign_nominal_forces, parse_forces
from .ratings_file import read_ratings_table
from .sensor_settings import SensorSettings
from .study_config import pad_ridge_periods, read_config, sensor_from_config

#: The files and folder of the study folder contract.
STUDY_TOML = "study.toml"
SPECIMENS_CSV = "specimens.csv"
MANIFEST_CSV = "manifest.csv"
RATINGS_CSV = "ratings.csv"
IMAGES_DIR = "images"
#: Written last by the simulator: a study.toml with a [simulation] table but no marker is an interrupted run.
COMPLETE_MARKER = ".simulation-complete"

MANIFEST_COLUMNS = ("image", "specimen", "pad", "force_n", "repetition")


SPECIMEN_COLUMNS = ("specimen", "shape", "wavelength_mm")


SHAPES = ("rectangular", "circular", "sinusoidal", "random", "other")


@dataclass
class Study:
    """A validated study folder held in memory (images stay on disk and are streamed)."""

    root: Path
    name: str
    reference_specimen: str
    sensor: SensorSettings
    forces_n: tuple[float, ...]
    specimens: pd.DataFrame
    manifest: pd.DataFrame
    ratings: pd.DataFrame | None = None
    extra: dict = field(default_factory=dict)
    #: Ridge period (mm) of each pad that has ridges (study.toml's ``[pads.NAME] ridge_period_mm``); a pad not
    #: listed is smooth. The peak-law model leaves the ridges' own frequency out of its peak search.
    pad_ridge_period_mm: dict[str, float] = field(default_factory=dict)

    @property
    def image_paths(self) -> list[Path]:
        return [self.root / p for p in self.manifest["image"]]

    @property
    def pads(self) -> list[str]:
        return list(dict.fromkeys(self.manifest["pad"]))

    @property
    def specimen_names(self) -> list[str]:
        return list(self.specimens["specimen"])

    @property
    def synthetic(self) -> str | None:
        """``[study] synthetic``: where synthetic images came from (an example made from the twin's images), or None.

        Such a folder has no [simulation] table (no simulator wrote it as a study), yet its results are no findings
        about a real sensor; the report says so instead of calling it user data.
        """
        return self.extra.get("synthetic")

    @property
    def simulation(self) -> dict | None:
        """The ``[simulation]`` table of study.toml (seed and settings) if a simulator wrote the folder, else None.

        The analysis labels a study "simulated" from this table alone, so it never needs to import the simulator.
        """
        table = self.extra.get("simulation")
        return dict(table) if isinstance(table, dict) else None


def read_specimens(path: str | os.PathLike[str], *, problems: Problems | None = None) -> pd.DataFrame:
    path = Path(path)
    frame = read_table(path, SPECIMEN_COLUMNS, positive=["wavelength_mm"], text=["specimen", "shape"], problems=problems)
    check_name_column(frame, "specimen", path, problems=problems)
    flag(problems, frame["specimen"].duplicated() & frame["specimen"].notna(), lambda i: InputError(
        f"specimen {frame['specimen'].iloc[i]!r} is listed twice", path=path, row=csv_line(i), column="specimen"))
    shape = frame["shape"].str.lower()
    flag(problems, ~shape.isin(SHAPES) & shape.notna(), lambda i: InputError(
        f"unknown shape {frame['shape'].iloc[i]!r}; expected one of {', '.join(SHAPES)}",
        path=path, row=csv_line(i), column="shape"))
    frame["shape"] = shape
    return frame


def read_manifest(path: str | os.PathLike[str], *, known_specimens: Iterable[str] | None = None,
                  problems: Problems | None = None) -> pd.DataFrame:
    path = Path(path)
    frame = read_table(
        path,
        MANIFEST_COLUMNS,
        positive=["force_n", "nominal_force_n"],  # read from the parsed header (a quoted name is still the column)
        integer=["repetition"],
        numeric=["contact_fraction"],
        text=["image", "specimen", "pad"],
        maximum={"force_n": MAX_FORCE_N, "nominal_force_n": MAX_FORCE_N, "repetition": MAX_REPETITION},
        problems=problems,
    )
    flag(problems, (frame["repetition"] < 0).fillna(False), lambda i: InputError(
        f"must be a whole number >= 0, got {frame['repetition'].iloc[i]}", path=path, row=csv_line(i),
        column="repetition"))
    check_name_column(frame, "specimen", path, problems=problems)
    check_name_column(frame, "pad", path, problems=problems)
    if known_specimens is not None:
        refuse_unknown(frame, "specimen", known_specimens, path, hint=f"not in {SPECIMENS_CSV}", problems=problems)
    dup = flag(problems, frame["image"].duplicated() & frame["image"].notna(), lambda i: InputError(
        f"image {frame['image'].iloc[i]!r} is listed twice", path=path, row=csv_line(i), column="image"))
    bad = check_image_paths(frame["image"], path.parent, path, problems=problems)
    if problems is not None and (dup.size or bad):
        frame.loc[frame.index[[*dup, *bad]], "image"] = None  # reported: not looked for on disk as well
    return frame


def image_path_problem(relative: str, root: Path) -> tuple[Path | None, str | None]:
    """(resolved path, None) for a manifest image path that stays inside ``root``, else (None, why not).

    Symbolic links are followed, so a link inside ``images/`` that points elsewhere is refused like ``..``.
    ``root`` must already be resolved.
    """
    text = str(relative)
    if "\x00" in text:
        return None, "contains a NUL character"
    if PurePosixPath(text).is_absolute() or PureWindowsPath(text).is_absolute() or PureWindowsPath(text).drive:
        return None, f"{text!r} is an absolute path; manifest image paths are relative to the study folder"
    if ".." in re.split(r"[/\\]", text):
        return None, f"{text!r} leads outside the study folder ('..' is not allowed in manifest image paths)"
    try:
        resolved = (root / text).resolve()
    except (OSError, RuntimeError, ValueError) as exc:
        return None, f"{text!r} cannot be resolved ({exc})"
    if resolved == root or not resolved.is_relative_to(root):
        return None, f"{text!r} leads outside the study folder (through '..' or a symbolic link)"
    return resolved, None


def check_image_paths(images: Iterable[str], root: Path, path: Path | None, *,
                      problems: Problems | None = None) -> list[int]:
    """Every manifest image path stays inside the study folder, and no two rows name the same file.

    Returns the positions reported (only when collecting ``problems``; else the first raises).
    """
    try:
        root = root.resolve()
    except (OSError, RuntimeError) as exc:
        raise InputError(f"cannot resolve the study folder ({exc})", path=root) from None
    seen: dict[Path, int] = {}
    bad: list[int] = []
    for i, relative in enumerate(images):
        if not isinstance(relative, str):
            continue  # a blank cell (only when collecting): reported as empty already
        resolved, problem = image_path_problem(relative, root)
        if problem is None and resolved in seen:
            problem = f"{relative!r} names the same file as row {csv_line(seen[resolved])}"
        if problem is not None:
            report(problems, InputError(problem, path=path, row=csv_line(i), column="image"))
            bad.append(i)
            continue
        seen[resolved] = i
    return bad


def check_simulation_complete(root: Path, config: Mapping) -> None:
    """Refuse a simulated study whose run never finished: its files may come from two different runs."""
    if isinstance(config.get("simulation"), dict) and not (root / COMPLETE_MARKER).is_file():
        raise InputError(f"simulated study is incomplete (no {COMPLETE_MARKER}: the simulation was interrupted); "
                         f"rerun `roughsense simulate --out {root} --force`", path=root)


def read_study(root: str | os.PathLike[str], *, require_ratings: bool = False, check_images: bool = True) -> Study:
    """Read and validate a study folder. Raises InputError naming the first problem found.

    ``roughsense check`` lists every problem at once instead.

    Parameters
    ----------
    root : str or os.PathLike
        The study folder (docs/study.md: study.toml, specimens.csv, manifest.csv, ratings.csv, images/).
    require_ratings : bool
        Refuse a folder without ratings.csv (the analysis needs them; features do not).
    check_images : bool
        Check that every image the manifest names is a file (its pixels are read only when used).

    Returns
    -------
    Study
        The folder in memory: ``name``, ``manifest``, ``specimens``, ``ratings`` (None without them), ``sensor``,
        ``image_paths``, ``pads``, ``specimen_names``; the images stay on disk.

    Examples
    --------
    >>> import roughsense as rs
    >>> from roughsense.sim import SimulationConfig
    >>> config = SimulationConfig(pads=("smooth",), specimens=("R2", "R3"), forces_n=(2.0,), repetitions=1)
    >>> study = rs.read_study(rs.simulate_study("simulated", config))
    >>> study.name, study.pads, study.specimen_names, sorted(study.manifest["condition"].unique())
    ('simulated', ['smooth'], ['R2', 'R3'], ['2N'])
    >>> list(study.ratings.columns)
    ['participant', 'session', 'specimen', 'rating']
    """
    from .._util.arguments import flag_argument, path_argument

    path_argument(root, "root", "a study folder")
    flag_argument(require_ratings, "require_ratings")
    flag_argument(check_images, "check_images")
    return load_study(root, require_ratings=require_ratings, check_images=check_images)


def load_study(root: str | os.PathLike[str], *, require_ratings: bool = False, check_images: bool = True,
               problems: Problems | None = None) -> Study:
    """:func:`read_study`, or, with ``problems``, every problem of the folder collected (``roughsense check``).

    When collecting, a file that cannot be read at all leaves its part of the Study None and the checks that
    need it (specimen names, forces) are skipped; the files after it are still checked.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError("study folder not found", path=root)
    settings = _read_settings(root, problems)
    tables = _read_tables(root, settings, problems, require_ratings=require_ratings, check_images=check_images)
    config = settings["config"]
    return Study(
        root=root, name=settings["name"], reference_specimen=settings["reference"], sensor=settings["sensor"],
        forces_n=settings["forces_n"], **tables, pad_ridge_period_mm=settings["ridges"] or {},
        extra={**{k: v for k, v in config.items() if k not in ("study", "sensor", "protocol", "pads")},
               **({"synthetic": settings["synthetic"]} if settings.get("synthetic") else {})},
    )


def _read_settings(root: Path, problems: Problems | None) -> dict:
    """study.toml's values, checked in the order ``study`` reports them (each None when collecting and bad)."""
    toml_path = root / STUDY_TOML
    config = attempt(problems, read_config, toml_path) or {}
    attempt(problems, check_simulation_complete, root, config)
    ridges = attempt(problems, pad_ridge_periods, config, toml_path)  # before any CSV is read
    sensor = attempt(problems, sensor_from_config, config, toml_path, strict=problems is not None)
    forces_n = attempt(problems, parse_forces, config.get("protocol", {}).get("forces_n", list(PAPER_FORCES_N)),
                       path=toml_path)
    study_cfg = config.get("study", {})
    synthetic = study_cfg.get("synthetic")
    if synthetic is not None and not (isinstance(synthetic, str) and synthetic.strip()):
        report(problems, InputError(f"[study] synthetic must say, as text, where the images came from; got "
                                    f"{short_repr(synthetic)}", path=toml_path))
    name = study_cfg.get("name", root.name)
    if not isinstance(name, str):
        report(problems, InputError(f"[study] name must be text, got {short_repr(name)}", path=toml_path))
        name = None
    reference = attempt(problems, check_name, study_cfg.get("reference_specimen", REFERENCE_SPECIMEN),
                        path=toml_path, what="[study] reference_specimen")
    return {"config": config, "ridges": ridges, "sensor": sensor, "forces_n": forces_n, "name": name,
            "reference": reference, "toml_path": toml_path,
            "synthetic": synthetic.strip() if isinstance(synthetic, str) and synthetic.strip() else None}


def _read_tables(root: Path, settings: dict, problems: Problems | None, *, require_ratings: bool,
                 check_images: bool) -> dict:
    """specimens.csv, manifest.csv (with each image's nominal force) and ratings.csv, checked against each other."""
    specimens = attempt(problems, read_specimens, root / SPECIMENS_CSV, problems=problems)
    if specimens is not None and specimens.empty:
        report(problems, InputError("lists no specimens (only a header)", path=root / SPECIMENS_CSV))
    known = None if specimens is None or specimens.empty else specimens["specimen"].dropna()
    manifest_path = root / MANIFEST_CSV
    manifest = attempt(problems, read_manifest, manifest_path, known_specimens=known, problems=problems)
    if manifest is not None and manifest.empty:
        report(problems, InputError("lists no images (only a header); capture or simulate some first",
                                    path=manifest_path))
    elif manifest is not None:
        if settings["forces_n"] is not None:
            manifest = assign_nominal_forces(manifest, settings["forces_n"], manifest_path, problems=problems)
        if check_images:
            missing = [_image_file_problem(root, rel) for rel in manifest["image"]]
            flag(problems, [why is not None for why in missing],
                 lambda i: InputError(f"{missing[i]}: {manifest['image'].iloc[i]}", path=manifest_path,
                                      row=csv_line(i), column="image"))
        _warn_pad_case(settings["config"], manifest, settings["toml_path"])
    ratings = None
    ratings_path = root / RATINGS_CSV
    if ratings_path.exists():
        ratings = attempt(problems, read_ratings_table, ratings_path, reference=settings["reference"],
                          specimens=known, unknown_hint=f"not in {SPECIMENS_CSV}", allow_empty=not require_ratings,
                          problems=problems)
    elif require_ratings:
        report(problems, InputError("file not found (the analysis needs participants' ratings)", path=ratings_path))
    return {"specimens": specimens, "manifest": manifest, "ratings": ratings}


def _image_file_problem(root: Path, relative: object) -> str | None:
    """Why a manifest image is not a readable file (``image file not found``), or None; an OS error such as
    "File name too long" is that row's problem, so `check` goes on listing the others."""
    if not isinstance(relative, str):
        return None  # a blank cell (only when collecting): reported as empty already
    try:
        os.close(open_regular(root / relative, what="image file"))  # readable, and a file: not a FIFO, not /dev/zero
    except FileNotFoundError:
        return "image file not found"
    except PermissionError:
        return "image file cannot be read (permission denied)"
    except InputError as exc:
        return f"image file {exc.message}"
    except OSError as exc:
        return f"image file cannot be looked up ({exc.strerror or type(exc).__name__})"
    return None


def _warn_pad_case(config: Mapping, manifest: pd.DataFrame, toml_path: Path) -> None:
    """Warn of a ``[pads.NAME]`` table that matches a manifest pad only but for case: its settings would be lost."""
    pads = set(manifest["pad"].dropna())
    tables = config.get("pads", {})
    for pad in tables if isinstance(tables, Mapping) else ():
        match = same_but_case(pad, pads) if pad not in pads else None
        if match is not None:
            warnings.warn(f"{toml_path}: [pads.{pad}] names no pad of {MANIFEST_CSV}; did you mean {match!r}? "
                          f"its ridge_period_mm is ignored", RoughsenseWarning, stacklevel=4)
