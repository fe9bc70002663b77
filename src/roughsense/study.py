"""The study folder: the one data contract between the sources (simulator, rig) and the analysis.

Layout (see DESIGN.md)::

    study.toml      [study] name, reference_specimen; [sensor] px_per_mm, roi; [protocol] forces_n
    specimens.csv   specimen, shape, wavelength_mm, geometry columns
    manifest.csv    image, specimen, pad, force_n, repetition [, nominal_force_n, contact_fraction, timestamp]
    ratings.csv     participant, session, specimen, rating
    images/         image files; manifest paths are relative to the folder

Every reader here validates and raises :class:`~roughsense.errors.InputError` naming the file and line,
so nothing downstream has to re-check. Every writer is atomic.
"""
from __future__ import annotations

import csv
import io
import math
import os
import re
import tomllib
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np
import pandas as pd

from . import atomic
from .errors import ConfigError, InputError, OutputExistsError, RoughsenseWarning

STUDY_TOML = "study.toml"
SPECIMENS_CSV = "specimens.csv"
MANIFEST_CSV = "manifest.csv"
RATINGS_CSV = "ratings.csv"
IMAGES_DIR = "images"
#: Written last by the simulator: a study.toml with a [simulation] table but no marker is an interrupted run.
COMPLETE_MARKER = ".simulation-complete"

DEFAULT_PX_PER_MM = 34.9
DEFAULT_FORCES_N = (1.0, 2.0, 3.0)
DEFAULT_REFERENCE = "R3"

#: What roi="center" means: a 1900 x 150 px (width, height) crop centred on the frame -- the paper's crop of
#: its 1920 x 1080 camera. Part of the study contract, so the rig can check frames without the sensor code.
CENTER_CROP_PX = (1900, 150)

MANIFEST_COLUMNS = ("image", "specimen", "pad", "force_n", "repetition")
SPECIMEN_COLUMNS = ("specimen", "shape", "wavelength_mm")
RATING_COLUMNS = ("participant", "session", "specimen", "rating")
SHAPES = ("rectangular", "circular", "sinusoidal", "random", "other")

Roi = str | tuple[int, int, int, int]

#: Largest image read, in pixels (width x height): a header claiming more is refused before decoding, so a
#: small file that inflates to gigabytes (a "decompression bomb") cannot exhaust memory. 100 Mpx is above
#: every camera a bench uses (the paper's is 2 Mpx); ``[sensor] max_pixels`` in study.toml changes it.
DEFAULT_MAX_PIXELS = 100_000_000

#: Largest force accepted anywhere (manifest readings, protocol forces, --forces). A fingertip presses with
#: a few newtons (the paper: 1-3 N); 100 N on a 50 x 10 mm specimen is 0.2 MPa, about the pad's own modulus.
MAX_FORCE_N = 100.0

#: Largest repetition number: bounds the work a manifest or an option can ask for (the paper uses 10).
MAX_REPETITION = 10_000

#: Longest name (see :func:`check_name`): file names built from two names and a suffix stay far below the
#: 255-byte limit of common file systems.
NAME_MAX_CHARS = 64

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")
NAME_RULE = (f"letters, digits, '.', '_' and '-' only, starting with a letter or digit, "
             f"at most {NAME_MAX_CHARS} characters")

#: Every table and key study.toml may hold. ``None`` means any key: the ``[simulation]`` table is the
#: simulator's own record of its settings. An unknown table or key is a warning naming it, so a typo such as
#: ``roi_typo`` is noticed. Add a key here when a reader starts using it.
CONFIG_KEYS: dict[str, frozenset[str] | None] = {
    "study": frozenset({"name", "reference_specimen"}),
    "sensor": frozenset({"px_per_mm", "roi", "max_pixels"}),
    "protocol": frozenset({"forces_n"}),
    "simulation": None,
}


# --------------------------------------------------------------------------- names


def is_safe_name(value: object) -> bool:
    """True if ``value`` may become part of a file name (see :data:`NAME_RULE`).

    Names from data (pad, specimen, participant, session, condition) end up in file names: in images the
    rig and the simulator write, in report figures. The rule leaves no room for a separator, ``..``, a
    hidden file, an option-like leading ``-``, a control character or a name too long for the disk.
    """
    return isinstance(value, str) and len(value) <= NAME_MAX_CHARS and _NAME.fullmatch(value) is not None


