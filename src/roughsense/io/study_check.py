"""``roughsense check``: every problem of a study folder at once, found by the very readers ``study`` uses.

A folder with five mistakes should take one run to fix, not five. Images are looked for on disk, not decoded.
"""
from __future__ import annotations

import os
import shlex
from dataclasses import dataclass
from pathlib import Path

from .._util.text import counted
from .problems import MAX_LISTED, Problems
from .sensor_settings import SensorSettings
from .study import load_study


@dataclass
class CheckResult:
    """What ``check`` found: the problems (none if the folder is fine) and the folder's size."""

    root: Path
    problems: Problems
    n_images: int
    n_specimens: int
    n_ratings: int | None  # None: no ratings.csv
    sensor: SensorSettings | None = None  # None: [sensor] has a problem of its own

    @property
    def ok(self) -> bool:
        return len(self.problems) == 0

    def summary(self) -> str:
        """The one line of a folder without problems."""
        ratings = "no ratings.csv" if self.n_ratings is None else counted(self.n_ratings, "rating")
        return f"study OK: {counted(self.n_images, 'image')}, {counted(self.n_specimens, 'specimen')}, {ratings}"

    def failure(self) -> str:
        """The one error line after the listed problems."""
        return (f"{counted(len(self.problems), 'problem')} (listed above); fix them and run "
                f"`roughsense check {shlex.quote(str(self.root))}` again")


def check_study(root: str | os.PathLike[str], *, limit: int = MAX_LISTED) -> CheckResult:
    """Validate the folder as ``study`` does, collecting every problem (the first ``limit`` in full)."""
    root = Path(root)
    problems = Problems(limit)
    study = load_study(root, problems=problems)
    return CheckResult(
        root=root, problems=problems,
        n_images=0 if study.manifest is None else len(study.manifest),
        n_specimens=0 if study.specimens is None else len(study.specimens),
        n_ratings=None if study.ratings is None else len(study.ratings),
        sensor=study.sensor,
    )
