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
    (semicolons, decimal commas) is read with a warning. Then the scale check every run makes: the stated px_per_mm
    against the pads' ridges and the gratings of stated period in a few presses of each; a scale they measure
    otherwise is a problem. Nothing is written.
    """
    from ..errors import InputError
    from ..io.study_check import check_study
    from ._studies import study_folder

    result = check_study(study_folder(folder, seed))
    _check_scale(result)
    if result.ok:
        _check_measured_scale(result)
    if not result.ok:
        for line in result.problems.lines():
            typer.echo(line)
        raise InputError(result.failure(), path=folder)
    typer.echo(result.summary())


def _check_scale(result) -> None:
    """An implausible scale is a problem: one the sensor's band cannot be measured at (``sensor.scale_misfit``)."""
    from ..errors import InputError
    from ..io.study import STUDY_TOML
    from ..sensor.line import scale_misfit

    sensor = result.sensor
    problem = None if sensor is None else scale_misfit(sensor.px_per_mm, sensor.roi)
    if problem is not None:
        result.problems.add(InputError(f"[sensor] {problem}", path=result.root / STUDY_TOML))


def _check_measured_scale(result) -> None:
    """The scale check `study` and `fit` make (``model/scale_check.py``): a stated px_per_mm the images measure
    otherwise is a problem; one that could not be confirmed is said on stderr (the check passes)."""
    import warnings

    from ..errors import InputError, RoughsenseError, RoughsenseWarning
    from ..io.study import STUDY_TOML, read_study
    from ..model.scale_check import UNCONFIRMED, check_study_scale

    try:
        with warnings.catch_warnings():  # the folder's own warnings were said by check_study, once
            warnings.simplefilter("ignore", RoughsenseWarning)
            study = read_study(result.root)
        check = check_study_scale(study)
    except RoughsenseError as exc:  # check looks for every image, decodes none: one the scale check reads may not
        typer.echo(f"roughsense: {UNCONFIRMED}: {exc}", err=True)
        return
    if check.off:
        result.problems.add(InputError(f"[sensor] {check.summary()}; measure it with `roughsense calibrate "
                                       f"{result.root}`", path=result.root / STUDY_TOML))
    else:
        typer.echo(f"roughsense: {check.summary()}", err=True)


def register(app: typer.Typer) -> None:
    app.command("check")(check)