def check_name(value: object, *, path: str | os.PathLike[str] | None = None, row: int | None = None,
               column: str | None = None, what: str = "name") -> str:
    """Return ``value`` if it obeys the name rule, else raise one :class:`InputError` naming file, row, column.

    The one gate for every name that can reach a path: readers call it where a name is read, and every
    writer that builds a file name from data calls it again just before (a name can come from an option).
    """
    if is_safe_name(value):
        return value
    shown = repr(value) if len(str(value)) <= 80 else repr(str(value)[:77] + "...")
    raise InputError(f"{what} {shown} is not allowed: use {NAME_RULE} (names become parts of file names)",
                     path=path, row=row, column=column)


def check_name_column(frame: pd.DataFrame, column: str, path: Path | None, *, line=None) -> None:
    """Refuse the first value of ``column`` that breaks the name rule, naming its line."""
    line = csv_line if line is None else line
    if column not in frame.columns:
        return
    ok = frame[column].map(is_safe_name)
    if not ok.all():
        i = int(np.flatnonzero(~ok.to_numpy(bool))[0])
        check_name(frame[column].iloc[i], path=path, row=line(i), column=column, what=column)


# --------------------------------------------------------------------------- tables


def csv_line(index: int) -> int:
    """Line number in the file of DataFrame row ``index`` (line 1 is the header)."""
    return int(index) + 2


def refuse_unknown(frame: pd.DataFrame, column: str, known, path: Path | None, *, hint: str,
                   line=csv_line) -> None:
    """Refuse the first value of ``column`` not in ``known``, naming its line; ``hint`` says where names come from."""
    known = set(known)
    unknown = ~frame[column].isin(known)
    if unknown.any():
        i = int(np.flatnonzero(unknown)[0])
        raise InputError(f"unknown {column} {frame[column].iloc[i]!r} ({hint})", path=path, row=line(i), column=column)


def read_text(path: Path, *, max_bytes: int | None = None) -> str:
    """The file as UTF-8 text (a BOM is dropped); anything else is one InputError naming the line."""
    try:
        if max_bytes is not None and path.stat().st_size > max_bytes:
            raise InputError(f"is larger than {max_bytes // 1_000_000} MB; refusing to read it", path=path)
        raw = path.read_bytes()
    except IsADirectoryError:
        raise InputError("is a folder, expected a file", path=path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path=path) from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise InputError(f"is not UTF-8 text (byte 0x{raw[exc.start]:02x}); save it as UTF-8",
                         path=path, row=line) from None


def _check_row_widths(path: Path, text: str) -> None:
    """Refuse a data row with non-empty fields beyond the header's, naming its line.

    pandas would take the first column as the index and shift every value one column left (or, with
    ``index_col=False``, drop the extras with only a warning). Empty extra fields -- a spreadsheet's
    trailing delimiter -- are accepted. Undecodable or malformed files are left for pandas to report.
    """
    try:
        with io.StringIO(text, newline="") as handle:
            reader = csv.reader(handle, skipinitialspace=True)
            header = next(reader, None)
            if header is None:
                return
            while header and not header[-1].strip():
                header.pop()  # the header's own trailing delimiter names no column
            width = len(header)
            start = reader.line_num + 1
            for row in reader:
                extra = [value for value in row[width:] if value.strip()]
                if extra:
                    raise InputError(
                        f"{len(row)} fields but the header has {width} (extra value {extra[0].strip()!r})",
                        path=path, row=start,
                    )
                start = reader.line_num + 1
    except csv.Error:
        return


