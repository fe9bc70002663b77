"""Results that survive: one Parquet file per finished cell, written atomically, beside a copy of the sweep file.

Layout of ``--out``::

    sweep.toml              the sweep file this folder belongs to (copied at the start)
    results/cell-ID.parquet one row per pad x condition x CV scheme x model of cell ID
                            (``pandas.read_parquet(out/"results")``; ``model`` is the last column)
    specimens/cell-ID.parquet  the same per specimen
    failures.csv            cells that failed: id, seed, design and the one-line error (retried on the next run)
    index.html              the report

A cell is finished when its results file exists: the specimens file is written first, the results file last, each
by rename, so a sweep killed at any moment leaves only whole files and a rerun recomputes exactly the cells missing.
A finished cell is verified, not trusted: a file that does not read back (truncated, emptied by a full disk), holds no
rows, or holds another cell's rows (copied by hand, or from another sweep) is removed and its cell computed again,
with one warning naming the file.
"""
from __future__ import annotations

import math
import os
import tomllib
import warnings
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from .._util import atomic
from .._util.checks import short_repr, shown
from ..errors import PASS_FORCE, OutputExistsError, RoughsenseWarning
from .cell import RESULT_COLUMNS, SPECIMEN_COLUMNS, result_keys
from .sweep import COLUMN_KINDS, Sweep
from .sweep_cells import MODEL_KEY, Cell

SWEEP_COPY = "sweep.toml"
RESULTS_DIR = "results"
SPECIMENS_DIR = "specimens"
FAILURES_CSV = "failures.csv"
REPORT = "index.html"
_TYPES = {"str": pa.string(), "float": pa.float64(), "int": pa.int64()}
_BASE_TYPES = {
    "cell": pa.string(), "seed": pa.int64(), "pad": pa.string(), "condition": pa.string(), "cv": pa.string(),
    "n_components": pa.int64(), "specimen": pa.string(), "shape": pa.string(),
}


def _schema(columns: list[str]) -> pa.Schema:
    """Fixed column types, so every cell's file reads back as one table (a NaN-only column stays float)."""
    design = [k for k in COLUMN_KINDS if k != "pad"]
    fields = [pa.field(c, _BASE_TYPES.get(c, pa.float64())) for c in columns]
    fields += [pa.field(k, _TYPES[COLUMN_KINDS[k]]) for k in design]
    return pa.schema(fields)


RESULT_SCHEMA = _schema(RESULT_COLUMNS)
SPECIMEN_SCHEMA = _schema(SPECIMEN_COLUMNS)


def cell_file(cell_id: str) -> str:
    return f"cell-{cell_id}.parquet"


