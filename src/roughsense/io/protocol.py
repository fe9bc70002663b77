"""The acquisition protocol's numbers: forces, repetitions, and the nominal force each image belongs to.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from .._util.checks import Integer, Real, check, short_repr
from ..errors import ConfigError, InputError
from .csv_read import csv_line
from .numbers import BOUNDS
from .problems import Problems, flag

#: Largest force accepted anywhere (manifest readings, protocol forces, --forces-n): stated in :data:`.numbers.BOUNDS`.
#: A fingertip presses with a few newtons (the paper: 1-3 N); 100 N on a 50 x 10 mm specimen is 0.2 MPa.
MAX_FORCE_N = float(BOUNDS["force_n"].high)


#: Largest repetition number: bounds the work a manifest or an option can ask for (the paper uses 10).
MAX_REPETITION = int(BOUNDS["repetition"].high)


def nominal_force_label(force_n: float) -> str:
    """Condition label of a nominal force: 1.0 -> "1N", 2.5 -> "2.5N"."""
    return f"{force_n:g}N"


def check_force(value: object, *, option: str = "force") -> float:
    """One force in newtons: a number (not a boolean), finite, positive and at most :data:`MAX_FORCE_N`."""
    return check(value, Real(0.0, MAX_FORCE_N, low_open=True), name=option,
                 must=f"a positive number of newtons up to {MAX_FORCE_N:g}")


def parse_forces(value: object, *, path: Path | None = None) -> tuple[float, ...]:
    """``[protocol] forces_n``: a non-empty list of distinct forces (see :func:`check_force`)."""
    if not isinstance(value, (list, tuple)) or not value:
        raise InputError(f"[protocol] forces_n must be a non-empty list of numbers, got {short_repr(value)}", path=path)
    try:
        forces = tuple(check_force(f, option="[protocol] forces_n: each force") for f in value)
    except ConfigError as exc:
        raise InputError(exc.message, path=path) from None
    if len(set(forces)) != len(forces):
        raise InputError(f"[protocol] forces_n lists a force twice: {short_repr(value)}", path=path)
    return forces


def check_repetitions(value: object, *, option: str = "--repetitions") -> int:
    """A count of repetitions: a whole number from 1 to :data:`MAX_REPETITION`."""
    return check(value, Integer(1, MAX_REPETITION), name=option)


def assign_nominal_forces(manifest: pd.DataFrame, forces_n: Sequence[float], path: Path | None = None, *,
                          problems: Problems | None = None) -> pd.DataFrame:
    """Give each image its nominal force (the condition), from the column or the nearest protocol force.

    The scale reading (``force_n``) scatters around the nominal force; a reading nearer to no protocol
    force than half the spacing is refused rather than silently binned. A missing force (a cell already
    reported when collecting problems) is passed over.
    """
    manifest = manifest.copy()
    forces = np.asarray(sorted(forces_n), dtype=float)
    listed = ", ".join(f"{f:g}" for f in forces)
    if "nominal_force_n" in manifest.columns:
        nominal = manifest["nominal_force_n"].to_numpy(float)
        flag(problems, ~np.isin(nominal, forces) & ~np.isnan(nominal), lambda i: InputError(
            f"nominal force {nominal[i]:g} N is not one of the protocol forces {listed}",
            path=path, row=csv_line(i), column="nominal_force_n"))
    else:
        measured = manifest["force_n"].to_numpy(float)
        nearest = np.abs(measured[:, None] - forces[None, :]).argmin(axis=1)
        nominal = forces[nearest]
        spacing = np.min(np.diff(forces)) if forces.size > 1 else forces[0]
        flag(problems, np.abs(measured - nominal) > 0.5 * spacing, lambda i: InputError(
            f"force {measured[i]:g} N is far from every protocol force ({listed})",
            path=path, row=csv_line(i), column="force_n"))
    manifest["nominal_force_n"] = nominal
    manifest["condition"] = [nominal_force_label(f) for f in nominal]
    return manifest