def read_table(
    path: str | os.PathLike[str],
    required: Sequence[str],
    *,
    numeric: Sequence[str] = (),
    positive: Sequence[str] = (),
    integer: Sequence[str] = (),
    text: Sequence[str] = (),
    maximum: Mapping[str, float] | None = None,
) -> pd.DataFrame:
    """Read a CSV and check columns and values, naming the line of the first bad cell.

    ``text`` columns are kept as strings (so specimen "3" stays "3", and participant IDs keep leading zeros).
    ``maximum`` bounds numeric columns from above (an absurd force, a repetition number that overflows).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    # Numeric columns are read as text too, so an error quotes the cell as written ('inf', not np.float64(inf)).
    dtypes = {name: str for name in {*text, *numeric, *positive, *integer, "image", "specimen", "pad", "participant", "shape"}}
    content = read_text(path)
    _check_row_widths(path, content)
    try:
        # index_col=False: a trailing delimiter on data rows must not turn the first column into the index.
        # skip_blank_lines=False keeps DataFrame row i on file line i + 2, so every error names the right line.
        frame = pd.read_csv(io.StringIO(content), dtype=dtypes, skipinitialspace=True, keep_default_na=False, na_values=[""],
                            index_col=False, skip_blank_lines=False)
    except pd.errors.EmptyDataError:
        raise InputError("is empty; expected a header line", path=path) from None
    except (pd.errors.ParserError, ValueError, OverflowError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"is not a readable CSV ({first})", path=path) from None
    frame.columns = [str(c).strip() for c in frame.columns]
    # A trailing delimiter on the header too gives a nameless, empty column: drop it.
    nameless = [c for c in frame.columns if c.startswith("Unnamed: ") and frame[c].isna().all()]
    frame = frame.drop(columns=nameless)
    blank_rows = frame.isna().all(axis=1).to_numpy()
    if blank_rows.any():
        last = len(blank_rows) - np.argmin(blank_rows[::-1]) if not blank_rows.all() else 0
        if blank_rows[:last].any():
            raise InputError("blank line inside the table; remove it", path=path, row=csv_line(np.flatnonzero(blank_rows)[0]))
        frame = frame.iloc[:last]  # blank lines at the end of the file are harmless
    missing = [c for c in required if c not in frame.columns]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}; found {', '.join(frame.columns)}", path=path)
    for column in required:
        blank = frame[column].isna()
        if blank.any():
            raise InputError("empty value", path=path, row=csv_line(np.flatnonzero(blank)[0]), column=column)
    for column in dict.fromkeys([*numeric, *positive, *integer]):
        if column not in frame.columns:
            continue
        try:
            values = pd.to_numeric(frame[column], errors="coerce").astype(float)
        except (OverflowError, ValueError, TypeError):
            values = frame[column].map(_to_float)
        bad = values.isna() & frame[column].notna()
        bad |= ~np.isfinite(values.fillna(0.0))
        if bad.any():
            i = np.flatnonzero(bad)[0]
            raise InputError(f"not a finite number: {frame[column].iloc[i]!r}", path=path, row=csv_line(i), column=column)
        if column in positive:
            nonpos = values <= 0
            if nonpos.any():
                i = np.flatnonzero(nonpos)[0]
                raise InputError(f"must be positive, got {values.iloc[i]:g}", path=path, row=csv_line(i), column=column)
        limit = (maximum or {}).get(column)
        if limit is not None:
            high = values > limit
            if high.any():
                i = np.flatnonzero(high)[0]
                raise InputError(f"must be at most {limit:g}, got {frame[column].iloc[i]}", path=path,
                                 row=csv_line(i), column=column)
        if column in integer:
            frac = values.notna() & (values != np.round(values))
            if frac.any():
                i = np.flatnonzero(frac)[0]
                raise InputError(f"must be a whole number, got {values.iloc[i]:g}", path=path, row=csv_line(i), column=column)
            frame[column] = values.astype("Int64") if values.isna().any() else values.astype(np.int64)
        else:
            frame[column] = values.astype(float)
    for column in text:
        if column in frame.columns:
            frame[column] = frame[column].str.strip()
    return frame


def _to_float(text: object) -> float:
    try:
        return float(text)
    except (TypeError, ValueError, OverflowError):
        return float("nan")


# --------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class SensorSettings:
    """How images of this study are turned into lines: camera scale and where the contact band is."""

    px_per_mm: float = DEFAULT_PX_PER_MM
    roi: Roi = "center"
    max_pixels: int = DEFAULT_MAX_PIXELS

    def __post_init__(self) -> None:
        if not (is_number(self.px_per_mm) and math.isfinite(self.px_per_mm) and self.px_per_mm > 0):
            shown = f"{self.px_per_mm:g}" if is_number(self.px_per_mm) else repr(self.px_per_mm)
            raise ConfigError(f"px_per_mm must be a positive number, got {shown}")
        object.__setattr__(self, "roi", parse_roi(self.roi))
        object.__setattr__(self, "max_pixels", check_max_pixels(self.max_pixels))


def is_number(value: object) -> bool:
    """A real number that is not a boolean (TOML's ``true`` is not 1 here)."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def check_max_pixels(value: object, *, option: str = "max_pixels") -> int:
    """A pixel limit: a positive whole number (see :data:`DEFAULT_MAX_PIXELS`)."""
    if not (is_number(value) and math.isfinite(value) and value == int(value) and value >= 1):
        raise ConfigError(f"{option} must be a positive whole number of pixels, got {value!r}")
    return int(value)


def parse_roi(value: object) -> Roi:
    """Accept "center", "auto", "X,Y,W,H" or a 4-sequence of non-negative ints (W, H positive)."""
    if isinstance(value, str):
        text = value.strip().lower()
        if text in ("center", "centre"):
            return "center"
        if text == "auto":
            return "auto"
        parts = [p.strip() for p in text.split(",")]
    elif isinstance(value, Sequence):
        parts = list(value)
        if any(isinstance(p, (bool, np.bool_)) for p in parts):
            raise ConfigError(f"ROI values must be whole pixels, not true/false, got {_roi_text(value)}")
    else:
        raise ConfigError(f"ROI must be 'center', 'auto' or X,Y,W,H, got {_roi_text(value)}")
    if len(parts) != 4:
        raise ConfigError(f"ROI must be 'center', 'auto' or X,Y,W,H, got {_roi_text(value)}")
    try:
        numbers = [float(p) for p in parts]
    except (TypeError, ValueError, OverflowError):
        raise ConfigError(f"ROI must be 'center', 'auto' or X,Y,W,H with whole numbers, got {_roi_text(value)}") from None
    if not all(math.isfinite(n) for n in numbers):
        raise ConfigError(f"ROI values must be finite whole pixels, got {_roi_text(value)}")
    if any(n != int(n) for n in numbers):
        raise ConfigError(f"ROI values must be whole pixels, got {_roi_text(value)}")
    x, y, w, h = (int(n) for n in numbers)
    if x < 0 or y < 0 or w <= 0 or h <= 0:
        raise ConfigError(f"ROI needs X,Y >= 0 and W,H > 0, got {_roi_text(value)}")
    return (x, y, w, h)


def _roi_text(value: object) -> str:
    """The ROI as the user gave it (a sequence of numpy numbers must not print as np.int64(...))."""
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, Sequence):
        return ",".join(str(v) for v in value)
    return repr(value)