class ResultStore:
    """The output folder of one sweep: refuses another sweep's folder (unless ``force``), knows finished cells."""

    def __init__(self, out: str | os.PathLike[str], sweep: Sweep, *, force: bool = False) -> None:
        self.root = Path(out)
        self.sweep = sweep
        self.force = force
        if self.root.exists() and not self.root.is_dir():
            raise OutputExistsError("exists and is not a folder", path=self.root)
        for sub in (RESULTS_DIR, SPECIMENS_DIR):  # written into cell by cell: a link there would send them elsewhere
            if os.path.islink(self.root / sub) or (os.path.lexists(self.root / sub) and not (self.root / sub).is_dir()):
                raise OutputExistsError(f"{sub} in it is not a folder roughsense made (a link or a file); delete "
                                        f"{self.root / sub} or choose another folder", path=self.root)
        self._check_owner(force)

    @classmethod
    def reader(cls, out: str | os.PathLike[str], sweep: Sweep) -> ResultStore:
        """Read access to a folder a sweep has run in (no ownership checks: nothing is written)."""
        store = cls.__new__(cls)
        store.root, store.sweep, store.force = Path(out), sweep, False
        return store

    def _check_owner(self, force: bool) -> None:
        copy = self.root / SWEEP_COPY
        if not self.root.is_dir() or not any(self.root.iterdir()):
            return
        if copy.is_file():
            try:
                with copy.open("rb") as handle:
                    same = tomllib.load(handle) == self.sweep.source
            except (tomllib.TOMLDecodeError, UnicodeDecodeError, OSError):
                same = False
            if same or force:
                return
            raise OutputExistsError("holds the results of another sweep (its sweep.toml differs); choose a new folder "
                                    f"or {PASS_FORCE} to replace them", path=self.root)
        if not force:
            raise OutputExistsError("folder is not empty and holds no sweep (no sweep.toml); choose a new or empty "
                                    f"folder, or {PASS_FORCE} to write into it", path=self.root)

    def foreign(self) -> list[Path]:
        """Cell files that are not cells of this sweep (another sweep's, or computed by another roughsense)."""
        ours = {cell_file(c.id) for c in self.sweep.cells}
        return [p for sub in (RESULTS_DIR, SPECIMENS_DIR) if (self.root / sub).is_dir()
                for p in sorted((self.root / sub).glob("cell-*.parquet")) if p.name not in ours]

    def prepare(self) -> list[str]:
        """Create the folder, copy the sweep file, drop cell files not of this sweep (``force`` only); their ids."""
        foreign = self.foreign()
        if foreign and not self.force:
            raise OutputExistsError(f"holds {len(foreign)} result files that are not cells of this sweep (another "
                                    f"sweep's, or computed by another version of roughsense); {PASS_FORCE} to "
                                    "replace them", path=self.root)
        for sub in (RESULTS_DIR, SPECIMENS_DIR):
            (self.root / sub).mkdir(parents=True, exist_ok=True)
        atomic.write_bytes(self.root / SWEEP_COPY, self.sweep.path.read_bytes())
        for path in foreign:
            path.unlink()
        return sorted({p.stem.removeprefix("cell-") for p in foreign})

    def finished(self) -> set[str]:
        """Ids of the cells whose files read back as those cells; a damaged cell's files are removed (and said so),
        so the run computes it again. Files of other sweeps' cells are listed as they are: prepare() judges them."""
        folder = self.root / RESULTS_DIR
        if not folder.is_dir():
            return set()
        cells = {c.id: c for c in self.sweep.cells}
        done, damaged = set(), []
        for path in sorted(folder.glob("cell-*.parquet")):
            cell_id = path.stem.removeprefix("cell-")
            problem = self.check_cell(cells[cell_id]) if cell_id in cells else None
            if problem is None:
                done.add(cell_id)
                continue
            damaged.append(problem)
            for sub in (SPECIMENS_DIR, RESULTS_DIR):  # the results file last: it is the cell's 'done' mark
                (self.root / sub / path.name).unlink(missing_ok=True)
        if damaged:
            more = f" (and {len(damaged) - 1} more)" if len(damaged) > 1 else ""
            warnings.warn(RoughsenseWarning(f"{damaged[0]}{more}; computing {'these cells' if more else 'it'} again"),
                          stacklevel=2)
        return done

    def check_cell(self, cell: Cell) -> str | None:
        """Why the stored files of ``cell`` cannot be trusted (naming the file), or None if both are that cell's,
        whole: every row its design promises (:func:`_missing_rows`)."""
        frames = []
        for sub, schema in ((RESULTS_DIR, RESULT_SCHEMA), (SPECIMENS_DIR, SPECIMEN_SCHEMA)):
            path = self.root / sub / cell_file(cell.id)
            try:
                frame = pq.read_table(path, schema=schema).to_pandas()
            except (OSError, pa.ArrowException, ValueError) as exc:
                reason = " ".join(str(exc).split())[:120] or type(exc).__name__
                return f"{path}: does not read back ({reason})"
            if frame.empty:
                return f"{path}: holds no rows"
            wrong = _other_cell(frame, cell)
            if wrong is not None:
                return f"{path}: is not the cell its name says ({wrong})"
            frames.append((path, frame))
        return _missing_rows(cell, *frames)

    def write_cell(self, results: pd.DataFrame, specimens: pd.DataFrame, cell_id: str) -> None:
        """Specimens first, results last: the results file is the cell's 'done' mark."""
        for frame, sub, schema in ((specimens, SPECIMENS_DIR, SPECIMEN_SCHEMA), (results, RESULTS_DIR, RESULT_SCHEMA)):
            table = pa.Table.from_pandas(frame[schema.names], schema=schema, preserve_index=False)
            with atomic.atomic_open(self.root / sub / cell_file(cell_id), "wb") as handle:
                pq.write_table(table, handle)

    def write_failures(self, failures: list[dict]) -> None:
        path = self.root / FAILURES_CSV
        if failures:
            atomic.write_csv(path, pd.DataFrame(failures))
        elif path.is_file():
            path.unlink()  # every earlier failure has now been computed

    def read(self, sub: str = RESULTS_DIR) -> pd.DataFrame:
        """Every cell file in the folder (after a run, exactly this sweep's finished cells: a run refuses others).

        A file that does not read back is left out with a warning naming it (a run computes its cell again)."""
        schema = RESULT_SCHEMA if sub == RESULTS_DIR else SPECIMEN_SCHEMA
        tables = []
        for path in sorted((self.root / sub).glob("cell-*.parquet")):
            try:
                tables.append(pq.read_table(path, schema=schema))
            except (OSError, pa.ArrowException, ValueError) as exc:
                reason = " ".join(str(exc).split())[:120] or type(exc).__name__
                warnings.warn(RoughsenseWarning(f"{path}: does not read back ({reason}); left out of the report, "
                                                "rerun the sweep to compute its cell again"), stacklevel=2)
        if not tables:
            return schema.empty_table().to_pandas()
        return pa.concat_tables(tables).to_pandas()


