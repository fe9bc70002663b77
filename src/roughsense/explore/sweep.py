"""The sweep file: a TOML grid of designs of the twin, checked up front and expanded into independent cells.

A cell is one grid point x one seed. Everything a cell needs travels inside :class:`Cell` (no files), so a worker on
another machine computes it from the cell alone, and the cell's id is a hash of exactly that content: a rerun of the
same sweep, or a sweep that shares some of its cells, finds them finished. This module reads and checks the file;
the grid's expansion into cells, their bounds and ids are :mod:`.sweep_cells`'.
"""
from __future__ import annotations

import json
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .. import defaults
from .._util.checks import POSITIVE, POSITIVE_INT, SEED, Constraint, Described, Integer, Options, given, short_repr
from .._util.files import open_regular
from ..analysis.magnitude_estimation import MAX_PARTICIPANTS, MAX_SESSIONS
from ..analysis.results import CV_SCHEMES
from ..errors import ConfigError
from ..io.numbers import toml_spelling_problem
from ..io.protocol import MAX_REPETITION, check_force
from ..model.registry import check_model_name
from ..model.registry import names as family_names
from ..paper import (
    PAPER_FORCES_N,
    PAPER_PARTICIPANTS,
    PAPER_REPETITIONS,
    PAPER_SESSIONS,
    REFERENCE_SPECIMEN,
    SMOOTH_PAD,
)
from ..sim.limits import pad_problem, specimen_problem
from ..sim.optics import HEIGHT_PX, WIDTH_PX
from ..sim.pads import PAD_NAMES, YOUNG_PA
from ..sim.panel import RATINGS_FROM
from ..sim.specimens import SPECIMEN_SETS, expand_specimen_sets, parse_specimen
from .sweep_cells import (
    MAX_CELLS,
    MODEL_KEY,
    PAPER_ONLY,
    Cell,
    _cells,
    _check_size,
    _design_points,
    _error,
    _label,
    forces_label,
)

MIN_FIELD_MM = 1.0 / defaults.F_MIN_PER_MM  # a shorter line cannot resolve the spectrum's lowest frequency
#: A sweep file is a few kB of settings and lists; a megabyte is no sweep anyone wrote by hand.
MAX_SWEEP_BYTES = 1_000_000
#: Longest sweep name: it titles the report page.
MAX_NAME_CHARS = 200
#: A sweep of more cells than this runs only with ``--yes``, after its estimate is shown: hours of work are asked for.
CONFIRM_CELLS = 1000
#: Core-seconds a cell costs per frame it renders, for that estimate: a paper-sized fingerprint-pad cell, 420 frames,
#: took 6.7 s on one core (BENCHMARKS.md, bench_explore); a smooth-pad cell about 60 % of that.
CELL_SECONDS_PER_FRAME = 6.7 / 420
#: ... and so does one of fewer cells whose estimate exceeds that of CONFIRM_CELLS paper-sized cells (420 frames each):
#: a cell may render up to MAX_CELL_FRAMES, so 999 cells can be 50 times the hours of 1000.
CONFIRM_CORE_HOURS = CONFIRM_CELLS * 420 * CELL_SECONDS_PER_FRAME / 3600
#: Design parameters: every one may be a single value in [sweep] or a list of values in [axes].
DESIGN_KEYS = ("pad", "fingerprint_period_mm", "ridge_height_mm", "pad_modulus_mpa", "field_length_mm", "forces_n",
               "specimens", "repetitions", "ratings_from")
SETTING_KEYS = ("name", "seeds", "max_components", "participants", "sessions", "image_size_px", "cv")
#: A design parameter the sweep file does not set: the paper's rig, each value read from its home.
DEFAULTS = {
    "pad": SMOOTH_PAD, "fingerprint_period_mm": defaults.FINGERPRINT_PERIOD_MM, "ridge_height_mm": defaults.RIDGE_HEIGHT_MM,
    "pad_modulus_mpa": YOUNG_PA / 1e6, "field_length_mm": None, "forces_n": PAPER_FORCES_N,
    "specimens": "paper", "repetitions": PAPER_REPETITIONS, "ratings_from": defaults.RATINGS_FROM,
}
#: Column type of each design parameter in the results (strings for lists, NaN where a value does not apply).
COLUMN_KINDS = {"pad": "str", "fingerprint_period_mm": "float", "ridge_height_mm": "float",
                "pad_modulus_mpa": "float", "field_length_mm": "float", "forces_n": "str", "specimens": "str",
                "repetitions": "int", "ratings_from": "str", MODEL_KEY: "str"}


