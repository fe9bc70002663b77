"""A sweep's grid expanded into cells: the cell record, the bounds counted from the axes before any cell is built,
and each cell's id, a hash of everything it computes from (the code included).

The ``model`` axis is not a grid dimension of cells: a model family does not change the simulated frames, so a cell
simulates once and fits every requested family on the same spectra. Its id covers the families only when they
differ from the paper's family alone, so sweeps without the axis keep the ids (and results) they had.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path

from .. import defaults
from ..analysis.magnitude_estimation import schedule_size_problem
from ..errors import ConfigError
from ..model.registry import paper_family
from ..paper import SMOOTH_PAD
from ..sim.limits import panel_problem
from ..sim.specimens import SPECIMEN_SETS

#: Most cells (designs x seeds) in one sweep: at seconds to a minute each, 100,000 cells are days of a cluster;
#: counted from the axes before any cell is built (a 1000 x 1000 grid is refused at once).
MAX_CELLS = 100_000
#: Most frames one cell renders (specimens x forces x repetitions; the paper's pad: 14 x 3 x 10 = 420): 50 times the
#: paper, tens of minutes and about 100 MB of spectra per cell.
MAX_CELL_FRAMES = 20_000
FINGERPRINT_ONLY = ("fingerprint_period_mm", "ridge_height_mm")  # meaningless for the smooth pad
#: The model families a cell fits: one value in [sweep] or a list in [axes], like a design parameter, but every
#: family of a design is fitted in the same cell (the frames do not depend on the model).
MODEL_KEY = "model"
#: The paper's family alone: what a sweep fits unless its file names families (the registry's paper family).
PAPER_ONLY = (paper_family().name,)


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
    code: str = ""  # fingerprint of the twin and analysis that compute it (explore.code_fingerprint)
    models: tuple[str, ...] = PAPER_ONLY  # the families fitted on the cell's spectra, in the registry's order

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


def forces_label(forces_n) -> str:
    return ",".join(f"{f:g}" for f in forces_n)


def _error(path: Path, message: str) -> ConfigError:
    return ConfigError(message, path=path)


def _label(key: str, value) -> object:
    if key == "forces_n":
        return forces_label(value)
    if key == "specimens":
        return value if isinstance(value, str) else ",".join(value)
    return value


def _where(key: str, axes: dict) -> str:
    return f"[axes] {key}" if key in axes else f"[sweep] {key}"


def _values(key: str, fixed: dict, axes: dict) -> list:
    return axes[key] if key in axes else [fixed[key]]


def _check_size(path: Path, fixed: dict, axes: dict[str, list], run: dict) -> None:
    """The sweep's bounds that need the whole file: cells per sweep, frames and pixels per cell, the panel, and
    field lengths that would make the same frame; counted from the axes, so nothing is built to find out."""
    cells = 0
    for pad in _values("pad", fixed, axes):
        grid = math.prod(len(v) for k, v in axes.items() if k != "pad" and not (pad == SMOOTH_PAD and k in FINGERPRINT_ONLY))
        cells += grid * len(run["seeds"])
    if cells > MAX_CELLS:
        sizes = " x ".join(f"{len(v)} {k}" for k, v in axes.items())
        raise _error(path, f"[axes]: {sizes} x {len(run['seeds'])} seeds make {cells} cells, above the limit of "
                           f"{MAX_CELLS} per sweep; split it into several sweeps")
    specimens = max(len(SPECIMEN_SETS[v] if isinstance(v, str) else v) for v in _values("specimens", fixed, axes))
    forces = max(len(v) for v in _values("forces_n", fixed, axes))
    repetitions = max(_values("repetitions", fixed, axes))
    if specimens * forces * repetitions > MAX_CELL_FRAMES:
        raise _error(path, f"{_where('specimens', axes)} x {_where('forces_n', axes)} x {_where('repetitions', axes)}"
                           f": a cell of {specimens} specimens x {forces} forces x {repetitions} repetitions renders "
                           f"{specimens * forces * repetitions} frames, above the limit of {MAX_CELL_FRAMES}")
    names = ("[sweep] participants", "[sweep] sessions")
    problem = (panel_problem(run["participants"], run["sessions"], names)
               or schedule_size_problem(run["participants"], run["sessions"], specimens - 1, names=names))
    if problem:
        raise _error(path, problem)
    _check_fields(path, _values("field_length_mm", fixed, axes), _where("field_length_mm", axes), run)


def _width_px(field_mm: float | None, run: dict) -> int:
    """The frame's width for a field length: the camera's pixel pitch, whole pixels (the sweep's width if None)."""
    return run["width_px"] if field_mm is None else max(16, int(round(field_mm * defaults.PX_PER_MM)))


def _check_fields(path: Path, fields: list, where: str, run: dict) -> None:
    """Every field length makes a frame within the pixel limit, and no two make the same frame (one cell id)."""
    height = run["height_px"]
    longest_mm = defaults.MAX_PIXELS / height / defaults.PX_PER_MM
    widths: dict[int, float] = {}
    for field_mm in fields:
        if field_mm is None:
            continue
        if field_mm > longest_mm:
            raise _error(path, f"{where}: {field_mm:g} mm at {defaults.PX_PER_MM:g} px/mm and {height} px high is a "
                               f"frame above the limit of {defaults.MAX_PIXELS / 1e6:g} Mpx (at most "
                               f"{longest_mm:.0f} mm)")
        width = _width_px(field_mm, run)
        if width in widths:
            raise _error(path, f"{where}: {widths[width]:g} and {field_mm:g} mm make the same frame of {width} px (a "
                               f"pixel is {1 / defaults.PX_PER_MM:.4g} mm), so the same cell; list one of them")
        widths[width] = field_mm


def _design_points(fixed: dict, axes: dict[str, list]) -> list[dict]:
    """The grid's distinct designs (a smooth pad has no ridge settings, so those collapse)."""
    keys = list(axes)
    points, seen = [], set()
    for combo in itertools.product(*(axes[k] for k in keys)):
        point = {**fixed, **dict(zip(keys, combo))}
        if point["pad"] == SMOOTH_PAD:
            for key in FINGERPRINT_ONLY:
                point[key] = None
        signature = json.dumps({k: _label(k, v) for k, v in point.items()}, sort_keys=True)
        if signature not in seen:
            seen.add(signature)
            points.append(point)
    return points


def _cells(points: list[dict], run: dict, models: tuple[str, ...] = PAPER_ONLY) -> list[Cell]:
    """One cell per design and seed, its id a hash of everything it computes from, the code included.

    The model families enter the hash only when they are not the paper's PLS alone: a sweep without the ``model``
    axis hashes exactly the content it always did, and any other set of families gives other ids.
    """
    from .code_fingerprint import code_fingerprint

    code = code_fingerprint()
    cells = []
    for point in points:
        specimens = point["specimens"]
        names = SPECIMEN_SETS[specimens] if isinstance(specimens, str) else specimens
        cell_width = _width_px(point["field_length_mm"], run)
        for seed in run["seeds"]:
            content = dict(
                seed=seed, pad=point["pad"], fingerprint_period_mm=point["fingerprint_period_mm"],
                ridge_height_mm=point["ridge_height_mm"], pad_modulus_mpa=point["pad_modulus_mpa"],
                field_length_mm=round(cell_width / defaults.PX_PER_MM, 6), forces_n=tuple(point["forces_n"]),
                specimens=tuple(names), specimens_label=_label("specimens", specimens),
                repetitions=point["repetitions"], ratings_from=point["ratings_from"], participants=run["participants"],
                sessions=run["sessions"], width_px=cell_width, height_px=run["height_px"],
                max_components=run["max_components"], cv=run["cv"], code=code,
            )
            hashed = content if models == PAPER_ONLY else {**content, "models": list(models)}
            digest = hashlib.sha256(json.dumps(hashed, sort_keys=True).encode()).hexdigest()[:16]
            cells.append(Cell(id=digest, **content, models=models))
    return cells
