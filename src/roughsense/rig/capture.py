"""The acquisition protocol of section 3.2, resumable and loss-free.

For each repetition the pad is loaded to each protocol force in turn (1, 2, 3 N) and one image is taken
at each. Every image and every manifest row is written atomically, image first, so an interruption loses
at most the frame in progress. A rerun reads the manifest and captures only the (repetition, force)
steps that have no row yet for this specimen and pad: ``repetitions`` is the target total, not a count
to add.

Orphans: an image written just before a crash has no manifest row. It is left where it is (never
overwritten or adopted: its force reading was lost with the row), reported, and the retaken frame gets
the next free name (``..._2N-2.png``). Only manifest rows define the study, so orphans are inert.
"""
from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from .. import defaults
from .._util.checks import POSITIVE, check
from .._util.lock import OutputLock, lock_path, output_lock
from ..errors import ConfigError, InputError, OutputExistsError
from ..io.csv_read import csv_line, read_table
from ..io.names import NAME_RULE, check_name, is_safe_name
from ..io.protocol import check_force, check_repetitions, nominal_force_label, parse_forces
from ..io.sensor_settings import SensorSettings, parse_roi, roi_misfit
from ..io.study import (
    IMAGES_DIR,
    MANIFEST_CSV,
    SHAPES,
    SPECIMEN_COLUMNS,
    SPECIMENS_CSV,
    STUDY_TOML,
    read_config,
    read_manifest,
    sensor_from_config,
)
from ..io.writer import CAPTURED, StudyWriter, refuse_simulated
from ..paper import PAPER_FORCES_N
from .camera import FrameSource
from .scale import ForceInput

#: Manifest columns the rig writes (``nominal_force_n`` keeps the condition exact whatever the scale read).
RIG_COLUMNS = ("image", "specimen", "pad", "force_n", "nominal_force_n", "repetition", "timestamp")
LOCK_FILE = ".capture.lock"  # older versions' lock inside the folder (now beside it: _util/lock.py); ignored


@dataclass
class CaptureResult:
    root: Path
    captured: list[str] = field(default_factory=list)
    already_done: int = 0
    orphans: list[str] = field(default_factory=list)
    specimen_incomplete: bool = False
    #: This run wrote study.toml with the paper's px_per_mm in place of one measured on this rig (no --px-per-mm).
    default_scale: bool = False
    #: (image, why) for each press the caller's ``inspect`` found wanting (``capture --model``: the model's gate).
    suspect: list[tuple[str, str]] = field(default_factory=list)


def check_option_name(value: str, option: str) -> str:
    """Specimen and pad names go into file names: the study contract's one name rule (:func:`roughsense.io.names.check_name`)."""
    if not is_safe_name(value):
        raise ConfigError(f"--{option} {value!r}: use {NAME_RULE} (it becomes part of file names)")
    return value


def image_name(specimen: str, pad: str, repetition: int, nominal_force_n: float, attempt: int = 1) -> str:
    check_name(specimen, what="specimen")
    check_name(pad, what="pad")
    base = f"{specimen}_{pad}_r{repetition:02d}_{nominal_force_label(nominal_force_n)}"
    return f"{base}.png" if attempt == 1 else f"{base}-{attempt}.png"


def force_window(forces_n: Sequence[float]) -> dict[float, tuple[float, float]]:
    """Accepted readings per step: within half the protocol spacing, the rule io/protocol.py uses to bin readings."""
    forces = sorted(forces_n)
    spacing = min(np.diff(forces)) if len(forces) > 1 else forces[0]
    half = 0.5 * float(spacing)
    return {f: (max(f - half, 1e-9), f + half) for f in forces}


# --------------------------------------------------------------------------- the folder


@dataclass
class _Folder:
    """What is already in ``root``, read before anything is captured (and before anything is written)."""

    root: Path
    is_new: bool
    forces_n: tuple[float, ...]
    sensor: SensorSettings
    manifest: pd.DataFrame
    specimens: pd.DataFrame | None