def roi_misfit(roi: Roi, width_px: int, height_px: int) -> str | None:
    """Why a ``width_px`` x ``height_px`` frame cannot yield this ROI's crop, or None if it can.

    The size rule of :func:`roughsense.sensor.resolve_roi`, so that a source can check its frames
    before recording a session the analysis would refuse.
    """
    roi = parse_roi(roi)
    if roi == "center":
        crop_w, crop_h = CENTER_CROP_PX
        if width_px < crop_w or height_px < crop_h:
            return f"smaller than the {crop_w}x{crop_h} px centre crop of roi 'center'"
        return None
    if roi == "auto":
        if width_px < 2 or height_px < 1:
            return "too small to find the contact band (roi 'auto')"
        return None
    x, y, w, h = roi
    if x + w > width_px or y + h > height_px:
        return f"ROI {x},{y},{w},{h} reaches outside it"
    return None


def nominal_force_label(force_n: float) -> str:
    """Condition label of a nominal force: 1.0 -> "1N", 2.5 -> "2.5N"."""
    return f"{force_n:g}N"


# --------------------------------------------------------------------------- the study


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

    @property
    def image_paths(self) -> list[Path]:
        return [self.root / p for p in self.manifest["image"]]

    @property
    def pads(self) -> list[str]:
        return list(dict.fromkeys(self.manifest["pad"]))

    @property
    def specimen_names(self) -> list[str]:
        return list(self.specimens["specimen"])

    def condition_labels(self) -> list[str]:
        return [nominal_force_label(f) for f in self.forces_n]

    @property
    def simulation(self) -> dict | None:
        """The ``[simulation]`` table of study.toml (seed and settings) if a simulator wrote the folder, else None.

        The analysis labels a study "simulated" from this table alone, so it never needs to import the simulator.
        """
        table = self.extra.get("simulation")
        return dict(table) if isinstance(table, dict) else None


#: study.toml is a few hundred bytes; a file far larger is not one (and is not read whole).
MAX_CONFIG_BYTES = 1_000_000


