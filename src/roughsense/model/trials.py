"""Grouping what predict is given into trials (:func:`gather_trials`): a combined-force model reads a trial as its
1 N, 2 N and 3 N spectra side by side, so images reach a model only in groups whose force slot is known (a study's
manifest, one flag per force), and a file name or manifest row that says another force than its slot is refused.
A study's trials are its specimens' surfaces, read at its own scale, and its gratings' stated periods check it."""
from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ConfigError, InputError

if TYPE_CHECKING:
    import pandas as pd

    from .modelfile import FittedModel
    from .reading import SensorOverride


_FORCE_TOKEN = re.compile(r"(?:^|[_\-. ])(\d+(?:\.\d+)?)[nN](?=$|[_\-. ])")


@dataclass(frozen=True)
class Trials:
    """What predict was given, as its model reads it: each trial's images in the model's condition order, the
    model's pad and condition, a study's specimen and repetition per trial (None: no study), each trial's surface
    (None: each press read alone), the override the images are read with, the periods a study states for the scale
    check (``(what, per-trial period in mm)``) and the note saying which scale a study was read at ('' if none)."""

    groups: list[tuple]
    pad: str
    condition: str
    meta: pd.DataFrame | None = None
    surfaces: object = None
    override: SensorOverride | None = None
    reference: tuple | None = None
    note: str = ""

    @property
    def images(self) -> list:
        """Every image, trial after trial (k per trial for a k-force model)."""
        return [image for trial in self.groups for image in trial]


def gather_trials(loaded: FittedModel, images: Sequence | None = None, *, study=None, specimens: Sequence[str] = (),
                  images_by_force: Mapping[str, Sequence] | None = None, same_surface: bool = False,
                  override: SensorOverride | None = None) -> Trials:
    """The trials of exactly one of ``images`` (a single-force model's), ``images_by_force`` or ``study`` (a study
    folder or read study: its manifest's trials of the model's pad, ``specimens`` only if given)."""
    reference, note, meta = None, "", None
    if study is not None:
        from ..io.study import read_study

        read = read_study(study) if isinstance(study, (str, os.PathLike)) else study
        groups, meta = groups_from_study(loaded, read, list(specimens or ()))
        override, reference, note = study_scale(loaded, read, override, meta)
    else:
        if same_surface:
            refuse_repeats([*(images or ()), *(p for paths in (images_by_force or {}).values() for p in paths)])
        groups = (groups_from_flags(loaded, images_by_force) if images_by_force
                  else groups_from_images(loaded, list(images or ())))
    surfaces = meta["specimen"].astype(str).to_numpy() if meta is not None and "specimen" in meta else (
        ["surface"] * len(groups) if same_surface else None)
    return Trials(groups, model_pad(loaded), model_condition(loaded), meta, surfaces, override, reference, note)


def groups_from_images(loaded: FittedModel, images: Sequence) -> list[tuple]:
    """Bare images: one trial each for a single-force model; refused for a combined one (no slots known)."""
    if len(loaded.conditions) > 1:
        flags = " ".join(f"--images-{c.lower()} ..." for c in loaded.conditions)
        raise InputError(f"this model combines {', '.join(loaded.conditions)}: bare images cannot say which force each "
                         f"is; group them with --study DIR (from its manifest) or with {flags} (the i-th of each "
                         "flag form a trial)", path=loaded.path)
    for image in images:
        check_slot(image, loaded.conditions[0])
    return [(image,) for image in images]


def groups_from_flags(loaded: FittedModel, by_condition: Mapping[str, Sequence]) -> list[tuple]:
    """``{"1N": [...], "2N": [...], ...}``: the i-th image of each condition forms trial i."""
    wanted = loaded.conditions
    unknown = [c for c in by_condition if c not in wanted]
    if unknown:
        raise InputError(f"--images-{unknown[0].lower()}: this model uses {', '.join(wanted)}, not {unknown[0]}",
                         path=loaded.path)
    missing = [c for c in wanted if not by_condition.get(c)]
    if missing:
        raise InputError(f"this model needs images at {', '.join(wanted)}: --images-{missing[0].lower()} is missing",
                         path=loaded.path)
    counts = {c: len(by_condition[c]) for c in wanted}
    if len(set(counts.values())) > 1:
        shown = ", ".join(f"{n} at {c}" for c, n in counts.items())
        raise InputError(f"every force needs as many images (the i-th of each form a trial); got {shown}")
    groups = list(zip(*(by_condition[c] for c in wanted)))
    for number, group in enumerate(groups, start=1):
        resolved = [os.path.realpath(str(image)) for image in group]
        if len(set(resolved)) < len(resolved):
            raise InputError(f"trial {number}: the same image fills two force slots ({Path(str(group[0])).name})")
        for image, condition in zip(group, wanted):
            check_slot(image, condition)
    return groups