@dataclass
class Sweep:
    """A checked sweep file: its settings, its axes (design parameters that vary) and the cells of its grid."""

    path: Path
    name: str
    axes: dict[str, list]
    cells: list[Cell]
    cv: tuple[str, ...]
    source: dict = field(default_factory=dict)  # the parsed file, to tell one sweep from another
    models: tuple[str, ...] = PAPER_ONLY


def _checked(path: Path, where: str, value, constraint: Constraint):
    """``value`` cast by its constraint, or one line naming where it was read, built from the constraint."""
    if constraint.accepts(value):
        return constraint.cast(value)
    if isinstance(constraint, Options):
        raise _error(path, f"{where}: unknown value {value!r} (expected one of {', '.join(constraint.values)})")
    raise _error(path, f"{where}: expected {constraint.describe()}, got {given(value)}")


_POSITIVE = Described(POSITIVE, "a positive number")
#: What each design value must be (one value in [sweep], each value of an axis); checks that need more than the
#: value's kind and range follow in :data:`_DESIGN_FURTHER`.
DESIGN_CONSTRAINTS: dict[str, Constraint] = {
    "pad": Options(PAD_NAMES), "fingerprint_period_mm": _POSITIVE, "ridge_height_mm": _POSITIVE,
    "pad_modulus_mpa": _POSITIVE, "field_length_mm": _POSITIVE, "repetitions": Integer(2, MAX_REPETITION),
    "ratings_from": Options(RATINGS_FROM),
}
#: What each run setting must be (each element, for the lists ``seeds`` and ``image_size_px``).
RUN_CONSTRAINTS: dict[str, Constraint] = {
    "seeds": SEED, "max_components": POSITIVE_INT, "participants": Integer(2, MAX_PARTICIPANTS),
    "sessions": Integer(1, MAX_SESSIONS), "image_size_px": Integer(16),
}
#: The keyword of :func:`sim.limits.pad_problem` each pad key is checked with, and its unit's factor.
_PAD_LIMITS = {"fingerprint_period_mm": ("period_mm", 1.0), "ridge_height_mm": ("ridge_height_mm", 1.0),
               "pad_modulus_mpa": ("modulus_pa", 1e6)}


def _pad_value(path: Path, key: str, number: float, where: str) -> float:
    """A pad parameter within what the twin computes (sim.limits)."""
    keyword, factor = _PAD_LIMITS[key]
    problem = pad_problem(**{keyword: number * factor}, names=(where, where, where))
    if problem:
        raise _error(path, problem)
    return number


def _field_length(path: Path, key: str, length: float, where: str) -> float:
    if length < MIN_FIELD_MM:
        raise _error(path, f"{where}: {length:g} mm is shorter than {MIN_FIELD_MM:g} mm, the longest wavelength "
                           "the spectrum (0.1-1 mm^-1) resolves")
    return length


def _forces(path: Path, key: str, value, where: str) -> tuple[float, ...]:
    if not isinstance(value, list) or not value:
        raise _error(path, f"{where}: expected a non-empty list of forces in N, got {value!r}")
    try:
        forces = tuple(sorted(check_force(f, option=f"{where}: every force") for f in value))
    except ConfigError as exc:
        raise _error(path, exc.message) from None
    if len(set(forces_label(forces).split(","))) != len(forces):
        raise _error(path, f"{where}: forces {value!r} are not distinct")
    return forces


def _specimen_name(path: Path, where: str, text: str) -> str:
    try:
        specimen = parse_specimen(text)
    except ConfigError as exc:
        raise _error(path, f"{where}: {exc.message}") from None
    problem = specimen_problem(specimen)
    if problem:
        raise _error(path, f"{where}: {problem}")
    return specimen.name