def read_config(path: str | os.PathLike[str]) -> dict:
    """Parse study.toml and check its shape: known tables are tables; unknown tables and keys are warned about.

    Values are checked by the readers that use them (:func:`_sensor_from_config`, :func:`parse_forces`).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found (every study folder needs study.toml)", path=path)
    text = read_text(path, max_bytes=MAX_CONFIG_BYTES)
    try:
        config = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"is not valid TOML ({exc})", path=path) from None
    except RecursionError:
        raise InputError("is not a study.toml: its values are nested too deeply", path=path) from None
    for table, value in config.items():
        if table not in CONFIG_KEYS:
            kind = "table" if isinstance(value, dict) else "key"
            warnings.warn(f"{path}: unknown {kind} {table!r} ignored (known tables: {', '.join(CONFIG_KEYS)})",
                          RoughsenseWarning, stacklevel=2)
            continue
        if not isinstance(value, dict):
            raise InputError(f"{table} must be a table ([{table}] followed by key = value lines), "
                             f"got {type(value).__name__} {_short(value)}", path=path)
        known = CONFIG_KEYS[table]
        for key in value:
            if known is not None and key not in known:
                warnings.warn(f"{path}: unknown key {key!r} in [{table}] ignored (known: {', '.join(sorted(known))})",
                              RoughsenseWarning, stacklevel=2)
    return config


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _sensor_from_config(config: Mapping, path: Path) -> SensorSettings:
    sensor = config.get("sensor", {})
    if not isinstance(sensor, Mapping):
        raise InputError(f"sensor must be a table, got {type(sensor).__name__}", path=path)
    try:
        return SensorSettings(px_per_mm=sensor.get("px_per_mm", DEFAULT_PX_PER_MM), roi=sensor.get("roi", "center"),
                              max_pixels=sensor.get("max_pixels", DEFAULT_MAX_PIXELS))
    except ConfigError as exc:
        raise InputError(f"[sensor] {exc.message}", path=path) from None


def check_force(value: object, *, option: str = "force") -> float:
    """One force in newtons: a number (not a boolean), finite, positive and at most :data:`MAX_FORCE_N`."""
    if not is_number(value) or not math.isfinite(value) or not 0 < value <= MAX_FORCE_N:
        shown = f"{value:g}" if is_number(value) else repr(value)
        raise ConfigError(f"{option} must be a positive number of newtons up to {MAX_FORCE_N:g}, got {shown}")
    return float(value)


def parse_forces(value: object, *, path: Path | None = None) -> tuple[float, ...]:
    """``[protocol] forces_n``: a non-empty list of distinct forces (see :func:`check_force`)."""
    if not isinstance(value, (list, tuple)) or not value:
        raise InputError(f"[protocol] forces_n must be a non-empty list of numbers, got {_short(value)}", path=path)
    try:
        forces = tuple(check_force(f, option="[protocol] forces_n: each force") for f in value)
    except ConfigError as exc:
        raise InputError(exc.message, path=path) from None
    if len(set(forces)) != len(forces):
        raise InputError(f"[protocol] forces_n lists a force twice: {_short(value)}", path=path)
    return forces


def check_repetitions(value: object, *, option: str = "--repetitions") -> int:
    """A count of repetitions: a whole number from 1 to :data:`MAX_REPETITION`."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or not 1 <= value <= MAX_REPETITION:
        raise ConfigError(f"{option} must be a whole number from 1 to {MAX_REPETITION}, got {value!r}")
    return int(value)


def read_specimens(path: str | os.PathLike[str]) -> pd.DataFrame:
    path = Path(path)
    frame = read_table(path, SPECIMEN_COLUMNS, positive=["wavelength_mm"], text=["specimen", "shape"])
    check_name_column(frame, "specimen", path)
    dup = frame["specimen"].duplicated()
    if dup.any():
        i = np.flatnonzero(dup)[0]
        raise InputError(f"specimen {frame['specimen'].iloc[i]!r} is listed twice", path=path, row=csv_line(i), column="specimen")
    bad_shape = ~frame["shape"].str.lower().isin(SHAPES)
    if bad_shape.any():
        i = np.flatnonzero(bad_shape)[0]
        raise InputError(
            f"unknown shape {frame['shape'].iloc[i]!r}; expected one of {', '.join(SHAPES)}",
            path=path, row=csv_line(i), column="shape",
        )
    frame["shape"] = frame["shape"].str.lower()
    return frame


def read_manifest(path: str | os.PathLike[str], *, known_specimens: Iterable[str] | None = None) -> pd.DataFrame:
    path = Path(path)
    frame = read_table(
        path,
        MANIFEST_COLUMNS,
        positive=["force_n", *(["nominal_force_n"] if _has_column(path, "nominal_force_n") else [])],
        integer=["repetition"],
        numeric=["contact_fraction"],
        text=["image", "specimen", "pad"],
        maximum={"force_n": MAX_FORCE_N, "nominal_force_n": MAX_FORCE_N, "repetition": MAX_REPETITION},
    )
    negative = frame["repetition"] < 0
    if negative.any():
        i = int(np.flatnonzero(negative.to_numpy(bool))[0])
        raise InputError(f"must be a whole number >= 0, got {frame['repetition'].iloc[i]}", path=path,
                         row=csv_line(i), column="repetition")
    check_name_column(frame, "specimen", path)
    check_name_column(frame, "pad", path)
    if known_specimens is not None:
        refuse_unknown(frame, "specimen", known_specimens, path, hint=f"not in {SPECIMENS_CSV}")
    dup = frame["image"].duplicated()
    if dup.any():
        i = np.flatnonzero(dup)[0]
        raise InputError(f"image {frame['image'].iloc[i]!r} is listed twice", path=path, row=csv_line(i), column="image")
    check_image_paths(frame["image"], path.parent, path)
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


