"""Writing a study folder atomically, file by file: used by both the simulator and the rig.

A folder also says where its frames came from, and never holds both kinds: the simulator marks its own with a
``[simulation]`` table in study.toml (and a completion marker), the rig gives every manifest row the time its frame
was taken. Real frames in a simulated folder would be labelled simulated in every report, and a later
``simulate --force`` would delete them: :func:`study_sources` lets every writer refuse the other's folder.
"""
from __future__ import annotations

import csv
import io
import os
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from .. import defaults
from .._util import atomic
from .._util.files import open_regular, read_regular
from ..errors import PASS_FORCE, InputError, OutputExistsError
from ..paper import PAPER_FORCES_N, REFERENCE_SPECIMEN
from .sensor_settings import SensorSettings
from .study import (
    COMPLETE_MARKER,
    IMAGES_DIR,
    MANIFEST_COLUMNS,
    MANIFEST_CSV,
    RATINGS_CSV,
    SPECIMEN_COLUMNS,
    SPECIMENS_CSV,
    STUDY_TOML,
)
from .toml_write import dump_toml

SIMULATED, CAPTURED = "simulated", "captured"
CAPTURE_TIME_COLUMN = "timestamp"  # the rig's manifest column: the moment each real frame was taken


def _has_simulation_table(path: Path) -> bool:
    try:
        with os.fdopen(open_regular(path), "rb") as handle:  # a FIFO there: no wait
            return isinstance(tomllib.load(handle).get("simulation"), dict)
    except (OSError, InputError, tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError):
        return False


def captured_images(manifest: str | os.PathLike[str]) -> set[str]:
    """The images of the manifest rows the rig wrote (a capture time given): real frames, never the simulator's."""
    try:
        with open(open_regular(manifest), newline="", encoding="utf-8-sig") as handle:  # a FIFO there: no wait
            first = handle.readline()
            delimiter = max(",;\t", key=first.count)  # as the rig wrote it, or re-saved by a European Excel
            header = [h.strip() for h in next(csv.reader([first], delimiter=delimiter), [])]
            if CAPTURE_TIME_COLUMN not in header or "image" not in header:
                return set()
            at, image = header.index(CAPTURE_TIME_COLUMN), header.index("image")
            return {row[image].strip() for row in csv.reader(handle, delimiter=delimiter)
                    if len(row) > max(at, image) and row[at].strip()}
    except (OSError, InputError, UnicodeDecodeError, csv.Error):
        return set()


def study_sources(root: str | os.PathLike[str]) -> set[str]:
    """Where the frames of the folder ``root`` came from: {"simulated"}, {"captured"}, both (a mixed folder an older
    roughsense let happen) or none (new, empty, or a study laid out by hand)."""
    root = Path(root)
    found = set()
    if (root / COMPLETE_MARKER).exists() or _has_simulation_table(root / STUDY_TOML):
        found.add(SIMULATED)
    if captured_images(root / MANIFEST_CSV):
        found.add(CAPTURED)
    return found


def refuse_captured(root: str | os.PathLike[str], advice: str) -> None:
    """A writer that would replace study files refuses a folder of real frames, ``--force`` or not."""
    if CAPTURED in study_sources(root):
        raise OutputExistsError(f"holds frames captured by the rig ({MANIFEST_CSV} rows with a {CAPTURE_TIME_COLUMN}); "
                                f"{advice}", path=root)


def refuse_simulated(root: str | os.PathLike[str], advice: str) -> None:
    """The rig refuses a folder the simulator wrote: its real frames would be reported as simulated."""
    if SIMULATED in study_sources(root):
        raise OutputExistsError(f"is a simulated study (its {STUDY_TOML} has a [simulation] table, or it has the "
                                f"simulator's {COMPLETE_MARKER} marker); {advice}", path=root)


