"""Grouping images into trials: a combined-force model reads a trial as its 1 N, 2 N and 3 N spectra side by side,
so images reach a model only in groups whose force slot is known (a study's manifest, one flag per force), and a
file name or manifest row that says another force than its slot is refused."""
from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InputError

if TYPE_CHECKING:
    import pandas as pd

    from .modelfile import FittedModel

_FORCE_TOKEN = re.compile(r"(?:^|[_\-. ])(\d+(?:\.\d+)?)[nN](?=$|[_\-. ])")


def condition_force_n(condition: str) -> float:
    """The nominal force of a condition label ("2.5N" -> 2.5)."""
    return float(condition[:-1]) if condition.upper().endswith("N") else float("nan")


def forces_in_name(image) -> set[float]:
    """Forces a file name states as tokens like ``_1N_`` or ``-2.5n.`` (empty if it states none)."""
    stem = Path(str(image)).stem
    return {float(m) for m in _FORCE_TOKEN.findall(stem)}


def check_slot(image, condition: str, *, path=None, row: int | None = None) -> None:
    """Refuse an image whose name states forces, none of them the force of the slot it fills."""
    stated = forces_in_name(image)
    if stated and condition_force_n(condition) not in stated:
        said = ", ".join(f"{f:g}N" for f in sorted(stated))
        raise InputError(f"image {Path(str(image)).name!r} fills the {condition} slot but its name says {said}",
                         path=path, row=row, column="image" if row is not None else None)


def model_pad(loaded: FittedModel) -> str:
    return str(loaded.training.get("pad", "")) if isinstance(loaded.training, dict) else ""


def model_condition(loaded: FittedModel) -> str:
    """The model's condition: its single force, or "combined"."""
    training = loaded.training if isinstance(loaded.training, dict) else {}
    return str(training.get("condition") or (loaded.conditions[0] if len(loaded.conditions) == 1 else "combined"))


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