def check_image_paths(images: Iterable[str], root: Path, path: Path | None) -> None:
    """Every manifest image path stays inside the study folder, and no two rows name the same file."""
    try:
        root = root.resolve()
    except (OSError, RuntimeError) as exc:
        raise InputError(f"cannot resolve the study folder ({exc})", path=root) from None
    seen: dict[Path, int] = {}
    for i, relative in enumerate(images):
        resolved, problem = image_path_problem(relative, root)
        if problem is not None:
            raise InputError(problem, path=path, row=csv_line(i), column="image")
        if resolved in seen:
            first = seen[resolved]
            raise InputError(f"{relative!r} names the same file as row {csv_line(first)}", path=path,
                             row=csv_line(i), column="image")
        seen[resolved] = i


def _has_column(path: Path, column: str) -> bool:
    try:
        with path.open(encoding="utf-8-sig") as handle:
            header = handle.readline(100_000)
    except (OSError, UnicodeDecodeError):
        return False  # read_table then names the real problem
    return column in [c.strip() for c in header.strip().split(",")]


def assign_nominal_forces(manifest: pd.DataFrame, forces_n: Sequence[float], path: Path | None = None) -> pd.DataFrame:
    """Give each image its nominal force (the condition), from the column or the nearest protocol force.

    The scale reading (``force_n``) scatters around the nominal force; a reading nearer to no protocol
    force than half the spacing is refused rather than silently binned.
    """
    manifest = manifest.copy()
    forces = np.asarray(sorted(forces_n), dtype=float)
    if "nominal_force_n" in manifest.columns:
        nominal = manifest["nominal_force_n"].to_numpy(float)
        off = ~np.isin(nominal, forces)
        if off.any():
            i = np.flatnonzero(off)[0]
            raise InputError(
                f"nominal force {nominal[i]:g} N is not one of the protocol forces {', '.join(f'{f:g}' for f in forces)}",
                path=path, row=csv_line(i), column="nominal_force_n",
            )
    else:
        measured = manifest["force_n"].to_numpy(float)
        nearest = np.abs(measured[:, None] - forces[None, :]).argmin(axis=1)
        nominal = forces[nearest]
        spacing = np.min(np.diff(forces)) if forces.size > 1 else forces[0]
        far = np.abs(measured - nominal) > 0.5 * spacing
        if far.any():
            i = np.flatnonzero(far)[0]
            raise InputError(
                f"force {measured[i]:g} N is far from every protocol force ({', '.join(f'{f:g}' for f in forces)})",
                path=path, row=csv_line(i), column="force_n",
            )
    manifest["nominal_force_n"] = nominal
    manifest["condition"] = [nominal_force_label(f) for f in nominal]
    return manifest


def drop_unrated(frame: pd.DataFrame) -> pd.DataFrame:
    """The one rule for blank rating cells: a trial not (yet) done, dropped; aggregation warns about the gap.

    Used by every ratings reader (``roughsense ratings``, ``study``, ``fit``), so a file means the same to all.
    Frames keep their index (``index + 2`` is the file line) for later errors.
    """
    if "rating" not in frame.columns:
        return frame
    blank = np.fromiter((_is_blank(v) for v in frame["rating"].to_numpy(object)), dtype=bool, count=len(frame))
    return frame[~blank]


def _is_blank(value: object) -> bool:
    if isinstance(value, str):
        return not value.strip()
    return value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value))


