"""What a simulation may replace: an empty folder, its own interrupted run, or (with ``--force``) its own complete run.

Never a real study, a folder of other files, or a simulation the rig has captured real frames into.
"""
from __future__ import annotations

import io
import os
import re
import tomllib
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from .._util import atomic
from .._util.files import open_regular, read_regular
from ..errors import PASS_FORCE, InputError, OutputExistsError
from ..io.study import COMPLETE_MARKER, IMAGES_DIR, MANIFEST_CSV, RATINGS_CSV, SPECIMENS_CSV, STUDY_TOML
from ..io.writer import captured_images, refuse_captured

SIMULATION_FILES = (STUDY_TOML, SPECIMENS_CSV, MANIFEST_CSV, RATINGS_CSV, COMPLETE_MARKER)
_IMAGE_NAME = re.compile(r"^[A-Za-z0-9.\-_]+_[0-9.e+\-]+N_r[0-9]+\.png$")  # plan_trials' names


def is_simulated_study(root: str | os.PathLike[str]) -> bool:
    """True if ``root`` holds a study.toml with a ``[simulation]`` table (the simulator wrote it)."""
    try:
        with os.fdopen(open_regular(Path(root) / STUDY_TOML), "rb") as handle:  # a FIFO there: no wait
            return isinstance(tomllib.load(handle).get("simulation"), dict)
    except (OSError, InputError, tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError):
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
        raise OutputExistsError(f"folder exists and is not empty; {PASS_FORCE} to write into it", path=root)
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
        manifest = pd.read_csv(io.BytesIO(read_regular(root / MANIFEST_CSV)), usecols=["image"], dtype=str,
                               keep_default_na=False)  # a FIFO there: no wait
        listed = {str(Path(p)) for p in manifest["image"]}
    except (OSError, InputError, ValueError, pd.errors.ParserError, UnicodeDecodeError):
        pass
    captured = {str(Path(p)) for p in captured_images(root / MANIFEST_CSV) if p}

    def owned(rel: Path) -> bool:
        parts = rel.parts
        if len(parts) == 1:
            return parts[0] in SIMULATION_FILES
        return (len(parts) == 2 and parts[0] == IMAGES_DIR and str(rel) not in captured
                and (str(rel) in listed or bool(_IMAGE_NAME.match(parts[1]))))

    return owned
