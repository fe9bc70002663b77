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
    from .._util.lock import output_lock
    from ..io.study import read_study
    from ._common import parse_float_list
    from ._studies import builtin_writable, study_folder

    low_high = None if scale_range is None else tuple(parse_float_list(scale_range, name="range"))
    if low_high is not None and (len(low_high) != 2 or not 0 < low_high[0] < low_high[1]):
        raise ConfigError(f"--range must be LOW,HIGH px/mm with 0 < LOW < HIGH, got {scale_range!r}")
    if ridges and specimen is not None:
        raise ConfigError("give one target: --specimen NAME or --ridges, not both")
    root = study_folder(folder, seed)
    dry_run = dry_run or not builtin_writable(folder)
    # The folder's lock for the whole run: a simulation or capture swapping the folder meanwhile would have this
    # measure one study's images and write the scale into another's study.toml.
    with output_lock(root, command="calibrate"):
        study = read_study(root)
        targets = _targets(study, specimen, ridges, limit)
        m, what = _measure(study, targets, low_high)
        _refuse_unfit(m, study, scale_range)
        typer.echo(f"{m.px_per_mm:.4f} px/mm measured from {m.n_measured} of {m.px_per_mm_each.size} presses of "
                   f"{what}: {_precision(m)}, range {m.measured.min():.4g}-{m.measured.max():.4g}")
        if not dry_run:
            _write(study, m, what, force)


def _refuse_unfit(m, study, scale_range) -> None:
    """A scale no press measured, or one the study reader would refuse (``SensorSettings``' bounds, a band the scale
    cannot resolve: ``sensor.line.scale_misfit``), is never written."""
    from ..io.sensor_settings import SensorSettings
    from ..io.study import STUDY_TOML
    from ..sensor.line import scale_misfit

    if m.n_measured == 0:
        searched = "the scales searched" if scale_range is None else f"--range {scale_range}"
        raise ConfigError(f"no press shows a clear peak of the target's period within {searched}")
    try:
        SensorSettings(px_per_mm=m.px_per_mm, roi=study.sensor.roi)
        problem = scale_misfit(m.px_per_mm, study.sensor.roi)
    except ConfigError as exc:
        problem = exc.message
    if problem is not None:
        within = "" if scale_range is None else f" (searched within --range {scale_range})"
        raise ConfigError(f"the measured {m.px_per_mm:.4g} px/mm is no scale the study can be read at{within}: "
                          f"{problem}; nothing written to {study.root / STUDY_TOML}")


def _write(study, m, what: str, force: bool) -> None:
    from ..io.study import STUDY_TOML
    from ..io.study_config import write_px_per_mm

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
    """(what, period in mm, image paths, the pad's ridge period or None, each image's mount, each image's grating
    period where the target is a pad's ridges and specimens.csv states one, else NaN) per pad."""
    import numpy as np

    from ..model.scale_check import stated_periods

    stated = stated_periods(study) if ridges else {}
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
        _refuse_aperiodic(name, str(specimens.loc[name, "shape"]))
        period = float(specimens.loc[name, "wavelength_mm"])
        rows = manifest[manifest["specimen"] == name]
        groups = [(f"{name} ({period:g} mm) on the {pad} pad", period, rows[rows["pad"] == pad],
                   study.pad_ridge_period_mm.get(pad)) for pad in dict.fromkeys(rows["pad"])]
    groups = _distinct(study.root, groups)
    total = sum(len(g[2]) for g in groups)
    if total == 0:
        raise ConfigError("the manifest lists no press of the target")
    out = []
    for what, period, rows, ridge in groups:
        keep = max(1, round(limit * len(rows) / total))
        chosen = rows.iloc[np.unique(np.linspace(0, len(rows) - 1, min(keep, len(rows))).round().astype(int))]
        mounts = [f"{s}/{p}/{r}" for s, p, r in zip(chosen["specimen"], chosen["pad"], chosen["repetition"])]
        gratings = [stated.get(s, np.nan) if ridges else np.nan for s in chosen["specimen"]]
        out.append((what, period, [study.root / image for image in chosen["image"]], ridge, mounts, gratings))
    return out


def _refuse_aperiodic(name: str, shape: str) -> None:
    """Only a specimen whose image repeats has a period to measure: a random surface's wavelength_mm is a
    correlation length (its spectrum has no peak there), and a shape roughsense does not know may not repeat."""
    from ..model.scale_check import PERIODIC_SHAPES

    if shape.strip().lower() not in PERIODIC_SHAPES:
        raise ConfigError(f"--specimen {name!r} is {shape!r} in specimens.csv, not a grating: its wavelength_mm is no "
                          f"period to measure the scale by; give a {', '.join(PERIODIC_SHAPES)} specimen (or --ridges)")