def _specimens(path: Path, key: str, value, where: str) -> str | tuple[str, ...]:
    """A named specimen set (sim.specimens.SPECIMEN_SETS), or a list of specimens and sets (at least 4 specimens
    besides the reference), each within the twin."""
    if isinstance(value, str):
        value = value.strip().lower()  # as in a list, and as simulate --specimens reads a set's name
        if value not in SPECIMEN_SETS:
            raise _error(path, f"{where}: unknown specimen set {value!r} (expected one of "
                               f"{', '.join(SPECIMEN_SETS)}, or a list of specimens)")
        return value
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise _error(path, f"{where}: expected a list of specimens or a set name, got {value!r}")
    value = list(expand_specimen_sets(value))  # a set named in a list stands for its specimens
    names = [_specimen_name(path, where, text) for text in value]
    if len(set(names)) != len(names):
        raise _error(path, f"{where}: a specimen is listed twice in {value!r}")
    rated = [n for n in names if n != REFERENCE_SPECIMEN]
    if len(rated) < 4:
        raise _error(path, f"{where}: give at least 4 specimens besides the reference R3 (leave-one-specimen-out "
                           "needs 3 to choose the components of each held-out one)")
    return tuple(text.strip() for text in value)  # the specs as written: the simulator parses them again


#: The checks of a design value that its constraint cannot state: the twin's limits, lists of forces and specimens.
_DESIGN_FURTHER = {"fingerprint_period_mm": _pad_value, "ridge_height_mm": _pad_value, "pad_modulus_mpa": _pad_value,
                   "field_length_mm": _field_length, "forces_n": _forces, "specimens": _specimens}


def _check_value(path: Path, key: str, value, where: str):
    """One design value, checked and normalised (lists become tuples); raises naming the key and value."""
    if key == "pad" and isinstance(value, str):
        value = value.strip().lower()
    if key in DESIGN_CONSTRAINTS:
        value = _checked(path, where, value, DESIGN_CONSTRAINTS[key])
    further = _DESIGN_FURTHER.get(key)
    return value if further is None else further(path, key, value, where)


def read_sweep(path: str | os.PathLike[str]) -> Sweep:
    """Read and check a sweep file; every problem is one line naming the file and the key."""
    path = Path(path)
    if not path.exists():
        raise _error(path, "sweep file not found")
    try:
        with os.fdopen(open_regular(path, what="sweep file"), "rb") as handle:  # a FIFO: refused, no wait
            if os.fstat(handle.fileno()).st_size > MAX_SWEEP_BYTES:
                raise _error(path, f"is {os.fstat(handle.fileno()).st_size} bytes, above the limit of "
                                   f"{MAX_SWEEP_BYTES} for a sweep file")
            text = handle.read().decode("utf-8")
            source = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise _error(path, f"is not valid TOML ({exc})") from None
    except RecursionError:
        raise _error(path, "is not a sweep file: its values are nested too deeply") from None
    problem = toml_spelling_problem(text)
    if problem is not None:  # TOML's 1_0, 0x2 and inf are not numbers to any other reader of roughsense
        raise _error(path, problem)
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
    _check_size(path, fixed, axes, run)  # before a single design point is built
    cells = _cells(_design_points(fixed, axes), run, models)
    if len({c.id for c in cells}) != len(cells):  # _check_size refuses the known cases; never run one id twice
        raise _error(path, "[axes]: two designs of the grid make the same cell; list each design once")
    name = settings.get("name", path.stem)
    if not isinstance(name, str) or not name.strip():
        raise _error(path, f"[sweep] name: expected a text, got {short_repr(name)}")
    if len(name) > MAX_NAME_CHARS or not name.isprintable():  # the report's title and heading
        raise _error(path, f"[sweep] name: must be one line of at most {MAX_NAME_CHARS} printable characters, got "
                           f"{short_repr(name)}")
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
                               f"({', '.join(family_names())}), got {values!r}")
    elif MODEL_KEY in settings:
        where, values = f"[sweep] {MODEL_KEY}", [settings[MODEL_KEY]]
    else:
        return PAPER_ONLY
    try:
        names = [check_model_name(v, option=where) for v in values]
    except ConfigError as exc:
        raise _error(path, exc.message) from None
    if len(set(names)) != len(names):
        raise _error(path, f"{where}: a model is listed twice")
    return tuple(m for m in family_names() if m in names)


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
        raise _error(path, f"[sweep] seeds: expected a non-empty list of whole numbers, got {short_repr(seeds)}")
    if len(seeds) > MAX_CELLS:
        raise _error(path, f"[sweep] seeds: {len(seeds)} seeds, above the limit of {MAX_CELLS} cells per sweep")
    seeds = [_checked(path, "[sweep] seeds", s, RUN_CONSTRAINTS["seeds"]) for s in seeds]
    if len(set(seeds)) != len(seeds):
        raise _error(path, "[sweep] seeds: a seed is listed twice")
    given = {"max_components": defaults.MAX_COMPONENTS, "participants": PAPER_PARTICIPANTS, "sessions": PAPER_SESSIONS}
    run = {key: _checked(path, f"[sweep] {key}", settings.get(key, default), RUN_CONSTRAINTS[key])
           for key, default in given.items()}
    size = settings.get("image_size_px", [WIDTH_PX, HEIGHT_PX])
    if not (isinstance(size, list) and len(size) == 2):
        raise _error(path, f"[sweep] image_size_px: expected [width, height], got {size!r}")
    width_px, height_px = (_checked(path, "[sweep] image_size_px", v, RUN_CONSTRAINTS["image_size_px"]) for v in size)
    if width_px * height_px > defaults.MAX_PIXELS:  # the study contract's pixel limit holds for simulated frames too
        raise _error(path, f"[sweep] image_size_px: {width_px} x {height_px} px is above the limit of "
                           f"{defaults.MAX_PIXELS / 1e6:g} Mpx per frame")
    cv = settings.get("cv", list(CV_SCHEMES))
    if not isinstance(cv, list) or not cv or any(c not in CV_SCHEMES for c in cv):
        raise _error(path, f"[sweep] cv: expected a list of {', '.join(CV_SCHEMES)}, got {cv!r}")
    return dict(seeds=seeds, **run, width_px=width_px, height_px=height_px, cv=tuple(c for c in CV_SCHEMES if c in cv))


