"""``roughsense features``: contact images (or a study folder) -> a CSV of spatial spectra and contact measures."""
from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .. import defaults
from ..errors import ConfigError
from ..sensor.settings import MAX_N_FREQS
from ._common import Jobs, number_option, parse_float_list, progress, run_inputs
from ._studies import STUDY_METAVAR, resolve_study

ORDER = 10


def _band(text: str) -> tuple[float, float]:
    values = parse_float_list(text, name="band")
    if len(values) != 2:
        raise ConfigError(f"--band needs two numbers F_MIN,F_MAX in mm^-1, got {text!r}")
    return values[0], values[1]


FeaturesOut = Annotated[Path, typer.Option(
    "--out", "-o", help="CSV to write: an image column (or the manifest's columns), then one column per frequency, "
    "named with its unit (f_0.1205_per_mm), then the contact measures: land_mm and groove_mm (the mean land "
    "(contact) and groove (gap) widths over the whole periods in the contact band), land_fraction and "
    "width_se_mm (their standard error); empty where a press's cannot be read with confidence. Beside it, "
    "OUT.spectrum.json holds the exact grid (freq_per_mm) and every setting that made the spectra.")]
Images = Annotated[list[Path] | None, typer.Argument(
    metavar="IMAGE...", help="Contact images (PNG, JPEG, TIFF or BMP; 8 or 16 bit; gray or colour).", show_default=False)]
StudyDir = Annotated[str | None, typer.Option(
    "--study", metavar=STUDY_METAVAR, show_default=False,
    help="A study folder: use its manifest's images and carry the manifest's columns along. "
         "builtin: the simulated paper study of --seed.")]
PxPerMm = Annotated[float | None, typer.Option(
    "--px-per-mm", show_default=False, parser=number_option("--px-per-mm", quantity="px_per_mm",
                                                           must="a positive number (px/mm) from 0.01 to 100000"),
    help=f"Camera scale in px/mm along the line. Default: the study's, else {defaults.PX_PER_MM:g} (the paper's "
         f"{defaults.PX_PER_MM * 10:g} px/cm).")]
Roi = Annotated[str | None, typer.Option(
    "--roi", show_default=False,
    help=f"Crop: 'center' ({defaults.CENTER_CROP_PX[0]}x{defaults.CENTER_CROP_PX[1]} px centred, as in the paper), 'auto' (the "
         f"{defaults.CENTER_CROP_PX[1]}-row band with the most horizontal texture) or X,Y,W,H in px. Default: the study's, "
         f"else {defaults.ROI}.")]
Rows = Annotated[int, typer.Option(
    "--rows", parser=number_option("--rows", whole=True),
    help="Average the N central rows of the crop (1 = the paper's middle row).")]
Band = Annotated[str, typer.Option("--band", help="Frequency band F_MIN,F_MAX in mm^-1.")]
NFreqs = Annotated[int, typer.Option(
    "--n-freqs", parser=number_option("--n-freqs", low=2, high=MAX_N_FREQS, whole=True),
    help=f"Number of evenly spaced frequencies in the band (2 to {MAX_N_FREQS}).")]
Window = Annotated[str, typer.Option(
    "--window", help=f"Taper before the DFT: '{defaults.WINDOW}' (default) or 'none' (the paper's literal choice).")]
RidgePeriod = Annotated[float | None, typer.Option(
    "--ridge-period-mm", show_default=False,
    parser=number_option("--ridge-period-mm", quantity="ridge_period_mm", must="a number of mm from 0.001 to 100"),
    help="The pad's ridge period in mm, for IMAGE... pressed on a fingerprint-like pad (its lands and grooves are "
         "then read on the ridges' crests). Default: a smooth pad. With --study each pad's comes from study.toml "
         "([pads.NAME] ridge_period_mm).")]
MaxPixels = Annotated[int | None, typer.Option(
    "--max-pixels", show_default=False, parser=number_option("--max-pixels", whole=True),
    help="Refuse images whose header claims more pixels (width x height) than this, before decoding. "
         f"Default: the study's [sensor] max_pixels, else {defaults.MAX_PIXELS}.")]