class StudyWriter:
    """Writes a study folder atomically, file by file. Used by both the simulator and the rig.

    A non-empty folder is refused unless ``force`` (then files roughsense writes are replaced, and
    nothing else is touched) or ``resume`` (the rig appends to its own earlier session). ``source="captured"``
    (the rig) also refuses a simulated folder, whatever else allows it.

    Parameters
    ----------
    root : str or os.PathLike
        The study folder (made if missing, with its ``images/``).
    force : bool
        Write into a non-empty folder, replacing roughsense's own files.
    resume : bool
        Append to an earlier session of the rig.
    source : str, optional
        ``"captured"`` for the rig's real frames.

    Examples
    --------
    A study folder by hand (docs/study.md gives every column): two synthetic images, then read back.

    >>> import numpy as np
    >>> import pandas as pd
    >>> import roughsense as rs
    >>> writer = rs.StudyWriter("by-hand")
    >>> x_mm = np.arange(1920) / 34.9
    >>> rows = []
    >>> for specimen, period in [("R2", 2.0), ("R3", 3.0)]:
    ...     image = np.tile(127 + 100 * np.sin(2 * np.pi * x_mm / period), (160, 1)).astype(np.uint8)
    ...     rows.append({"image": writer.write_image(f"{specimen}.png", image), "specimen": specimen,
    ...                  "pad": "smooth", "force_n": 2.0, "repetition": 1})
    >>> _ = writer.write_manifest(pd.DataFrame(rows))
    >>> _ = writer.write_specimens(pd.DataFrame({"specimen": ["R2", "R3"], "shape": "rectangular",
    ...                                          "wavelength_mm": [2.0, 3.0]}))
    >>> _ = writer.write_config(name="by-hand", forces_n=[2.0])
    >>> study = rs.read_study("by-hand")
    >>> study.specimen_names, sorted(study.manifest["condition"].unique())
    (['R2', 'R3'], ['2N'])
    """

    def __init__(self, root: str | os.PathLike[str], *, force: bool = False, resume: bool = False,
                 source: str | None = None) -> None:
        self.root = Path(root)
        self.force = force
        if self.root.exists() and not self.root.is_dir():
            raise OutputExistsError("exists and is not a folder", path=self.root)
        if source == CAPTURED:
            refuse_simulated(self.root, "capture real frames into a folder of their own")
        if self.root.is_dir() and any(self.root.iterdir()) and not (force or resume):
            raise OutputExistsError(f"folder exists and is not empty; {PASS_FORCE} to write into it", path=self.root)
        self.root.mkdir(parents=True, exist_ok=True)
        (self.root / IMAGES_DIR).mkdir(exist_ok=True)

    def write_config(
        self,
        *,
        name: str,
        reference_specimen: str = REFERENCE_SPECIMEN,
        sensor: SensorSettings = SensorSettings(),
        forces_n: Sequence[float] = PAPER_FORCES_N,
        extra: Mapping[str, Mapping[str, object]] | None = None,
    ) -> Path:
        """Write ``study.toml``.

        Parameters
        ----------
        name : str
            The study's name.
        reference_specimen : str
            The specimen whose perceived roughness is 1 (the modulus of the ratings).
        sensor : SensorSettings
            The camera's scale and the contact band's crop.
        forces_n : sequence of float
            The protocol's nominal forces (N).
        extra : mapping, optional
            Further tables, e.g. ``{"pads": {"fingerprint": {"ridge_period_mm": 1.0}}}``.

        Returns
        -------
        pathlib.Path
            The file written.
        """
        roi = sensor.roi if isinstance(sensor.roi, str) else list(sensor.roi)
        tables: dict[str, Mapping[str, object]] = {
            "study": {"name": name, "reference_specimen": reference_specimen},
            "sensor": {"px_per_mm": float(sensor.px_per_mm), "roi": roi,
                       **({"max_pixels": sensor.max_pixels} if sensor.max_pixels != defaults.MAX_PIXELS else {})},
            "protocol": {"forces_n": [float(f) for f in forces_n]},
        }
        tables.update(extra or {})
        return atomic.write_text(self.root / STUDY_TOML, dump_toml(tables))

    def write_specimens(self, specimens: pd.DataFrame) -> Path:
        """Write ``specimens.csv``.

        Parameters
        ----------
        specimens : pandas.DataFrame
            Columns specimen, shape, wavelength_mm (and any geometry columns).

        Returns
        -------
        pathlib.Path
            The file written.
        """
        return self._write_table(SPECIMENS_CSV, specimens, SPECIMEN_COLUMNS)

    def write_manifest(self, manifest: pd.DataFrame) -> Path:
        """Write ``manifest.csv``, one row per image.

        Parameters
        ----------
        manifest : pandas.DataFrame
            Columns image (relative to the folder), specimen, pad, force_n, repetition.

        Returns
        -------
        pathlib.Path
            The file written.
        """
        return self._write_table(MANIFEST_CSV, manifest, MANIFEST_COLUMNS)

    def _write_table(self, name: str, table: pd.DataFrame, required: Sequence[str]) -> Path:
        """A caller's bug, not a user's: the sources build these tables, so a missing column is a plain ValueError."""
        missing = [c for c in required if c not in table.columns]
        if missing:
            raise ValueError(f"{name} lacks {missing}")
        return atomic.write_csv(self.root / name, table, for_people=False)  # the folder's data, read back as written

    def append_manifest_row(self, row: Mapping[str, object]) -> Path:
        """Append one row by rewriting the file atomically: a crash never leaves half a row.

        Parameters
        ----------
        row : mapping
            One manifest row (:meth:`write_manifest`'s columns).

        Returns
        -------
        pathlib.Path
            The manifest.
        """
        path = self.root / MANIFEST_CSV
        new = pd.DataFrame([dict(row)])
        if path.exists():
            old = pd.read_csv(io.BytesIO(read_regular(path)), dtype={"image": str, "specimen": str, "pad": str},
                              keep_default_na=False, na_values=[""],  # a FIFO there: refused, no wait
                              index_col=False)  # a hand-edited file's trailing commas must not shift the columns
            old = old.drop(columns=[c for c in old.columns if str(c).startswith("Unnamed: ") and old[c].isna().all()])
            new = pd.concat([old, new], ignore_index=True)
        return self.write_manifest(new)

    def write_ratings(self, ratings: pd.DataFrame) -> Path:
        """Write ``ratings.csv``.

        Parameters
        ----------
        ratings : pandas.DataFrame
            Columns participant, session, specimen, rating (magnitude estimates).

        Returns
        -------
        pathlib.Path
            The file written.
        """
        return atomic.write_csv(self.root / RATINGS_CSV, ratings, for_people=False)

    def image_path(self, name: str) -> Path:
        """Where :meth:`write_image` puts an image.

        Parameters
        ----------
        name : str
            The image's file name.

        Returns
        -------
        pathlib.Path
            ``images/<name>`` in the folder.
        """
        return self.root / IMAGES_DIR / name

    def write_image(self, name: str, image: np.ndarray, *, params: Sequence[int] = ()) -> str:
        """Encode and write ``images/<name>`` atomically; returns the manifest-relative path.

        ``params`` are OpenCV's ``imwrite`` flags (e.g. the PNG compression strategy); the file stays a standard one.

        Parameters
        ----------
        name : str
            The file name; its extension picks the format (PNG without one).
        image : numpy.ndarray
            Gray (h, w) or RGB (h, w, 3) pixels, uint8 or uint16.
        params : sequence of int
            OpenCV's ``imwrite`` flags.

        Returns
        -------
        str
            The path for the manifest's image column, ``images/<name>``.
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
