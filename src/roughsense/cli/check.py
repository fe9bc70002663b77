"""``roughsense check DIR``: list every problem of a study folder (file, row, column, what to do), write nothing."""
from __future__ import annotations

from typing import Annotated

import typer

from .. import defaults
from ._studies import BuiltinSeed

ORDER = 4

Folder = Annotated[str, typer.Argument(
    metavar="DIR|builtin", show_default=False,
    help="The study folder to check (builtin: the built-in simulated study of --seed).")]


def check(folder: Folder, seed: BuiltinSeed = defaults.SEED) -> None:
    """Check a study folder and list every problem at once, one per line, exit 2 if there is any.

    The same checks `study`, `fit` and `features` make, which stop at the first problem: study.toml, specimens.csv,
    manifest.csv (every image file is looked for, not decoded) and ratings.csv. A European Excel file
    (semicolons, decimal commas) is read with a warning. Nothing is written.
    """
    from ..errors import InputError
    from ..io.study_check import check_study
    from ._studies import study_folder

    result = check_study(study_folder(folder, seed))
    _check_scale(result)
    if not result.ok:
        for line in result.problems.lines():
            typer.echo(line)
        raise InputError(result.failure(), path=folder)
    typer.echo(result.summary())


def _check_scale(result) -> None:
    """An implausible scale is a problem: one the sensor's band cannot be measured at (``sensor.scale_misfit``)."""
    from ..errors import InputError
    from ..io.study import STUDY_TOML
    from ..sensor.spectrum import scale_misfit

    sensor = result.sensor
    problem = None if sensor is None else scale_misfit(sensor.px_per_mm, sensor.roi)
    if problem is not None:
        result.problems.add(InputError(f"[sensor] {problem}", path=result.root / STUDY_TOML))


def register(app: typer.Typer) -> None:
    app.command("check")(check)