def _distinct(root, groups: list[tuple]) -> list[tuple]:
    """Each press once, by its bytes: a press copied or hard-linked under a second name is one measurement, not two
    (it would halve the standard error it claims)."""
    import hashlib

    from .._util.files import open_regular

    seen: set[str] = set()
    out = []
    for what, period, rows, ridge in groups:
        keep = []
        for image in rows["image"]:
            with open(open_regular(root / image), "rb") as handle:
                digest = hashlib.file_digest(handle, "sha256").hexdigest()
            keep.append(digest not in seen)
            seen.add(digest)
        out.append((what, period, rows[keep], ridge))
    return out


def _measure(study, targets, scale_range):
    """The pooled measurement over every target's presses, and what was measured, in words."""
    import numpy as np

    from ..sensor.period import ScaleMeasurement, calibrate_scale
    from ..sensor.spectrum import SpatialSpectrum

    reader = SpatialSpectrum(roi=study.sensor.roi, max_pixels=study.sensor.max_pixels)
    values, mounts, blank, entries = [], [], [], []
    for what, period, images, ridge, mount, gratings in targets:
        lines = [reader.line(image)[0] for image in images]
        entries.extend((what, period, line, label) for line, label in zip(lines, mount))
        if ridge is not None:
            entries.extend((f"the pad's {ridge:g} mm ridges", ridge, line, label) for line, label in zip(lines, mount))
        entries.extend(("the specimens' periods", g, line, label) for line, label, g in zip(lines, mount, gratings)
                       if np.isfinite(g))
        each = calibrate_scale(lines, period, px_per_mm_range=scale_range, ridge_period_mm=ridge).px_per_mm_each
        for i, (line, value) in enumerate(zip(lines, each)):
            if not _clear(line, value, period, ridge):
                each[i] = np.nan
                blank.append(images[i])
        values.append(each)
        mounts.extend(mount)
    what = " and ".join(t[0] for t in targets)
    measured = ScaleMeasurement(targets[0][1], np.concatenate(values), np.asarray(mounts, dtype=object))
    _refuse_blank(measured, blank, study.root, what)
    _refuse_disagreeing(entries, measured.px_per_mm, scale_range)
    return measured, what


def _clear(line, px_per_mm: float, period_mm: float, ridge_mm: float | None) -> bool:
    """Whether the press shows the scale it measured: a clear peak (``sensor/prominence.py``) at the target's period;
    on a ridged pad at its ridges' (in every press of it; they outshine a grating, whose own peak may be weak)."""
    from ..sensor.prominence import CLEAR_PROMINENCE, peak_prominence

    period = period_mm if ridge_mm is None else ridge_mm
    return peak_prominence(line, 1.0 / (period * px_per_mm)) >= CLEAR_PROMINENCE


def _refuse_disagreeing(entries, px_per_mm: float, scale_range) -> None:
    """The scale check's search (``model/scale_search.py``) over every resolvable scale must put the measured scale
    among those the presses agree on: a 3 mm target on a 1 mm-ridged pad also reads 3x the scale, where the ridges'
    period falls on the grating's, and a --range that holds only that is refused."""
    from ..model.scale_search import search

    if len({entry[1] for entry in entries}) < 2:  # one period alone has nothing to agree with: its strongest peak
        return
    found = search(entries, px_per_mm)
    if found.doubt:
        raise ConfigError(f"the scale could not be confirmed: {found.doubt}; nothing written")
    if not found.low <= px_per_mm <= found.high:
        within = "" if scale_range is None else f" within --range {scale_range}"
        raise ConfigError(f"the presses' structures agree on {found.px_per_mm:.4g} px/mm, not on the {px_per_mm:.4g} "
                          f"measured{within} (a harmonic or another structure); nothing written")


def _refuse_blank(measured, blank: list, root, what: str) -> None:
    """Presses with no clear peak measure nothing: named on stderr and left out; a target that is mostly such presses
    (noise, a blank frame, another specimen) is refused, naming them."""
    from .._util.text import counted
    from ..sensor.prominence import CLEAR_PROMINENCE

    if not blank:
        return
    names = [str(p.relative_to(root)) if p.is_relative_to(root) else str(p) for p in blank]
    shown = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
    why = (f"no clear peak (over {CLEAR_PROMINENCE:g}x the noise floor) of the target's period (on a ridged pad, of its "
           f"ridges) in the presses of {what}")
    if measured.n_mounts < MIN_MOUNTS or len(blank) * 2 > measured.px_per_mm_each.size:
        raise ConfigError(f"{counted(len(blank), 'press', 'presses')} of {measured.px_per_mm_each.size} show {why}: "
                          f"{shown}; nothing written")
    typer.echo(f"roughsense: warning: {counted(len(blank), 'press', 'presses')} left out, with {why}: {shown}", err=True)


def register(app: typer.Typer) -> None:
    app.command("calibrate")(calibrate)