def _axes(axes_in: dict, path: Path) -> dict[str, list]:
    """Each axis's values, checked; a value listed twice is refused."""
    axes: dict[str, list] = {}
    for key, values in axes_in.items():
        if not isinstance(values, list):
            raise _error(path, f"[axes] {key}: expected a list of values, got {values!r}")
        if not values:
            raise _error(path, f"[axes] {key}: no values, so the grid is empty")
        if len(values) > MAX_CELLS:
            raise _error(path, f"[axes] {key}: {len(values)} values, above the limit of {MAX_CELLS} cells per sweep")
        checked = [_check_value(path, key, v, f"[axes] {key}") for v in values]
        if len({json.dumps(_label(key, v)) for v in checked}) != len(checked):
            raise _error(path, f"[axes] {key}: a value is listed twice")
        axes[key] = checked
    return axes


def estimated_core_hours(sweep: Sweep) -> float:
    """About how many core-hours the sweep's cells take (frames x :data:`CELL_SECONDS_PER_FRAME`), before any runs."""
    frames = sum(len(c.specimens) * len(c.forces_n) * c.repetitions for c in sweep.cells)
    return frames * CELL_SECONDS_PER_FRAME / 3600


def check_size_confirmed(sweep: Sweep, *, yes: bool, workers: int) -> str | None:
    """Refuse a sweep above :data:`CONFIRM_CELLS` cells or :data:`CONFIRM_CORE_HOURS` without ``yes`` (one line with
    its estimate); with it, the estimate to show. None for a sweep within both limits."""
    hours = estimated_core_hours(sweep)
    if len(sweep.cells) <= CONFIRM_CELLS and hours <= CONFIRM_CORE_HOURS:
        return None
    estimate = (f"{len(sweep.cells)} cells, about {hours:.1f} core-hours ({hours / max(workers, 1):.1f} h on "
                f"{workers} worker{'s' if workers != 1 else ''})")
    if not yes:
        limit = (f"more than {CONFIRM_CELLS} cells" if len(sweep.cells) > CONFIRM_CELLS else
                 f"more than {CONFIRM_CORE_HOURS:.1f} core-hours (as long as {CONFIRM_CELLS} paper-sized cells)")
        raise ConfigError(f"{estimate}: a sweep of {limit} runs only with --yes", path=sweep.path)
    return estimate
