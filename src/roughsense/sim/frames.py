"""Rendering a planned trial: the line's brightness from its contact, then the camera's 8-bit frame.

Deterministic given the trial: every draw but the sensor noise was made when the trial was planned (:mod:`.plan`),
and the noise is seeded by the trial's own key, so a frame does not depend on which worker renders it.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from . import contact
from .bench import Mount
from .optics import Camera, bin_to_pixels, render
from .pads import Pad
from .plan import Trial, rng
from .specimens import SPECIMEN_LENGTH_MM, Specimen
from .trial_contact import solve_levels

SUBSAMPLES_PER_PX = 7
NO_CONTACT_GAP_MM = 1e3  # beyond the specimen's ends nothing touches the pad
PRESSURE_LEVELS = 5  # local pressures solved per trial at most; the line blends them (see trial_line)


def trial_line(trial: Trial, *, warm: dict | None = None) -> tuple[np.ndarray, float]:
    """Brightness of each pixel column of the line (0..1) and the fraction of the line in contact.

    ``warm``: a dict the caller keeps across the trials of one run; a trial's contact levels then start from the
    last solution of the same surfaces in an earlier trial (same answer within the solver's tolerance, in fewer
    steps). The result then depends, at that tolerance, on
    which trials came before, so the study path leaves it off (its images must not depend on ``jobs``); a sweep
    cell, which runs its trials in one fixed order, uses it.

    A tilted or warped specimen presses harder in some places. The pressure varies slowly compared with the
    grating period, so the line is treated as locally periodic: the contact is solved at a few pressures spanning
    the local range (together, :func:`.contact.solve_periodic_many`), and each point blends the two nearest
    solutions by its local pressure (hat weights).
    """
    levels = _pressure_levels(trial)
    length, solutions = solve_levels(trial.pad, trial.specimen, trial.mount, _mean_pressure(trial) * levels, warm=warm)
    return _line(trial, levels, length, solutions)


def mount_lines(trials: list[Trial]) -> list[tuple[np.ndarray, float]]:
    """:func:`trial_line` of each trial of one mount (same pad, specimen and mount: its forces), bit-identical.

    The trials press the same surfaces, so every level of every trial is one row of a single batched solve: each
    row takes exactly the steps it takes alone (:func:`.contact.solve_periodic_many`) and the rows share the calls,
    which costs about 40 % less than a solve per trial (BENCHMARKS.md, issue 37).
    """
    first = trials[0]
    if any((t.pad, t.specimen, t.mount) != (first.pad, first.specimen, first.mount) for t in trials):
        raise ValueError("mount_lines needs trials of one mount (the same pad, specimen and mount)")
    levels = [_pressure_levels(t) for t in trials]
    pressures = np.concatenate([_mean_pressure(t) * lv for t, lv in zip(trials, levels)])
    length, solutions = solve_levels(first.pad, first.specimen, first.mount, pressures)
    bounds = np.cumsum([0] + [lv.size for lv in levels])
    return [_line(t, lv, length, solutions[a:b]) for t, lv, a, b in zip(trials, levels, bounds[:-1], bounds[1:])]


def _mean_pressure(trial: Trial) -> float:
    return contact.nominal_pressure_pa(trial.exposure.force_true_n)


def _pressure_levels(trial: Trial) -> np.ndarray:
    """The local pressures (relative to the mean) a trial's contact is solved at: few, spanning the mount's range."""
    _, _, on, local = _mount_geometry(trial.camera, trial.mount)
    lo, hi = float(local[on].min()) if on.any() else 1.0, float(local[on].max()) if on.any() else 1.0
    count = 1 if hi - lo < 0.02 else int(min(PRESSURE_LEVELS, 2 + math.ceil((hi - lo) / 0.2)))
    return np.linspace(lo, hi, count) if count > 1 else np.array([1.0])


def _line(trial: Trial, levels: np.ndarray, length: float, solutions: list) -> tuple[np.ndarray, float]:
    """The line from a trial's contact solutions at ``levels``: each point blends the two nearest by its pressure."""
    cam, pad, spec, mount = trial.camera, trial.pad, trial.specimen, trial.mount
    x_mm, u, on, local = _mount_geometry(cam, mount)
    count = levels.size
    brightness = np.zeros_like(x_mm)
    touching = np.zeros_like(x_mm)
    for level, solution in zip(levels, solutions):
        if count == 1:
            weight = np.ones_like(x_mm)
        else:  # piecewise-linear (hat) weights in local pressure
            weight = np.clip(1.0 - np.abs(local - level) / (levels[1] - levels[0]), 0.0, 1.0)
        gap = solution.gap_mm
        grid = np.arange(gap.size + 1) * (length / gap.size)
        g = np.interp(np.mod(u, length), grid, np.append(gap, gap[0]))
        g = np.where(on, g, NO_CONTACT_GAP_MM)
        brightness += weight * cam.contrast(g)
        touching += weight * (g <= 0)
    if pad.has_ridges and trial.exposure.ridge_visibility > 0:
        # Where the pad is not in optical contact, its ridged surface is still seen through the pad: each ridge is a
        # small cylindrical lens that bends light into the camera, a flat groove bottom is not (a 1 mm^-1 pattern
        # along the whole pad, which is longer than the field). Optical contact wipes it out (index-matched there).
        # Its fundamental sits at the band's upper edge, so its exposure-to-exposure strength rescales the whole
        # area-normalised spectrum (docs/simulator.md, noise calibration).
        crests = _ridge_crests(cam, mount, pad, spec)  # 1 on the crests, 0 in the grooves
        brightness += trial.exposure.ridge_visibility * crests * np.clip(1.0 - brightness, 0.0, 1.0)
    return bin_to_pixels(brightness, cam.width_px), float(touching.mean())