def _inspect(root: Path, forces_n, px_per_mm, roi) -> _Folder:
    if root.exists() and not root.is_dir():
        raise OutputExistsError("exists and is not a folder", path=root)
    refuse_simulated(root, "real frames are never mixed with simulated ones, so capture into a folder of their own")
    toml_path = root / STUDY_TOML
    if not toml_path.exists():
        if root.is_dir() and not _is_blank(root):
            raise OutputExistsError("folder is not empty and has no study.toml; capture into a new folder or a study folder",
                                    path=root)
        forces = tuple(float(f) for f in (forces_n or PAPER_FORCES_N))
        sensor = SensorSettings(px_per_mm=defaults.PX_PER_MM if px_per_mm is None else px_per_mm,
                                   roi=defaults.ROI if roi is None else roi)
        _check_forces(forces)
        return _Folder(root, True, forces, sensor, pd.DataFrame(columns=RIG_COLUMNS), None)

    config = read_config(toml_path)
    stored_forces = parse_forces(config.get("protocol", {}).get("forces_n", list(PAPER_FORCES_N)), path=toml_path)
    sensor = sensor_from_config(config, toml_path)
    if forces_n is not None and tuple(sorted(map(float, forces_n))) != tuple(sorted(stored_forces)):
        raise ConfigError(
            f"--forces-n {','.join(f'{f:g}' for f in forces_n)} differs from this study's protocol "
            f"{','.join(f'{f:g}' for f in stored_forces)} in {toml_path}; omit --forces-n to use it"
        )
    if px_per_mm is not None and not math.isclose(float(px_per_mm), sensor.px_per_mm):
        raise ConfigError(f"--px-per-mm {px_per_mm:g} differs from {sensor.px_per_mm:g} in {toml_path}; omit it or edit the file")
    if roi is not None and parse_roi(roi) != sensor.roi:
        raise ConfigError(f"--roi {roi} differs from {sensor.roi!r} in {toml_path}; omit it or edit the file")
    _check_forces(stored_forces)

    manifest_path = root / MANIFEST_CSV
    if manifest_path.exists():
        manifest = read_manifest(manifest_path)
        if len(manifest) and "nominal_force_n" not in manifest.columns:
            raise InputError("has no nominal_force_n column: it was not written by the rig, so the rig will not extend it",
                             path=manifest_path)
    else:
        manifest = pd.DataFrame(columns=RIG_COLUMNS)
    specimens_path = root / SPECIMENS_CSV
    specimens = _read_specimens_loose(specimens_path) if specimens_path.exists() else None
    return _Folder(root, False, stored_forces, sensor, manifest, specimens)


def _is_blank(root: Path) -> bool:
    """Empty but for what an interrupted first capture leaves: the lock file and an empty images/ folder."""
    for entry in root.iterdir():
        if entry.name == LOCK_FILE:
            continue
        if entry.name == IMAGES_DIR and entry.is_dir() and not any(entry.iterdir()):
            continue
        return False
    return True


def _check_forces(forces: Sequence[float]) -> None:
    if not forces or len(set(forces)) != len(forces):
        raise ConfigError(f"protocol forces must be distinct positive numbers, got {list(forces)}")
    for f in forces:
        check_force(f, option="each protocol force")


def _read_specimens_loose(path: Path) -> pd.DataFrame:
    """specimens.csv as text, blanks allowed: the rig may have left shape/wavelength for the user to fill in."""
    frame = read_table(path, ["specimen"], text=["specimen", "shape"])
    frame = frame.astype(object).where(frame.notna(), "")
    for column in SPECIMEN_COLUMNS:
        if column not in frame.columns:
            frame[column] = ""
    return frame


def _merge_specimen(folder: _Folder, specimen: str, shape: str | None, wavelength_mm: float | None
                    ) -> tuple[pd.DataFrame | None, bool]:
    """specimens.csv with ``specimen`` added or its blanks filled; (None if unchanged, is it still incomplete)."""
    path = folder.root / SPECIMENS_CSV
    table = folder.specimens if folder.specimens is not None else pd.DataFrame(columns=list(SPECIMEN_COLUMNS))
    given = {"shape": shape or "", "wavelength_mm": "" if wavelength_mm is None else f"{wavelength_mm:g}"}
    hits = np.flatnonzero(table["specimen"].astype(str).to_numpy() == specimen)
    if hits.size == 0:
        row = dict.fromkeys(table.columns, "")
        row.update(specimen=specimen, **given)
        merged = pd.concat([table, pd.DataFrame([row])], ignore_index=True)
        return merged, not all(given.values())
    i = int(hits[0])
    merged = table.copy()
    changed = False
    for column, value in given.items():
        current = str(merged.at[i, column]).strip()
        if not value:
            continue
        same = (current == value) if column == "shape" else (current != "" and math.isclose(float(current), float(value)))
        if current and not same:
            raise ConfigError(
                f"specimen {specimen!r} has {column} {current}; --{column.replace('_', '-')} says {value} "
                "(edit specimens.csv if the file is wrong)", path=path, row=csv_line(i), column=column,
            )
        if not current:
            merged.at[i, column] = value
            changed = True
    incomplete = any(str(merged.at[i, c]).strip() == "" for c in ("shape", "wavelength_mm"))
    return (merged if changed else None), incomplete