def _missing_rows(cell: Cell, results: tuple[Path, pd.DataFrame], specimens: tuple[Path, pd.DataFrame]) -> str | None:
    """What a cell's files lack of the rows its design promises, or None.

    The results hold one row per condition x CV scheme x model family (:func:`.cell.result_keys`), each once; the
    specimens file, for each of those, one row per specimen its result row counts. A cell with rows dropped (a
    model family's, say) would otherwise count as finished and be missing from every summary.
    """
    keys = ["condition", "cv", MODEL_KEY]
    expected = result_keys(cell)
    (results_path, summary), (specimens_path, rows) = results, specimens
    found = list(summary[keys].astype(str).itertuples(index=False, name=None))
    listed = set(rows[keys].astype(str).itertuples(index=False, name=None))
    for path, have in ((results_path, found), (specimens_path, listed)):
        missing = sorted(expected - set(have))
        if missing:
            more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
            return f"{path}: lacks the rows of {' '.join(missing[0])}{more}"
    if len(found) != len(set(found)) or set(found) != expected:
        return f"{results_path}: holds rows its cell's design does not promise, or one row twice"
    counts = rows.groupby(keys, sort=False).size()
    promised = summary.set_index(keys)["n_specimens"]
    for key, count in counts.items():
        wanted = promised.get(key)
        if wanted is not None and wanted == wanted and int(wanted) != int(count):  # (NaN: a cell with no count)
            return (f"{specimens_path}: {' '.join(map(str, key))} holds {count} specimen rows, its result row counts "
                    f"{int(wanted)}")
    return None


def _other_cell(frame: pd.DataFrame, cell: Cell) -> str | None:
    """What in a cell file's rows says they are not ``cell``'s (its id, seed, design or model families), or None."""
    ids = set(frame["cell"].astype(str))
    if ids != {cell.id}:
        return f"rows of cell {short_repr(sorted(ids)[0])}"
    if not (frame["seed"] == cell.seed).all():
        return f"seed {frame['seed'].iloc[0]}, not {cell.seed}"
    expected = {**cell.columns(), "pad": cell.pad}
    families = set(expected.pop(MODEL_KEY).split(","))
    if not set(frame[MODEL_KEY].astype(str)) <= families:
        return f"model families other than {', '.join(sorted(families))}"
    for key, value in expected.items():
        column = frame[key]
        if isinstance(value, float) and math.isnan(value):
            same = column.isna()
        else:
            same = column == value
        if not bool(same.all()):
            return f"{key} {shown(column[~same].iloc[0])}, not {shown(value)}"
    return None