def read_ratings_table(path: str | os.PathLike[str], *, allow_empty: bool = False) -> pd.DataFrame:
    """Structural read of ratings.csv; perception.py adds the domain checks (reference, gaps).

    Blank rating cells follow :func:`drop_unrated`; a file with no rating left is refused unless ``allow_empty``
    (a study of the reference specimen alone has nothing to rate, and only the analysis needs ratings).
    """
    path = Path(path)
    frame = read_table(path, ("participant", "session", "specimen"), text=["participant", "session", "specimen", "rating"])
    if "rating" not in frame.columns:
        raise InputError(f"missing column(s) rating; found {', '.join(frame.columns)}", path=path)
    frame = drop_unrated(frame)
    if frame.empty and allow_empty:
        return frame.assign(rating=pd.Series(dtype=float))
    if frame.empty:
        raise InputError("has no ratings (no row, or every rating cell is empty)", path=path)
    values = frame["rating"].map(_to_float)
    bad = ~np.isfinite(values.to_numpy(float))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"not a finite number: {frame['rating'].iloc[i]!r}", path=path,
                         row=csv_line(frame.index[i]), column="rating")
    nonpositive = values.to_numpy(float) <= 0
    if nonpositive.any():
        i = int(np.flatnonzero(nonpositive)[0])
        raise InputError(f"must be positive, got {values.iloc[i]:g}", path=path,
                         row=csv_line(frame.index[i]), column="rating")
    frame = frame.assign(rating=values.astype(float))
    for column in ("participant", "session", "specimen"):
        check_name_column(frame, column, path, line=lambda i, f=frame: csv_line(f.index[i]))
    return frame


def check_simulation_complete(root: Path, config: Mapping) -> None:
    """Refuse a simulated study whose run never finished: its files may come from two different runs."""
    if isinstance(config.get("simulation"), dict) and not (root / COMPLETE_MARKER).is_file():
        raise InputError(f"simulated study is incomplete (no {COMPLETE_MARKER}: the simulation was interrupted); "
                         f"rerun `roughsense simulate --out {root} --force`", path=root)


def read_study(root: str | os.PathLike[str], *, require_ratings: bool = False, check_images: bool = True) -> Study:
    """Read and validate a study folder. Raises InputError naming the first problem found."""
    root = Path(root)
    if not root.is_dir():
        raise InputError("study folder not found", path=root)
    toml_path = root / STUDY_TOML
    config = read_config(toml_path)
    check_simulation_complete(root, config)
    study_cfg = config.get("study", {})
    sensor = _sensor_from_config(config, toml_path)
    forces_n = parse_forces(config.get("protocol", {}).get("forces_n", list(DEFAULT_FORCES_N)), path=toml_path)
    name = study_cfg.get("name", root.name)
    if not isinstance(name, str):
        raise InputError(f"[study] name must be text, got {_short(name)}", path=toml_path)
    reference = study_cfg.get("reference_specimen", DEFAULT_REFERENCE)
    check_name(reference, path=toml_path, what="[study] reference_specimen")

    specimens = read_specimens(root / SPECIMENS_CSV)
    if specimens.empty:
        raise InputError("lists no specimens (only a header)", path=root / SPECIMENS_CSV)
    manifest_path = root / MANIFEST_CSV
    manifest = read_manifest(manifest_path, known_specimens=specimens["specimen"])
    if manifest.empty:
        raise InputError("lists no images (only a header); capture or simulate some first", path=manifest_path)
    manifest = assign_nominal_forces(manifest, forces_n, manifest_path)
    if check_images:
        for i, rel in enumerate(manifest["image"]):
            if not (root / rel).is_file():
                raise InputError(f"image file not found: {rel}", path=manifest_path, row=csv_line(i), column="image")

    ratings = None
    ratings_path = root / RATINGS_CSV
    if ratings_path.exists():
        ratings = read_ratings_table(ratings_path, allow_empty=not require_ratings)
        refuse_unknown(ratings, "specimen", specimens["specimen"], ratings_path, hint=f"not in {SPECIMENS_CSV}")
    elif require_ratings:
        raise InputError("file not found (the analysis needs participants' ratings)", path=ratings_path)

    return Study(
        root=root,
        name=name,
        reference_specimen=reference,
        sensor=sensor,
        forces_n=forces_n,
        specimens=specimens,
        manifest=manifest,
        ratings=ratings,
        extra={k: v for k, v in config.items() if k not in ("study", "sensor", "protocol")},
    )


# --------------------------------------------------------------------------- writing


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, str):  # a TOML basic string: quotes, backslashes and control characters escaped
        escaped = "".join(
            "\\" + ch if ch in '"\\' else f"\\u{ord(ch):04X}" if ord(ch) < 0x20 or ord(ch) == 0x7F else ch
            for ch in value
        )
        return f'"{escaped}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def dump_toml(tables: Mapping[str, Mapping[str, object]]) -> str:
    """Tiny TOML writer for flat tables of scalars and lists (all study.toml needs)."""
    lines: list[str] = []
    for table, values in tables.items():
        lines.append(f"[{table}]")
        for key, value in values.items():
            lines.append(f"{key} = {_toml_value(value)}")
        lines.append("")
    return "\n".join(lines)