# --------------------------------------------------------------------------- the protocol


def plan_steps(manifest: pd.DataFrame, specimen: str, pad: str, forces_n: Sequence[float], repetitions: int
               ) -> list[tuple[int, float]]:
    """The (repetition, nominal force) steps still missing for this specimen and pad, in protocol order."""
    done: set[tuple[int, float]] = set()
    if len(manifest):
        mine = manifest[(manifest["specimen"].astype(str) == specimen) & (manifest["pad"].astype(str) == pad)]
        done = {(int(r), float(f)) for r, f in zip(mine["repetition"], mine["nominal_force_n"])}
    return [(r, float(f)) for r in range(1, repetitions + 1) for f in forces_n if (r, float(f)) not in done]


def capture_session(
    root: str | Path,
    *,
    source: FrameSource,
    force_input: ForceInput,
    specimen: str,
    pad: str,
    repetitions: int = 10,
    forces_n: Sequence[float] | None = None,
    px_per_mm: float | None = None,
    roi: str | None = None,
    shape: str | None = None,
    wavelength_mm: float | None = None,
    log: Callable[[str], None] | None = None,
    clock: Callable[[], datetime] = lambda: datetime.now(UTC),
    held: OutputLock | None = None,
    inspect: Callable[[np.ndarray], str] | None = None,
) -> CaptureResult:
    """Run (or resume) the protocol for one specimen on one pad, writing into the study folder ``root``.

    ``forces_n``, ``px_per_mm`` and ``roi`` default to the folder's study.toml (or the paper's values in a
    new folder); a value that contradicts study.toml is refused. Nothing is written until the first frame
    is in hand, so a source or scale that fails at once leaves the folder as it was. One writer per folder at a
    time: the run holds the folder's lock, taken here, or ``held``, the lock a caller took already (the command
    line takes it before it opens the camera, so a second capture names the first, not a busy camera).
    ``inspect(frame)`` says why a press taken is wanting ('' where it is not): the press is kept (it is what the
    camera saw) and named at once, so the operator can look before the next (the rig knows nothing of the sensor:
    the command line composes them).
    """
    log = log or (lambda text: print(text, file=sys.stderr, flush=True))
    root = Path(root)
    _check_capture_options(specimen, pad, repetitions, shape, wavelength_mm)
    if held is not None and held.path != lock_path(root):
        raise ValueError(f"the lock held is {held.path}'s, not {root}'s")
    with output_lock(root, command="capture") if held is None else contextlib.nullcontext():
        folder = _inspect(root, forces_n, px_per_mm, roi)
        forces = tuple(float(f) for f in (forces_n or folder.forces_n))
        specimens_update, incomplete = _merge_specimen(folder, specimen, shape.lower() if shape else None, wavelength_mm)
        steps = plan_steps(folder.manifest, specimen, pad, forces, repetitions)
        session = _Session(
            root=root, folder=folder, specimens_update=specimens_update, source=source, force_input=force_input,
            specimen=specimen, pad=pad, repetitions=repetitions, log=log, clock=clock,
            window=force_window(folder.forces_n), inspect=inspect,
            result=CaptureResult(root=root, already_done=repetitions * len(forces) - len(steps),
                                 specimen_incomplete=incomplete))
        for repetition, nominal in steps:
            session.capture(repetition, nominal)
        session.result.default_scale = folder.is_new and px_per_mm is None and session.writer is not None
        if session.writer is None and specimens_update is not None and not folder.is_new:
            # Nothing left to capture, but --shape/--wavelength-mm completed the specimen's row.
            StudyWriter(root, resume=True, source=CAPTURED).write_specimens(specimens_update)
        return session.result


