"""``roughsense calibrate``: the camera's px/mm measured from a study's presses of a target of known period, and
written into its study.toml (the first step on a new rig)."""
from __future__ import annotations

from typing import Annotated

import typer

from .. import defaults
from ..errors import ConfigError
from ._common import number_option
from ._studies import BuiltinSeed

ORDER = 5
#: The fewest mounts of a target whose measurement is written: a standard error needs two (the scale check that
#: every run makes wants three, model.scale_check.MIN_MOUNTS).
MIN_MOUNTS = 2

Folder = Annotated[str, typer.Argument(metavar="DIR|builtin", help="The study folder: its manifest lists the presses, "
                                       "its study.toml receives px_per_mm (builtin: measured and printed only).")]
Specimen = Annotated[str | None, typer.Option(
    "--specimen", show_default=False,
    help="The target: this specimen's presses, its period the wavelength_mm of specimens.csv. Default: the "
         "reference specimen (R3, 3 mm, pressed in every study).")]
Ridges = Annotated[bool, typer.Option(
    "--ridges", help="The target: the ridges of every pad with [pads.NAME] ridge_period_mm (every press of it).")]
Limit = Annotated[int, typer.Option("--limit", parser=number_option("--limit", whole=True, low=1),
                                    help="At most this many presses, evenly spread over the manifest.")]
ScaleRange = Annotated[str | None, typer.Option(
    "--range", show_default=False,
    help="LOW,HIGH: the px/mm searched (a new rig's scale is not known yet). Default: every scale at which the "
         "target shows at least 3 px per period and 5 periods on the line.")]
DryRun = Annotated[bool, typer.Option("--dry-run", help="Measure and print; write nothing.")]
Force = Annotated[bool, typer.Option("--force", help="Replace a px_per_mm study.toml already states.")]


def calibrate(folder: Folder, specimen: Specimen = None, ridges: Ridges = False, limit: Limit = 30,
              scale_range: ScaleRange = None, dry_run: DryRun = False, force: Force = False,
              seed: BuiltinSeed = defaults.SEED) -> None:
    """Measure the camera's scale (px/mm) from presses of a target of known period and write it into study.toml.

    Each press's line is read where the study's [sensor] roi says; the target's period in pixels is found first
    over --range (on a pad with ridges, where the target and the ridges both sit), then refined below the DFT's
    bin. The median over the presses is written as [sensor] px_per_mm, with its precision as the value's comment.
    """
    from ..io.sensor_settings import write_px_per_mm
    from ..io.study import STUDY_TOML, read_study
    from ._common import parse_float_list
    from ._studies import builtin_writable, study_folder

    low_high = None if scale_range is None else tuple(parse_float_list(scale_range, name="range"))
    if low_high is not None and (len(low_high) != 2 or not 0 < low_high[0] < low_high[1]):
        raise ConfigError(f"--range must be LOW,HIGH px/mm with 0 < LOW < HIGH, got {scale_range!r}")
    if ridges and specimen is not None:
        raise ConfigError("give one target: --specimen NAME or --ridges, not both")
    study = read_study(study_folder(folder, seed))
    dry_run = dry_run or not builtin_writable(folder)
    targets = _targets(study, specimen, ridges, limit)
    m, what = _measure(study, targets, low_high)
    if m.n_measured == 0:
        searched = "the scales searched" if scale_range is None else f"--range {scale_range}"
        raise ConfigError(f"no press of {what} shows a peak of its period within {searched}")
    typer.echo(f"{m.px_per_mm:.4f} px/mm measured from {m.n_measured} of {m.px_per_mm_each.size} presses of {what}: "
               f"{_precision(m)}, range {m.measured.min():.4g}-{m.measured.max():.4g}")
    if dry_run:
        return
    if m.n_mounts < MIN_MOUNTS:
        raise ConfigError(f"{m.n_mounts} mount(s) of the target cannot say how precise the scale is: nothing written; "
                          f"press it in at least {MIN_MOUNTS} mounts (or look with --dry-run)")
    toml_path = study.root / STUDY_TOML
    note = (f"roughsense calibrate: {m.n_measured} presses of {what}, +-{100 * m.standard_error:.2g} % (standard "
            "error)")
    previous = write_px_per_mm(toml_path, m.px_per_mm, note=note, force=force)
    was = "" if previous is None else f" (was {previous:g})"
    typer.echo(f"wrote [sensor] px_per_mm = {round(m.px_per_mm, 4):g}{was} to {toml_path}")