def features(
    out: FeaturesOut, images: Images = None, study: StudyDir = None,
    seed: Annotated[int, typer.Option("--seed", parser=number_option("--seed", quantity="seed"),
                                      help="Seed of --study builtin.")] = defaults.SEED,
    px_per_mm: PxPerMm = None, roi: Roi = None, rows: Rows = defaults.ROWS,
    band: Band = f"{defaults.F_MIN_PER_MM:g},{defaults.F_MAX_PER_MM:.1f}",
    n_freqs: NFreqs = defaults.N_FREQS, window: Window = defaults.WINDOW,
    jobs: Jobs = None,
    force: Annotated[bool, typer.Option(
        "--force", help="Replace FEATURES.csv, its grid file and the --plot file if they exist (never an input).")] = False,
    max_pixels: MaxPixels = None,
    ridge_period_mm: RidgePeriod = None,
    plot: Annotated[Path | None, typer.Option(
        "--plot", show_default=False, help="Also draw the one IMAGE's contact line, its contact band with the lands "
        "and grooves read and their widths, and its spectrum, its peak marked, into this file (.png, .svg or "
        ".pdf).")] = None,
) -> None:
    """Turn contact images into normalised spatial spectra (the paper's section 3.2).

    Each image is cropped, converted to gray (MATLAB weights) and reduced to its middle row; the amplitude
    spectrum of that line is sampled at N_FREQS frequencies over the band and normalised to unit area. The land
    and groove widths are read on the band's rows averaged (sensor/contact_geometry.py). Nothing is written if any
    image fails; the error names that file.
    """
    import json

    from .._util.atomic import check_outputs, write_bytes, write_csv, write_text
    from ..io.sensor_settings import check_max_pixels
    from ..io.study import read_study
    from ..sensor.contact_geometry import CONTACT_MEASURES

    _check_sources(images, study, ridge_period_mm)
    if max_pixels is not None:
        check_max_pixels(max_pixels, option="--max-pixels")
    _check_plot(plot, images)
    check_outputs({"--out": out, "--out's grid file": definition_path(out), "--plot": plot}, force=force,
                  inputs=run_inputs(images or [], study=study))
    f_min, f_max = _band(band)
    loaded = read_study(resolve_study(study, seed=seed, jobs=None if jobs < 1 else jobs)) if study is not None else None
    if loaded is not None:
        px_per_mm = loaded.sensor.px_per_mm if px_per_mm is None else px_per_mm
        roi = loaded.sensor.roi if roi is None else roi
        max_pixels = loaded.sensor.max_pixels if max_pixels is None else max_pixels
    spectrum = _spectrum(px_per_mm=px_per_mm, roi=roi, rows=rows, f_min=f_min, f_max=f_max, n_freqs=n_freqs, jobs=jobs,
                         window=window, max_pixels=max_pixels)
    paths, table = _table(spectrum, loaded, images, ridge_period_mm)
    names = [str(c) for c in spectrum.get_feature_names_out()]
    # the figure is drawn before anything is written: a failure or a stop while drawing leaves no CSV behind
    drawn = (_draw(plot, spectrum, paths[0], table[names].to_numpy(float)[0], ridge_period_mm)
             if plot is not None else None)
    write_csv(out, table.rename(columns=dict(zip(names, unit_names(spectrum.freq_per_mm_)))))
    write_text(definition_path(out), json.dumps(spectrum.feature_definition(), indent=2) + "\n")
    typer.echo(f"wrote {len(paths)} x {len(names)} features and {len(CONTACT_MEASURES)} contact measures to {out} "
               f"(grid and settings: {definition_path(out)})")
    if drawn is not None:
        write_bytes(plot, drawn)
        typer.echo(f"drew its line, contact band and spectrum in {plot}")


def _check_sources(images, study, ridge_period_mm) -> None:
    """IMAGE... or --study, one of them; a ridge period only for IMAGE... (a study's pads carry their own)."""
    if study is not None and images:
        raise ConfigError("give either IMAGE... or --study DIR, not both")
    if study is None and not images:
        raise ConfigError("no images given; pass IMAGE... or --study DIR")
    if study is not None and ridge_period_mm is not None:
        raise ConfigError("--ridge-period-mm is for IMAGE...; with --study each pad's ridge period comes from its "
                          "study.toml ([pads.NAME] ridge_period_mm)")