def _check_capture_options(specimen: str, pad: str, repetitions: int, shape: str | None,
                           wavelength_mm: float | None) -> None:
    """Refuse bad options before the folder, the camera or the scale is touched."""
    check_option_name(specimen, "specimen")
    check_option_name(pad, "pad")
    check_repetitions(repetitions)
    if shape is not None and shape.lower() not in SHAPES:
        raise ConfigError(f"--shape {shape!r}: expected one of {', '.join(SHAPES)}")
    if wavelength_mm is not None:
        check(wavelength_mm, POSITIVE, name="--wavelength-mm", must="positive")


@dataclass(kw_only=True)
class _Session:
    """One run of the protocol: what it reads from, what it writes into, and what it has done so far.

    The folder is created and written only once the first frame is in hand (its lock is beside it).
    """

    root: Path
    folder: _Folder
    specimens_update: pd.DataFrame | None
    source: FrameSource
    force_input: ForceInput
    specimen: str
    pad: str
    repetitions: int
    log: Callable[[str], None]
    clock: Callable[[], datetime]
    window: dict[float, tuple[float, float]]
    result: CaptureResult
    inspect: Callable[[np.ndarray], str] | None = None
    writer: StudyWriter | None = None

    def capture(self, repetition: int, nominal: float) -> None:
        """Wait for the force, take a fresh frame, and write it with its manifest row."""
        label = f"[{self.specimen}/{self.pad} rep {repetition}/{self.repetitions}] "
        low_n, high_n = self.window[nominal]
        force_n = self.force_input.read_force(nominal, low_n=low_n, high_n=high_n, label=label)
        frame = self.source.read_fresh()
        _check_frame(frame, self.folder.sensor, self.source)
        stamp = self.clock().astimezone(UTC).isoformat(timespec="milliseconds")
        if self.writer is None:
            self.writer = _start_writing(self.folder, self.specimens_update)
        name, skipped = _free_name(self.writer, self.specimen, self.pad, repetition, nominal)
        self.result.orphans.extend(skipped)
        for orphan in skipped:
            self.log(f"  images/{orphan} has no manifest row (interrupted earlier): kept, not reused")
        rel = self.writer.write_image(name, frame)
        self.writer.append_manifest_row({
            "image": rel, "specimen": self.specimen, "pad": self.pad, "force_n": round(force_n, 6),
            "nominal_force_n": nominal, "repetition": repetition, "timestamp": stamp,
        })
        self.result.captured.append(rel)
        self.log(f"  saved {rel} at {force_n:.3f} N")
        why = self.inspect(frame) if self.inspect is not None else ""
        if why:
            self.result.suspect.append((rel, why))
            self.log(f"  {rel} is no press the model would read ({why}): look at the pad and the specimen")


def _check_frame(frame: np.ndarray, sensor: SensorSettings, source: FrameSource) -> None:
    """Refuse a frame the analysis could not crop (wrong camera resolution), or one above the study's
    ``[sensor] max_pixels`` (its images must read back), before any of it is written."""
    height, width = frame.shape[:2]
    if width * height > sensor.max_pixels:
        raise InputError(f"frame is {width}x{height} px ({width * height / 1e6:.3g} Mpx), above the study's [sensor] "
                         f"max_pixels of {sensor.max_pixels / 1e6:.3g} Mpx; nothing of it was written",
                         path=getattr(source, "name", None))
    problem = roi_misfit(sensor.roi, width, height)
    if problem is not None:
        raise InputError(
            f"frame is {width}x{height} px, {problem}; set the camera's resolution or the study's roi",
            path=getattr(source, "name", None),
        )


def _start_writing(folder: _Folder, specimens_update: pd.DataFrame | None) -> StudyWriter:
    writer = StudyWriter(folder.root, resume=True, source=CAPTURED)
    if not (folder.root / STUDY_TOML).exists():
        writer.write_config(name=folder.root.resolve().name, sensor=folder.sensor, forces_n=folder.forces_n)
    if specimens_update is not None:
        writer.write_specimens(specimens_update)
    if not (folder.root / MANIFEST_CSV).exists():
        writer.write_manifest(pd.DataFrame(columns=list(RIG_COLUMNS)))
    return writer


def _free_name(writer: StudyWriter, specimen: str, pad: str, repetition: int, nominal: float) -> tuple[str, list[str]]:
    skipped = []
    attempt = 1
    while writer.image_path(name := image_name(specimen, pad, repetition, nominal, attempt)).exists():
        skipped.append(name)
        attempt += 1
    return name, skipped