def groups_from_study(loaded: FittedModel, study, specimens: Sequence[str] = ()) -> tuple[list[tuple], pd.DataFrame]:
    """Trials of the model's pad from a study's manifest: each (specimen, repetition) with one image per force.

    Returns the groups (paths, in the model's condition order) and their specimen and repetition.
    """
    import pandas as pd

    from ..io.csv_read import csv_line
    from ..io.study import MANIFEST_CSV

    manifest_path = study.root / MANIFEST_CSV
    manifest = study.manifest.reset_index(drop=True)
    pad = model_pad(loaded)
    if pad and pad not in set(manifest["pad"]):
        raise InputError(f"no images of the model's pad {pad!r} (pads in the study: {', '.join(study.pads)})",
                         path=manifest_path)
    rows = manifest[manifest["pad"] == pad] if pad else manifest
    if specimens:
        unknown = [s for s in specimens if s not in set(rows["specimen"])]
        if unknown:
            raise InputError(f"no images of specimen {unknown[0]!r} on pad {pad!r}", path=manifest_path)
        rows = rows[rows["specimen"].isin(specimens)]
    conditions = loaded.conditions
    rows = rows[rows["condition"].isin(conditions)]
    if rows.empty:
        raise InputError(f"no images of pad {pad!r} at {', '.join(conditions)}", path=manifest_path)
    for i, row in rows.iterrows():
        check_slot(row["image"], row["condition"], path=manifest_path, row=csv_line(i))
    groups, meta = [], []
    for (specimen, repetition), trial in rows.groupby(["specimen", "repetition"], sort=True):
        slots = []
        for condition in conditions:
            at = trial[trial["condition"] == condition]
            if len(at) != 1:
                what = "no image" if at.empty else f"{len(at)} images"
                where = f" (rows {', '.join(str(csv_line(i)) for i in at.index)})" if len(at) > 1 else ""
                raise InputError(f"specimen {specimen!r}, repetition {repetition} on pad {pad!r} has {what} at "
                                 f"{condition}{where}; a trial needs exactly one image per force of the model",
                                 path=manifest_path)
            slots.append(study.root / at["image"].iloc[0])
        groups.append(tuple(slots))
        meta.append({"specimen": specimen, "repetition": int(repetition)})
    return groups, pd.DataFrame(meta)


def study_scale(loaded: FittedModel, study, override: SensorOverride | None, meta: pd.DataFrame):
    """A study's images are read at its own study.toml scale unless ``override`` states one; the trials of
    specimens of stated period are marked for the scale check. Returns (override, reference, the note saying
    which scale was used, or '')."""
    from .reading import SensorOverride

    model_px = float(loaded.model_file_.features["spectrum"]["px_per_mm"])
    note = ""
    if override is None or override.px_per_mm is None:
        stated = float(study.sensor.px_per_mm)
        note = (f"images read at {stated:g} px/mm, the scale in {study.root / 'study.toml'} (the model was fitted at "
                f"{model_px:g} px/mm)")
        override = SensorOverride(None if override is None else override.roi, stated)
    reference = None
    if "specimen" in meta:
        from .scale_check import stated_periods

        periods = stated_periods(study)
        reference = ("the specimens' periods in specimens.csv",
                     np.array([periods.get(s, np.nan) for s in meta["specimen"].astype(str)]))
    return override, reference, note


def refuse_repeats(images) -> None:
    """Grouped presses are averaged: one file given twice (by any path) would count as two presses and narrow the
    surface's interval."""
    seen: dict[tuple[int, int], str] = {}
    for image in images:
        try:
            info = os.stat(image)
        except (OSError, TypeError, ValueError):
            continue  # reading it names the problem (an array has no file)
        key = (info.st_dev, info.st_ino)
        if key in seen:
            raise ConfigError(f"--same-surface: {image} is the same file as {seen[key]}; give each press once")
        seen[key] = str(image)


def check_slot(image, condition: str, *, path=None, row: int | None = None) -> None:
    """Refuse an image whose name states forces, none of them the force of the slot it fills."""
    stated = forces_in_name(image)
    if stated and condition_force_n(condition) not in stated:
        said = ", ".join(f"{f:g}N" for f in sorted(stated))
        raise InputError(f"image {Path(str(image)).name!r} fills the {condition} slot but its name says {said}",
                         path=path, row=row, column="image" if row is not None else None)


def forces_in_name(image) -> set[float]:
    """Forces a file name states as tokens like ``_1N_`` or ``-2.5n.`` (empty if it states none)."""
    stem = Path(str(image)).stem
    return {float(m) for m in _FORCE_TOKEN.findall(stem)}


def condition_force_n(condition: str) -> float:
    """The nominal force of a condition label ("2.5N" -> 2.5)."""
    return float(condition[:-1]) if condition.upper().endswith("N") else float("nan")


def model_pad(loaded: FittedModel) -> str:
    return str(loaded.training.get("pad", "")) if isinstance(loaded.training, dict) else ""


def model_condition(loaded: FittedModel) -> str:
    """The model's condition: its single force, or "combined"."""
    training = loaded.training if isinstance(loaded.training, dict) else {}
    return str(training.get("condition") or (loaded.conditions[0] if len(loaded.conditions) == 1 else "combined"))