@functools.lru_cache(maxsize=8)
def _mount_geometry(cam: Camera, mount: Mount) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sub-pixel positions on the frame (mm) and on the specimen, where the specimen is, and the local pressure
    relative to the mean: all fixed by the mount, so a mount's forces (consecutive trials) compute them once."""
    w_px = cam.width_px
    px_per_mm = cam.px_per_mm * mount.magnification
    x_mm = (np.arange(w_px * SUBSAMPLES_PER_PX) + 0.5) / (px_per_mm * SUBSAMPLES_PER_PX)
    start = (w_px / px_per_mm - SPECIMEN_LENGTH_MM) / 2.0 + mount.shift_mm
    u = x_mm - start  # position along the specimen
    on = (u >= 0) & (u <= SPECIMEN_LENGTH_MM)
    u_spec = np.linspace(0.0, SPECIMEN_LENGTH_MM, 501)
    mean = float(mount.local_pressure(u_spec, SPECIMEN_LENGTH_MM).mean())
    local = mount.local_pressure(np.clip(u, 0.0, SPECIMEN_LENGTH_MM), SPECIMEN_LENGTH_MM) / mean
    return _read_only(x_mm, u, on, local)


@functools.lru_cache(maxsize=8)
def _ridge_crests(cam: Camera, mount: Mount, pad: Pad, specimen: Specimen) -> np.ndarray:
    """Where the pad's ridges are along the line, 1 on the crests and 0 in the grooves (per mount, like the above)."""
    _, u, _, _ = _mount_geometry(cam, mount)
    _, pad_period = contact.periodic_domain(specimen.period_mm, pad.period_mm, max_length_mm=SPECIMEN_LENGTH_MM)
    return _read_only(1.0 + pad.height_mm(u - mount.pad_phase_mm, period_mm=pad_period) / pad.ridge_height_mm)[0]


def _read_only(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """Cached arrays are shared by the trials of a mount: no caller may change them."""
    for array in arrays:
        array.flags.writeable = False
    return arrays


def render_trial(trial: Trial, *, rows: tuple[int, int] | None = None,
                 warm: dict | None = None) -> tuple[np.ndarray, float]:
    """The 8-bit frame of one trial and its ground-truth contact fraction.

    ``rows=(start, stop)`` renders only those rows, bit-identical to the same rows of the whole frame (for a
    reader that needs only the sensor's line); ``warm`` is passed to :func:`trial_line`.
    """
    line, fraction = trial_line(trial, warm=warm)
    return _frame(trial, line, rows), fraction


def render_mount(trials: list[Trial]) -> list[tuple[np.ndarray, float]]:
    """:func:`render_trial` of each trial of one mount, their contacts solved together (:func:`mount_lines`)."""
    return [(_frame(trial, line, None), fraction) for trial, (line, fraction) in zip(trials, mount_lines(trials))]


def _frame(trial: Trial, line: np.ndarray, rows: tuple[int, int] | None) -> np.ndarray:
    center = trial.camera.height_px / 2.0 + trial.mount.band_shift_px
    return render(trial.camera, line, band_center_px=center, lighting=trial.exposure.lighting,
                  rng=rng(trial.seed, *trial.noise_key), spots=trial.mount.spots, rows=rows)
