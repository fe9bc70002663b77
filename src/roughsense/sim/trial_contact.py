"""The contact of one trial: the pad's and specimen's relief on the periodic domain, solved at its pressure levels.

The solver itself is :mod:`.contact` (FFT-BEM); this module chooses what it solves for a planned trial and carries
warm starts between trials.
"""
from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from . import contact
from .bench import Mount
from .pads import Pad
from .specimens import SPECIMEN_LENGTH_MM, Specimen

WARM_MAX_ITER = 500  # a warm-started solve needs tens of steps; past this it is cycling and restarts cold
SOLVER_TOL = 1e-5  # relative pressure change at convergence: lines within 1e-4 of 1e-6's (< 0.01 DN), BENCHMARKS.md


def ridges_in_domain(pad: Pad, specimen: Specimen) -> int:
    """Fingerprint ridges in the periodic contact domain: each needs its own height error per mount."""
    if not pad.has_ridges:
        return 0
    length, pad_period = contact.periodic_domain(specimen.period_mm, pad.period_mm, max_length_mm=SPECIMEN_LENGTH_MM)
    return max(1, round(length / pad_period))


def contact_surface(pad: Pad, specimen: Specimen, mount: Mount) -> tuple[float, np.ndarray, tuple]:
    """The periodic domain's length, the combined relief on its grid, and a key naming the surfaces in contact."""
    length, pad_period = contact.periodic_domain(specimen.period_mm, pad.period_mm if pad.has_ridges else None,
                                                 max_length_mm=SPECIMEN_LENGTH_MM)
    n = contact.grid_points(length)
    x = np.arange(n) * (length / n)
    height = specimen.height_mm(x)
    if pad.has_ridges:
        ridges = ridges_in_domain(pad, specimen)
        if len(mount.ridge_offsets_mm) < ridges:  # plan_trials draws one per ridge: never silently drop them
            raise RuntimeError(f"mount has {len(mount.ridge_offsets_mm)} ridge height errors for {ridges} ridges")
        offsets = np.asarray(mount.ridge_offsets_mm[:ridges])
        height = height + pad.height_mm(x - mount.pad_phase_mm, period_mm=pad_period, ridge_offsets_mm=offsets)
    # The pad's relief depends on the mount only for a ridged pad.
    key = (repr(pad), repr(specimen), mount.pad_phase_mm, mount.ridge_offsets_mm) if pad.has_ridges else \
        (repr(pad), repr(specimen))
    return length, height, key


def solve_levels(pad: Pad, specimen: Specimen, mount: Mount, pressures_pa: np.ndarray,
                  warm: dict | None = None) -> tuple[float, list[contact.ContactSolution]]:
    """The contact at each of a trial's pressure levels, solved together (one batched solve).

    ``warm`` (see :func:`.frames.trial_line`) holds the last solution of each set of surfaces across trials and starts
    every level from it. A warm start that has not converged after ``WARM_MAX_ITER`` steps (it can cycle when far
    from the answer) is dropped and the levels start afresh from uniform pressure.
    """
    length, height, key = contact_surface(pad, specimen, mount)
    initial = warm.get(key) if warm is not None else None
    try:
        solutions = None
        if initial is not None:
            try:
                solutions = contact.solve_periodic_many(height, length, pressures_pa, pad.contact_modulus_pa,
                                                        tol=SOLVER_TOL, initial_pressure_pa=initial,
                                                        max_iter=WARM_MAX_ITER)
            except contact.ContactNotConverged:
                solutions = None
        if solutions is None:
            solutions = contact.solve_periodic_many(height, length, pressures_pa, pad.contact_modulus_pa, tol=SOLVER_TOL)
    except contact.ContactNotConverged as exc:
        raise ConfigError(f"pad {pad.name!r} on specimen {specimen.name!r} at {float(np.max(pressures_pa)):.0f} Pa: "
                          f"{exc.message}; try a smoother specimen or a different pad") from None
    if warm is not None:
        warm[key] = solutions[-1].pressure_pa
    return length, solutions
