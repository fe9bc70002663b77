"""The sweep file: a TOML grid of designs of the twin, checked up front and expanded into independent cells.

A cell is one grid point x one seed. Everything a cell needs travels inside :class:`Cell` (no files), so a worker on
another machine computes it from the cell alone, and the cell's id is a hash of exactly that content: a rerun of the
same sweep, or a sweep that shares some of its cells, finds them finished.

The ``model`` axis is not a grid dimension of cells: a model family does not change the simulated frames, so a cell
simulates once and fits every requested family on the same spectra (rows per model). Its id covers the families only
when they differ from the paper's PLS alone, so sweeps without the axis keep the ids (and results) they had.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .._util.checks import POSITIVE, Integer, Real
from ..analysis.study_analysis import CV_SCHEMES
from ..errors import ConfigError
from ..io.images import DEFAULT_MAX_PIXELS
from ..io.sensor_settings import DEFAULT_PX_PER_MM
from ..model.families import DEFAULT_MODEL, MODEL_FAMILIES, check_model_name
from ..model.pls_cv import DEFAULT_MAX_COMPONENTS
from ..paper import (
    PAPER_FORCES_N,
    PAPER_PARTICIPANTS,
    PAPER_REPETITIONS,
    PAPER_SESSIONS,
    PAPER_SPECIMENS,
    REFERENCE_SPECIMEN,
)
from ..sensor.settings import SPECTRUM_DEFAULTS
from ..sim.optics import HEIGHT_PX, WIDTH_PX
from ..sim.pads import DEFAULT_FINGERPRINT_PERIOD_MM, DEFAULT_RIDGE_HEIGHT_MM, PAD_NAMES, YOUNG_PA
from ..sim.panel import RATINGS_FROM
from ..sim.specimens import parse_specimen

MIN_FIELD_MM = 1.0 / SPECTRUM_DEFAULTS.f_min_per_mm  # a shorter line cannot resolve the spectrum's lowest frequency
#: Named specimen sets usable wherever a list of specimens is expected.
SPECIMEN_SETS = {
    "paper": PAPER_SPECIMENS,
    "rectangular": tuple(s for s in PAPER_SPECIMENS if s.startswith("R")),
    "circular": tuple(s for s in PAPER_SPECIMENS if s.startswith("C")),
}
PAPER_DESIGN = {  # the paper's rig, the baseline the questions are asked against
    "fingerprint_period_mm": DEFAULT_FINGERPRINT_PERIOD_MM, "ridge_height_mm": DEFAULT_RIDGE_HEIGHT_MM,
    "pad_modulus_mpa": YOUNG_PA / 1e6, "field_length_mm": round(WIDTH_PX / DEFAULT_PX_PER_MM, 3), "forces_n": "1,2,3",
}
#: Design parameters: every one may be a single value in [sweep] or a list of values in [axes].
DESIGN_KEYS = ("pad", "fingerprint_period_mm", "ridge_height_mm", "pad_modulus_mpa", "field_length_mm", "forces_n",
               "specimens", "repetitions", "ratings_from")
FINGERPRINT_ONLY = ("fingerprint_period_mm", "ridge_height_mm")  # meaningless for the smooth pad
#: The model families a cell fits: one value in [sweep] or a list in [axes], like a design parameter, but every
#: family of a design is fitted in the same cell (the frames do not depend on the model).
MODEL_KEY = "model"
SETTING_KEYS = ("name", "seeds", "max_components", "participants", "sessions", "image_size_px", "cv")
DEFAULTS = {
    "pad": "smooth", "fingerprint_period_mm": DEFAULT_FINGERPRINT_PERIOD_MM, "ridge_height_mm": DEFAULT_RIDGE_HEIGHT_MM,
    "pad_modulus_mpa": YOUNG_PA / 1e6, "field_length_mm": None, "forces_n": PAPER_FORCES_N,
    "specimens": "paper", "repetitions": PAPER_REPETITIONS, "ratings_from": "paper",
}
#: Column type of each design parameter in the results (strings for lists, NaN where a value does not apply).
COLUMN_KINDS = {"pad": "str", "fingerprint_period_mm": "float", "ridge_height_mm": "float",
                "pad_modulus_mpa": "float", "field_length_mm": "float", "forces_n": "str", "specimens": "str",
                "repetitions": "int", "ratings_from": "str", MODEL_KEY: "str"}


@dataclass(frozen=True)
class Cell:
    """One grid point x one seed: everything needed to compute it, nothing else."""

    id: str
    seed: int
    pad: str
    fingerprint_period_mm: float | None
    ridge_height_mm: float | None
    pad_modulus_mpa: float
    field_length_mm: float
    forces_n: tuple[float, ...]
    specimens: tuple[str, ...]
    specimens_label: str
    repetitions: int
    ratings_from: str
    participants: int
    sessions: int
    width_px: int
    height_px: int
    max_components: int
    cv: tuple[str, ...]
    code: str = ""  # fingerprint of the twin and analysis that compute it (explore.version)
    models: tuple[str, ...] = (DEFAULT_MODEL,)  # the families fitted on the cell's spectra, in MODEL_FAMILIES order

    def columns(self) -> dict:
        """The design as result columns: one scalar per design parameter (lists as text; ``model`` lists the
        cell's families, each result row names its own)."""
        return {
            "pad": self.pad,
            "fingerprint_period_mm": math.nan if self.fingerprint_period_mm is None else self.fingerprint_period_mm,
            "ridge_height_mm": math.nan if self.ridge_height_mm is None else self.ridge_height_mm,
            "pad_modulus_mpa": self.pad_modulus_mpa,
            "field_length_mm": self.field_length_mm,
            "forces_n": forces_label(self.forces_n),
            "specimens": self.specimens_label,
            "repetitions": self.repetitions,
            "ratings_from": self.ratings_from,
            MODEL_KEY: ",".join(self.models),
        }


@dataclass
class Sweep:
    """A checked sweep file: its settings, its axes (design parameters that vary) and the cells of its grid."""

    path: Path
    name: str
    axes: dict[str, list]
    cells: list[Cell]
    cv: tuple[str, ...]
    source: dict = field(default_factory=dict)  # the parsed file, to tell one sweep from another
    models: tuple[str, ...] = (DEFAULT_MODEL,)


def forces_label(forces_n) -> str:
    return ",".join(f"{f:g}" for f in forces_n)


def _error(path: Path, message: str) -> ConfigError:
    return ConfigError(message, path=path)


def _number(path, where, value, *, positive=True) -> float:
    if not (POSITIVE if positive else Real()).accepts(value):
        raise _error(path, f"{where}: expected a positive number, got {value!r}")
    return float(value)


def _whole(path, where, value, least) -> int:
    if not Integer(least).accepts(value):
        raise _error(path, f"{where}: expected a whole number >= {least}, got {value!r}")
    return int(value)


def _check_value(path: Path, key: str, value, where: str):
    """One design value, checked and normalised (lists become tuples); raises naming the key and value."""
    if key == "pad":
        if not isinstance(value, str) or value.strip().lower() not in PAD_NAMES:
            raise _error(path, f"{where}: unknown value {value!r} (expected one of {', '.join(PAD_NAMES)})")
        return value.strip().lower()
    if key in ("fingerprint_period_mm", "ridge_height_mm", "pad_modulus_mpa"):
        return _number(path, where, value)
    if key == "field_length_mm":
        length = _number(path, where, value)
        if length < MIN_FIELD_MM:
            raise _error(path, f"{where}: {value!r} mm is shorter than {MIN_FIELD_MM:g} mm, the longest wavelength "
                               "the spectrum (0.1-1 mm^-1) resolves")
        return length
    if key == "forces_n":
        if not isinstance(value, list) or not value:
            raise _error(path, f"{where}: expected a non-empty list of forces in N, got {value!r}")
        forces = tuple(sorted(_number(path, where, f) for f in value))
        if len(set(forces_label(forces).split(","))) != len(forces):
            raise _error(path, f"{where}: forces {value!r} are not distinct")
        return forces
    if key == "specimens":
        if isinstance(value, str):
            if value not in SPECIMEN_SETS:
                raise _error(path, f"{where}: unknown specimen set {value!r} (expected one of "
                                   f"{', '.join(SPECIMEN_SETS)}, or a list of specimens)")
            return value
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise _error(path, f"{where}: expected a list of specimens or a set name, got {value!r}")
        names = []
        for text in value:
            try:
                names.append(parse_specimen(text).name)
            except ConfigError as exc:
                raise _error(path, f"{where}: {exc.message}") from None
        if len(set(names)) != len(names):
            raise _error(path, f"{where}: a specimen is listed twice in {value!r}")
        rated = [n for n in names if n != REFERENCE_SPECIMEN]
        if len(rated) < 4:
            raise _error(path, f"{where}: give at least 4 specimens besides the reference R3 (leave-one-specimen-out "
                               "needs 3 to choose the components of each held-out one)")
        return tuple(text.strip() for text in value)  # the specs as written: the simulator parses them again
    if key == "repetitions":
        return _whole(path, where, value, 2)
    if key == "ratings_from":
        if value not in RATINGS_FROM:
            raise _error(path, f"{where}: unknown value {value!r} (expected one of {', '.join(RATINGS_FROM)})")
        return value
    raise AssertionError(key)


def _label(key: str, value) -> object:
    if key == "forces_n":
        return forces_label(value)
    if key == "specimens":
        return value if isinstance(value, str) else ",".join(value)
    return value


def read_sweep(path: str | os.PathLike[str]) -> Sweep:
    """Read and check a sweep file; every problem is one line naming the file and the key."""
    path = Path(path)
    if not path.is_file():
        raise _error(path, "sweep file not found")
    try:
        with path.open("rb") as handle:
            source = tomllib.load(handle)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise _error(path, f"is not valid TOML ({exc})") from None
    except RecursionError:
        raise _error(path, "is not a sweep file: its values are nested too deeply") from None
    return build_sweep(source, path)


def build_sweep(source: dict, path: Path) -> Sweep:
    """The sweep a parsed file describes: its settings and axes checked, its grid expanded into cells."""
    settings, axes_in = _tables(source, path)
    run = _run_settings(settings, path)
    fixed = {key: _check_value(path, key, settings[key], f"[sweep] {key}") if key in settings else DEFAULTS[key]
             for key in DESIGN_KEYS}
    models = _models(settings, axes_in, path)
    axes = _axes({k: v for k, v in axes_in.items() if k != MODEL_KEY}, path)
    if "pad" not in axes and "pad" not in settings:
        axes["pad"] = list(PAD_NAMES)  # both of the paper's pads unless told otherwise
    cells = _cells(_design_points(fixed, axes), run, models)
    name = settings.get("name", path.stem)
    if not isinstance(name, str) or not name.strip():
        raise _error(path, f"[sweep] name: expected a text, got {name!r}")
    varying = {k: [_label(k, v) for v in vals] for k, vals in axes.items()}
    if MODEL_KEY in axes_in:
        varying[MODEL_KEY] = list(models)
    return Sweep(path=path, name=name, axes=varying, cells=cells, cv=run["cv"], source=source, models=models)


def _models(settings: dict, axes_in: dict, path: Path) -> tuple[str, ...]:
    """The model families: ``model`` in [sweep] (one name) or in [axes] (a list); the paper's PLS by default."""
    if MODEL_KEY in axes_in:
        where, values = f"[axes] {MODEL_KEY}", axes_in[MODEL_KEY]
        if not isinstance(values, list) or not values:
            raise _error(path, f"{where}: expected a non-empty list of model families "
                               f"({', '.join(MODEL_FAMILIES)}), got {values!r}")
    elif MODEL_KEY in settings:
        where, values = f"[sweep] {MODEL_KEY}", [settings[MODEL_KEY]]
    else:
        return (DEFAULT_MODEL,)
    try:
        names = [check_model_name(v, option=where) for v in values]
    except ConfigError as exc:
        raise _error(path, exc.message) from None
    if len(set(names)) != len(names):
        raise _error(path, f"{where}: a model is listed twice")
    return tuple(m for m in MODEL_FAMILIES if m in names)


def _tables(source: dict, path: Path) -> tuple[dict, dict]:
    """The [sweep] and [axes] tables, refusing unknown tables and keys and a key given in both."""
    unknown_tables = [k for k in source if k not in ("sweep", "axes")]
    if unknown_tables:
        raise _error(path, f"unknown table [{unknown_tables[0]}] (expected [sweep] and [axes])")
    settings = source.get("sweep", {})
    axes_in = source.get("axes", {})
    if not isinstance(settings, dict) or not isinstance(axes_in, dict):
        raise _error(path, "[sweep] and [axes] must be tables")
    for key in settings:
        if key not in SETTING_KEYS + DESIGN_KEYS + (MODEL_KEY,):
            raise _error(path, f"[sweep]: unknown key {key!r} (known: "
                               f"{', '.join(SETTING_KEYS + DESIGN_KEYS + (MODEL_KEY,))})")
    for key in axes_in:
        if key not in DESIGN_KEYS + (MODEL_KEY,):
            raise _error(path, f"[axes]: unknown axis {key!r} (known: {', '.join(DESIGN_KEYS + (MODEL_KEY,))})")
        if key in settings:
            raise _error(path, f"{key!r} is given both in [sweep] and in [axes]; give it in one place")
    return settings, axes_in


def _run_settings(settings: dict, path: Path) -> dict:
    """Seeds, CV schemes, panel size and frame size: what every cell shares."""
    seeds = settings.get("seeds", [0])
    if not isinstance(seeds, list) or not seeds:
        raise _error(path, f"[sweep] seeds: expected a non-empty list of whole numbers, got {seeds!r}")
    seeds = [_whole(path, "[sweep] seeds", s, 0) for s in seeds]
    if len(set(seeds)) != len(seeds):
        raise _error(path, "[sweep] seeds: a seed is listed twice")
    max_components = _whole(path, "[sweep] max_components", settings.get("max_components", DEFAULT_MAX_COMPONENTS), 1)
    participants = _whole(path, "[sweep] participants", settings.get("participants", PAPER_PARTICIPANTS), 2)
    sessions = _whole(path, "[sweep] sessions", settings.get("sessions", PAPER_SESSIONS), 1)
    size = settings.get("image_size_px", [WIDTH_PX, HEIGHT_PX])
    if not (isinstance(size, list) and len(size) == 2):
        raise _error(path, f"[sweep] image_size_px: expected [width, height], got {size!r}")
    width_px, height_px = (_whole(path, "[sweep] image_size_px", v, 16) for v in size)
    if width_px * height_px > DEFAULT_MAX_PIXELS:  # the study contract's pixel limit holds for simulated frames too
        raise _error(path, f"[sweep] image_size_px: {width_px} x {height_px} px is above the limit of "
                           f"{DEFAULT_MAX_PIXELS / 1e6:g} Mpx per frame")
    cv = settings.get("cv", list(CV_SCHEMES))
    if not isinstance(cv, list) or not cv or any(c not in CV_SCHEMES for c in cv):
        raise _error(path, f"[sweep] cv: expected a list of {', '.join(CV_SCHEMES)}, got {cv!r}")
    return dict(seeds=seeds, max_components=max_components, participants=participants, sessions=sessions,
                width_px=width_px, height_px=height_px, cv=tuple(c for c in CV_SCHEMES if c in cv))


def _axes(axes_in: dict, path: Path) -> dict[str, list]:
    """Each axis's values, checked; a value listed twice is refused."""
    axes: dict[str, list] = {}
    for key, values in axes_in.items():
        if not isinstance(values, list):
            raise _error(path, f"[axes] {key}: expected a list of values, got {values!r}")
        if not values:
            raise _error(path, f"[axes] {key}: no values, so the grid is empty")
        checked = [_check_value(path, key, v, f"[axes] {key}") for v in values]
        if len({json.dumps(_label(key, v)) for v in checked}) != len(checked):
            raise _error(path, f"[axes] {key}: a value is listed twice")
        axes[key] = checked
    return axes


def _design_points(fixed: dict, axes: dict[str, list]) -> list[dict]:
    """The grid's distinct designs (a smooth pad has no ridge settings, so those collapse)."""
    keys = list(axes)
    points, seen = [], set()
    for combo in itertools.product(*(axes[k] for k in keys)):
        point = {**fixed, **dict(zip(keys, combo))}
        if point["pad"] == "smooth":
            for key in FINGERPRINT_ONLY:
                point[key] = None
        signature = json.dumps({k: _label(k, v) for k, v in point.items()}, sort_keys=True)
        if signature not in seen:
            seen.add(signature)
            points.append(point)
    return points


def _cells(points: list[dict], run: dict, models: tuple[str, ...] = (DEFAULT_MODEL,)) -> list[Cell]:
    """One cell per design and seed, its id a hash of everything it computes from, the code included.

    The model families enter the hash only when they are not the paper's PLS alone: a sweep without the ``model``
    axis hashes exactly the content it always did, and any other set of families gives other ids.
    """
    from .version import code_fingerprint

    code = code_fingerprint()
    cells = []
    for point in points:
        specimens = point["specimens"]
        names = SPECIMEN_SETS[specimens] if isinstance(specimens, str) else specimens
        field_mm = point["field_length_mm"]
        cell_width = run["width_px"] if field_mm is None else max(16, int(round(field_mm * DEFAULT_PX_PER_MM)))
        for seed in run["seeds"]:
            content = dict(
                seed=seed, pad=point["pad"], fingerprint_period_mm=point["fingerprint_period_mm"],
                ridge_height_mm=point["ridge_height_mm"], pad_modulus_mpa=point["pad_modulus_mpa"],
                field_length_mm=round(cell_width / DEFAULT_PX_PER_MM, 6), forces_n=tuple(point["forces_n"]),
                specimens=tuple(names), specimens_label=_label("specimens", specimens),
                repetitions=point["repetitions"], ratings_from=point["ratings_from"], participants=run["participants"],
                sessions=run["sessions"], width_px=cell_width, height_px=run["height_px"],
                max_components=run["max_components"], cv=run["cv"], code=code,
            )
            hashed = content if models == (DEFAULT_MODEL,) else {**content, "models": list(models)}
            digest = hashlib.sha256(json.dumps(hashed, sort_keys=True).encode()).hexdigest()[:16]
            cells.append(Cell(id=digest, **content, models=models))
    return cells