def _precision(m) -> str:
    """How precisely the scale is known, in words: over mounts (their magnification differs), never a NaN."""
    if m.n_mounts < 2:
        return f"precision unknown from {m.n_mounts} mount (at least {MIN_MOUNTS} are needed)"
    spread = 100 * m.measured.std(ddof=1) / m.px_per_mm
    return (f"+-{100 * m.standard_error:.2g} % (standard error over {m.n_mounts} mounts), {spread:.2g} % SD from "
            "press to press")


def _targets(study, specimen: str | None, ridges: bool, limit: int) -> list[tuple]:
    """(what, period in mm, image paths, the pad's ridge period or None, each image's mount) per pad."""
    import numpy as np

    manifest = study.manifest
    if ridges:
        if not study.pad_ridge_period_mm:
            raise ConfigError("--ridges: no pad in study.toml states [pads.NAME] ridge_period_mm")
        groups = [(f"the {pad} pad's {period:g} mm ridges", period, manifest[manifest["pad"] == pad], None)
                  for pad, period in study.pad_ridge_period_mm.items()]
    else:
        name = specimen or study.reference_specimen
        specimens = study.specimens.set_index("specimen")
        if name not in specimens.index:
            raise ConfigError(f"--specimen {name!r} is not in specimens.csv" if specimen else
                              f"the reference specimen {name!r} (calibrate's default target) is not in specimens.csv; "
                              "pass --specimen NAME (a specimen of known period) or --ridges")
        period = float(specimens.loc[name, "wavelength_mm"])
        rows = manifest[manifest["specimen"] == name]
        groups = [(f"{name} ({period:g} mm) on the {pad} pad", period, rows[rows["pad"] == pad],
                   study.pad_ridge_period_mm.get(pad)) for pad in dict.fromkeys(rows["pad"])]
    total = sum(len(g[2]) for g in groups)
    if total == 0:
        raise ConfigError("the manifest lists no press of the target")
    out = []
    for what, period, rows, ridge in groups:
        keep = max(1, round(limit * len(rows) / total))
        chosen = rows.iloc[np.unique(np.linspace(0, len(rows) - 1, min(keep, len(rows))).round().astype(int))]
        mounts = [f"{s}/{p}/{r}" for s, p, r in zip(chosen["specimen"], chosen["pad"], chosen["repetition"])]
        out.append((what, period, [study.root / image for image in chosen["image"]], ridge, mounts))
    return out


def _measure(study, targets, scale_range):
    """The pooled measurement over every target's presses, and what was measured, in words."""
    import numpy as np

    from ..sensor.period import ScaleMeasurement, calibrate_scale
    from ..sensor.spectrum import SpatialSpectrum

    reader = SpatialSpectrum(roi=study.sensor.roi, max_pixels=study.sensor.max_pixels)
    values, mounts = [], []
    for _, period, images, ridge, mount in targets:
        lines = [reader.line(image)[0] for image in images]
        values.append(calibrate_scale(lines, period, px_per_mm_range=scale_range, ridge_period_mm=ridge)
                      .px_per_mm_each)
        mounts.extend(mount)
    what = " and ".join(t[0] for t in targets)
    return ScaleMeasurement(targets[0][1], np.concatenate(values), np.asarray(mounts, dtype=object)), what


def register(app: typer.Typer) -> None:
    app.command("calibrate")(calibrate)