class StudyWriter:
    """Writes a study folder atomically, file by file. Used by both the simulator and the rig.

    A non-empty folder is refused unless ``force`` (then files roughsense writes are replaced, and
    nothing else is touched) or ``resume`` (the rig appends to its own earlier session).
    """

    def __init__(self, root: str | os.PathLike[str], *, force: bool = False, resume: bool = False) -> None:
        self.root = Path(root)
        self.force = force
        if self.root.exists() and not self.root.is_dir():
            raise OutputExistsError("exists and is not a folder", path=self.root)
        if self.root.is_dir() and any(self.root.iterdir()) and not (force or resume):
            raise OutputExistsError("folder exists and is not empty; pass --force to write into it", path=self.root)
        self.root.mkdir(parents=True, exist_ok=True)
        (self.root / IMAGES_DIR).mkdir(exist_ok=True)

    def write_config(
        self,
        *,
        name: str,
        reference_specimen: str = DEFAULT_REFERENCE,
        sensor: SensorSettings = SensorSettings(),
        forces_n: Sequence[float] = DEFAULT_FORCES_N,
        extra: Mapping[str, Mapping[str, object]] | None = None,
    ) -> Path:
        roi = sensor.roi if isinstance(sensor.roi, str) else list(sensor.roi)
        tables: dict[str, Mapping[str, object]] = {
            "study": {"name": name, "reference_specimen": reference_specimen},
            "sensor": {"px_per_mm": float(sensor.px_per_mm), "roi": roi,
                       **({"max_pixels": sensor.max_pixels} if sensor.max_pixels != DEFAULT_MAX_PIXELS else {})},
            "protocol": {"forces_n": [float(f) for f in forces_n]},
        }
        tables.update(extra or {})
        return atomic.write_text(self.root / STUDY_TOML, dump_toml(tables))

    def write_specimens(self, specimens: pd.DataFrame) -> Path:
        missing = [c for c in SPECIMEN_COLUMNS if c not in specimens.columns]
        if missing:
            raise ValueError(f"specimens table lacks {missing}")
        return atomic.write_csv(self.root / SPECIMENS_CSV, specimens)

    def write_manifest(self, manifest: pd.DataFrame) -> Path:
        missing = [c for c in MANIFEST_COLUMNS if c not in manifest.columns]
        if missing:
            raise ValueError(f"manifest lacks {missing}")
        return atomic.write_csv(self.root / MANIFEST_CSV, manifest)

    def append_manifest_row(self, row: Mapping[str, object]) -> Path:
        """Append one row by rewriting the file atomically: a crash never leaves half a row."""
        path = self.root / MANIFEST_CSV
        new = pd.DataFrame([dict(row)])
        if path.exists():
            old = pd.read_csv(path, dtype={"image": str, "specimen": str, "pad": str}, keep_default_na=False, na_values=[""],
                              index_col=False)  # a hand-edited file's trailing commas must not shift the columns
            old = old.drop(columns=[c for c in old.columns if str(c).startswith("Unnamed: ") and old[c].isna().all()])
            new = pd.concat([old, new], ignore_index=True)
        return self.write_manifest(new)

    def write_ratings(self, ratings: pd.DataFrame) -> Path:
        return atomic.write_csv(self.root / RATINGS_CSV, ratings)

    def image_path(self, name: str) -> Path:
        return self.root / IMAGES_DIR / name

    def write_image(self, name: str, image: np.ndarray, *, params: Sequence[int] = ()) -> str:
        """Encode and write ``images/<name>`` atomically; returns the manifest-relative path.

        ``params`` are OpenCV's ``imwrite`` flags (e.g. the PNG compression strategy); the file stays a standard one.
        """
        import cv2  # local: the study contract should not pay for OpenCV at import

        target = self.image_path(name)
        if target.exists() and not self.force:
            raise OutputExistsError("already exists; refusing to overwrite a captured image", path=target)
        ext = target.suffix.lower() or ".png"
        array = np.ascontiguousarray(image)
        if array.ndim == 3 and array.shape[2] == 3:
            array = array[:, :, ::-1]  # OpenCV stores BGR; callers hand us RGB
        ok, encoded = cv2.imencode(ext, array, list(params))
        if not ok:
            raise InputError(f"could not encode image as {ext}", path=target)
        atomic.write_bytes(target, encoded.tobytes())
        return f"{IMAGES_DIR}/{name}"