def _check_plot(plot: Path | None, images) -> None:
    """--plot draws one image, into a file named by its format; checked before any work."""
    if plot is None:
        return
    if not images or len(images) != 1:
        raise ConfigError("--plot draws one image: give exactly one IMAGE (not several, not --study)")
    if plot.suffix.lower().lstrip(".") not in ("png", "svg", "pdf"):
        raise ConfigError(f"--plot: {plot.name!r} must end in .png, .svg or .pdf (the format it is written in)")


def _draw(plot: Path, spectrum, image: Path, amplitude, ridge_period_mm: float | None) -> bytes:
    """The image's line, contact band and spectrum (report/figures.py), as the bytes of ``plot``'s format."""
    from ..report import figures

    line, box = spectrum.line(image)
    fig = figures.line_spectrum_figure(line, float(spectrum.px_per_mm), spectrum.freq_per_mm_, amplitude,
                                       f"{Path(image).name}: crop x={box[0]}, y={box[1]}, {box[2]} x {box[3]} px",
                                       contact=spectrum.contact_reading(image, ridge_period_mm))
    return figures.figure_bytes(fig, plot.suffix.lower().lstrip("."))


def definition_path(out: Path) -> Path:
    """Where the spectra's definition goes beside the CSV: features.csv -> features.spectrum.json."""
    out = Path(out)
    return out.with_name(f"{out.stem if out.suffix.lower() == '.csv' else out.name}.spectrum.json")


def unit_names(freq_per_mm) -> list[str]:
    """A spectrum column's header with its unit, f_0.1205_per_mm: the fewest decimals (at least 4) that keep every
    name distinct. The exact grid is in the definition file, so nobody parses a header to get a number back."""
    for decimals in range(4, 17):
        names = [f"f_{float(f):.{decimals}f}_per_mm" for f in freq_per_mm]
        if len(set(names)) == len(names):
            return names
    return [f"f_{float(f)!r}_per_mm" for f in freq_per_mm]


def _spectrum(*, px_per_mm, roi, rows, f_min, f_max, n_freqs, jobs, window, max_pixels):
    """The transformer, with the defaults of a study-less run where an option was not given."""
    from ..sensor.spectrum import SpatialSpectrum

    return SpatialSpectrum(
        px_per_mm=defaults.PX_PER_MM if px_per_mm is None else px_per_mm,
        roi=defaults.ROI if roi is None else roi,
        rows=rows, f_min_per_mm=f_min, f_max_per_mm=f_max, n_freqs=n_freqs, n_jobs=jobs, window=window,
        max_pixels=defaults.MAX_PIXELS if max_pixels is None else max_pixels,
    ).fit()


def _table(spectrum, loaded, images, ridge_period_mm):
    """(the images read, the table to write): the study's manifest and features (each pad's contact read with its
    own ridges), or one row per IMAGE."""
    from ..analysis.dataset import plain_names, study_features

    if loaded is not None:
        features = study_features(loaded, spectrum=spectrum, progress=progress)
        return loaded.image_paths, plain_names(features, source=loaded.root / "manifest.csv")
    return list(images), _image_features(spectrum, list(images), ridge_period_mm)


def _image_features(spectrum, paths: list[Path], ridge_period_mm: float | None):
    """One row per image: its path, then its spectrum, then its contact measures (read as on a pad with ridges of
    ``ridge_period_mm``, or a smooth one)."""
    import numpy as np
    import pandas as pd

    from ..sensor.contact_geometry import CONTACT_MEASURES

    names = list(spectrum.get_feature_names_out())
    read = list(progress(spectrum.iter_transform_contact(paths, ridge_period_mm), total=len(paths),
                         description="features"))
    spectra = np.vstack([s for s, _ in read]) if read else np.empty((0, len(names)))
    contact = np.vstack([c for _, c in read]) if read else np.empty((0, len(CONTACT_MEASURES)))
    return pd.concat([pd.DataFrame({"image": [str(p) for p in paths]}), pd.DataFrame(spectra, columns=names),
                      pd.DataFrame(contact, columns=list(CONTACT_MEASURES))], axis=1)


def register(app: typer.Typer) -> None:
    app.command("features")(features)
