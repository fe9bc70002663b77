"""Planning a simulated study: every exposure (:class:`Trial`) in acquisition order, with its seeds.

Randomness: every mount, exposure and each specimen's panel ratings get their own ``SeedSequence`` child keyed by
the master seed and the *names* of pad, specimen, repetition and force, so results do not depend on ``jobs``, on
scheduling, or on which other specimens are in the run.
"""
from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..io.names import check_name
from ..io.protocol import nominal_force_label
from .bench import Exposure, Mount, draw_exposure, draw_mount
from .config import SimulationConfig, force_key
from .optics import Camera
from .pads import Pad
from .specimens import Specimen
from .trial_contact import ridges_in_domain


@dataclass(frozen=True)
class Trial:
    """One exposure, fully specified: a worker renders it without drawing anything but sensor noise."""

    image: str
    pad: Pad
    specimen: Specimen
    nominal_force_n: float
    repetition: int
    mount: Mount
    exposure: Exposure
    noise_key: tuple[int, ...]
    seed: int
    camera: Camera


def _key(text: str) -> int:
    return zlib.crc32(text.encode("utf-8"))


def check_unique_images(trials: Sequence[Trial]) -> None:
    """Planned image names must differ (also in case: a case-insensitive disk would merge them)."""
    seen: dict[str, str] = {}
    for t in trials:
        key = t.image.casefold()
        if key in seen:
            raise ConfigError(f"two trials would write the same image {t.image!r} (and {seen[key]!r}): "
                              "give specimens whose names differ by more than case or punctuation")
        seen[key] = t.image


def rng(seed: int, *key: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=tuple(key)))


def plan_trials(config: SimulationConfig, pads: Sequence[Pad], specimens: Sequence[Specimen]) -> list[Trial]:
    """All exposures in acquisition order: per pad and specimen, mount ``repetition`` times, step the forces up."""
    trials = []
    forces = sorted(config.forces_n)
    for pad in pads:
        for specimen in specimens:
            for rep in range(1, config.repetitions + 1):
                mount_key = (1, _key(pad.name), _key(specimen.name), rep)
                mount = draw_mount(rng(config.seed, *mount_key), config.bench, pad.period_mm if pad.has_ridges else None,
                                   ridges=ridges_in_domain(pad, specimen))
                for force in forces:
                    fkey = force_key(force)
                    exposure = draw_exposure(rng(config.seed, 2, *mount_key[1:], fkey), config.bench, force)
                    name = f"{check_name(pad.name, what='pad')}_{check_name(specimen.name, what='specimen')}_" \
                           f"{nominal_force_label(force)}_r{rep:02d}.png"
                    trials.append(Trial(name, pad, specimen, float(force), rep, mount, exposure,
                                        (3, *mount_key[1:], fkey), config.seed, config.camera))
    return trials


def mount_groups(trials: Sequence[Trial]) -> list[list[Trial]]:
    """The planned trials in runs of one mount (consecutive trials on the same pad, specimen and mount: its forces),
    in plan order: what a worker renders together (:func:`.frames.render_mount`)."""
    groups: list[list[Trial]] = []
    for trial in trials:
        if groups and (trial.pad, trial.specimen, trial.mount) == (groups[-1][0].pad, groups[-1][0].specimen,
                                                                   groups[-1][0].mount):
            groups[-1].append(trial)
        else:
            groups.append([trial])
    return groups
