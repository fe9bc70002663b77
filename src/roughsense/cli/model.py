"""``roughsense fit`` and ``roughsense predict``: a model (the paper's PLS1 or the peak law) from a study, and
roughness from images, with a flag on every prediction the model extrapolates."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import typer

from .._util.text import counted
from ..errors import ConfigError
from ._common import Jobs, check_seed, number_option, progress, run_inputs
from ._studies import STUDY_METAVAR, checked_scale, echo_scale, resolve_study

ORDER = 20

StudyDir = Annotated[str, typer.Option(
    "--study", metavar=STUDY_METAVAR,
    help="Study folder with images, manifest and ratings, or builtin: the simulated paper study of --seed.",
)]
Pad = Annotated[str, typer.Option("--pad", help="Which pad's images to use (a value of the manifest's pad column).")]
Condition = Annotated[str, typer.Option(
    "--condition", help="Force condition: 1N, 2N, 3N, or combined (a trial's three spectra side by side).")]
ModelOut = Annotated[Path, typer.Option("--out", "-o", help="Model file to write (JSON).")]
MaxComponents = Annotated[int | None, typer.Option(
    "--max-components", show_default=False, parser=number_option("--max-components", whole=True),
    help="Largest number of PLS components to cross-validate. Default: 20, or fewer if the data support fewer. "
         "PLS only.",
)]
CV = Annotated[str, typer.Option(
    "--cv", help="Cross-validation: loo (the paper's leave-one-out), loso (leave one specimen out) or K (shuffled K-fold).")]
Rule = Annotated[str | None, typer.Option(
    "--rule", show_default=False,
    help="PLS component choice: min (lowest CV RMSE, the paper's rule; the default) or 1se (fewest within one SE "
         "of it).")]
ModelName = Annotated[str, typer.Option(
    "--model", help="Model family: peak-law (the default: a power law of where the spectrum peaks and how high, "
                    "the family that passes its controls for surfaces left out of training) or pls (the paper's "
                    "PLS1 on the spectrum, to reproduce the paper).")]
FitSeed = Annotated[int, typer.Option(
    "--seed", parser=number_option("--seed", quantity="seed"),
    help="Seed for the K-fold shuffle (LOO and LOSO use no randomness), the presses drawn for the interval's "
         "residuals of 1-, 3- and 5-press surfaces, and --study builtin.")]
FitRoi = Annotated[str | None, typer.Option(
    "--roi", show_default=False,
    help="Crop where the line is read: 'center' (1900x150 px centred, as in the paper), 'auto' (the 150-row band "
         "with the most horizontal texture) or X,Y,W,H in px. Default: the study's [sensor] roi. Stored in the "
         "model file, so predict reads its images the same way.")]


def fit(study: StudyDir, pad: Pad, condition: Condition, out: ModelOut, max_components: MaxComponents = None,
        cv: CV = "loo", rule: Rule = None, seed: FitSeed = 0, jobs: Jobs = None, model: ModelName = "peak-law",
        force: Annotated[bool, typer.Option("--force", help="Replace MODEL.json if it exists.")] = False,
        roi: FitRoi = None) -> None:
    """Fit a model for one pad and force condition: the peak law (default) or the paper's PLS1 (SIMPLS, X centred).

    Use the default peak law to score surfaces you never trained on; use --model pls to reproduce the paper.
    Spectra are computed from the study's images with its camera scale and ROI; the response is each
    specimen's perceived roughness (geometric mean over participants). For PLS the number of components is
    chosen by cross-validation and the CV curve is printed; the peak law chooses nothing from the data, so its CV
    RMSE is printed beside the training mean's under the same folds. Either model is then judged as the study
    judges it for new surfaces (nested leave-one-specimen-out against the training mean and 199 shuffled
    targets): one line says if it fails, and the file records it with the model's 90 % prediction interval and
    applicability domain. The feature definition is stored too, so `roughsense predict` recomputes features
    exactly as here.
    """
    from .._util.atomic import check_can_write
    from ..analysis.training import check_training_options, parse_cv, train_model
    from ..io.study import read_study
    from ..model.modelfile import save_model
    from ..model.predict import SensorOverride

    condition = parse_condition(condition)
    family = check_training_options(condition, rule, max_components, model)
    override = SensorOverride.parse(roi=roi)
    scheme = parse_cv(cv)
    check_seed(seed)
    check_can_write(out, force=force, inputs=run_inputs(study=study))
    study = resolve_study(study, seed=seed, jobs=None if jobs < 1 else jobs)
    loaded, scale = checked_scale(read_study(study, require_ratings=True), pad=pad)
    trained = train_model(loaded, pad=pad, condition=condition, cv=scheme, rule=rule, seed=seed,
                          max_components=max_components, study_path=str(study), n_jobs=jobs, progress=progress,
                          model=family, roi=None if override is None else override.roi)
    save_model(out, trained.model, feature_definition=trained.feature_definition,
               training={**trained.training, "scale_check": scale}, force=force, domain=trained.domain)
    typer.echo(f"{loaded.name}: pad {pad}, {condition}, {counted(trained.n_samples, 'sample')} x "
               f"{counted(trained.n_features, 'feature')}, {trained.cv.scheme} CV, model {family}")
    if override is not None:
        typer.echo(f"line read at --roi {_roi_text(override.roi)} (the study's [sensor] roi: "
                   f"{_roi_text(loaded.sensor.roi)})")
    _echo_cv(trained)
    _echo_unseen(trained.unseen)
    typer.echo(f"wrote {out}")
    echo_scale(scale)
    _warn_failed_controls(trained.training)


def _echo_unseen(unseen) -> None:
    """The model as the study judges it for new surfaces: RMSE beside the training mean's, p, the interval."""
    import math

    if unseen is None:  # too small a design to judge: the warning after writing says so
        return
    interval = unseen.interval

    def span(halfwidth: float, what: str) -> str:
        if not math.isfinite(halfwidth):
            return f"none {what} (too few specimens for a 90 % interval)"
        return f"x{math.exp(-halfwidth):.2f}-x{math.exp(halfwidth):.2f} {what}"

    width = f"{span(interval.trial_log_halfwidth, 'per trial')}, {span(interval.surface_log_halfwidth, 'per surface')}"
    if math.isfinite(interval.alone_log_halfwidth):
        width += f", {span(interval.alone_log_halfwidth, 'per press read alone')}"
    jackknife = unseen.jackknife
    if jackknife is not None:  # what predict gives a surface (and a press read alone)
        surface = (f"the {jackknife.name}, from surfaces read from {', '.join(map(str, jackknife.counts))} presses"
                   if jackknife.bounded else f"none (the {jackknife.name} needs at least {jackknife.fewest_specimens} specimens)")
        width = (f"{span(interval.trial_log_halfwidth, 'per press of a surface')} (jackknife); per surface and per "
                 f"press read alone {surface}")
    typer.echo(f"a grating left out of training (nested leave-one-specimen-out): per-specimen RMSE {unseen.rmse:.3f} vs the "
               f"training mean's {unseen.null_rmse:.3f}; permutation p {_p_text(unseen.permutation_p, unseen.n_permutations)}; "
               f"90 % prediction interval {width}")


def _p_text(p: float, n_permutations: int) -> str:
    """A permutation p as the report states it (never 0: at its floor, a bound naming the shufflings)."""
    from ..report.tables import permutation_p_text

    text = permutation_p_text(p, n_permutations, at_most="<=")
    return text if text.startswith("<=") or text == "—" else f"= {text}"


def _warn_failed_controls(training) -> None:
    """The one line a model that fails its controls earns, on stderr (``fit`` after writing, ``predict`` before
    scoring)."""
    import warnings

    from ..errors import RoughsenseWarning

    unseen = training.get("unseen") if isinstance(training, dict) else None
    failure = unseen.get("failure") if isinstance(unseen, dict) else None
    if isinstance(failure, str) and failure:
        warnings.warn(RoughsenseWarning(failure), stacklevel=2)


def _echo_cv(trained) -> None:
    """PLS: the CV curve and the chosen count. The peak law: its CV RMSE beside the training mean's, and the law."""
    import numpy as np

    from ..analysis.training import curve_table, law_table
    from ..model.families import PEAK_LAW

    result, number = trained.cv, (lambda v: f"{v:.5f}")
    if trained.family != PEAK_LAW:
        chosen = trained.n_components
        typer.echo(curve_table(result, chosen).to_string(index=False, float_format=number))
        typer.echo(f"chosen: {counted(chosen, 'component')} (CV RMSE {result.rmse[chosen]:.5f}; "
                   f"min at {result.best_n_components}, one-SE rule {result.one_se_n_components})")
        return
    law = trained.model
    typer.echo(law_table(result).to_string(index=False, float_format=number))
    typer.echo(f"peak law: CV RMSE {result.rmse[1]:.5f} (training mean {result.rmse[0]:.5f}); "
               f"log(roughness) = {law.intercept_:.4f} {law.coef_[0]:+.4f} log(peak frequency, mm^-1)"
               + (f" {law.coef_[2]:+.4f} log(second-harmonic ratio)" if law.coef_[2] else
                  " (the contact's shape not read on every training surface: no shape term)"))
    low, high = np.exp(law.feature_min_[0]), np.exp(law.feature_max_[0])
    typer.echo(f"trained on spectral peaks at {low:.3f}-{high:.3f} mm^-1 (periods {1 / high:.2f}-{1 / low:.2f} mm)"
               f"{_shape_range(law)}; a surface outside that range is flagged as extrapolating when predicted")


def _shape_range(law) -> str:
    """The contact patterns a law that reads the shape was trained on ('' where it reads none): they bound its
    domain as the periods do, so the line that states the domain states them too."""
    import numpy as np

    from ..model.peak_law import HARMONIC
    from ..sensor.shape import duty_cycle

    if len(law.feature_min_) <= HARMONIC or not np.isfinite([law.feature_min_[HARMONIC],
                                                              law.feature_max_[HARMONIC]]).all():
        return ""
    return (f" and contact patterns {duty_cycle(law.feature_max_[HARMONIC]):.2f}-"
            f"{duty_cycle(law.feature_min_[HARMONIC]):.2f} of the period in contact")


def parse_condition(text: str) -> str:
    """A --condition as typed, in the form the study and model files use: "2n" -> "2N", "Combined" -> "combined"."""
    value = text.strip()
    return value.lower() if value.lower() == "combined" else value.upper()


def _roi_text(roi) -> str:
    """An ROI as a user would type it after --roi."""
    return roi if isinstance(roi, str) else ",".join(str(v) for v in roi)


ModelFile = Annotated[Path, typer.Argument(metavar="MODEL.json", help="A model file written by `roughsense fit`.")]
Images = Annotated[list[str] | None, typer.Argument(
    metavar="[IMAGE...] [--images-1n IMAGE... --images-2n IMAGE... --images-3n IMAGE...]",
    help="Contact images. A single-force model scores each image. A combined model needs each image's "
         "force: give one --images-XN flag per force of the model, each followed by its images; the i-th "
         "image of each flag form one trial (or use --study).",
    show_default=False,
)]
PredictStudy = Annotated[str | None, typer.Option(
    "--study", metavar=STUDY_METAVAR,
    help="Score a study's images, grouped into trials by its manifest (the model's pad and forces); builtin: the "
         "simulated paper study of --seed.")]
Specimens = Annotated[list[str] | None, typer.Option(
    "--specimen", help="With --study: only this specimen (repeat for more).")]
PredictionsOut = Annotated[Path | None, typer.Option(
    "--out", "-o", help="CSV to write (one row per trial: images, pad, condition, roughness). Default: print a table.")]
Source = Annotated[str | None, typer.Option(
    "--source", help="With --live: a camera index, video file or image-sequence pattern (anything OpenCV's "
                     "VideoCapture opens).")]
Live = Annotated[bool, typer.Option(
    "--live", help="Score frames from --source continuously and show the predicted roughness on the terminal "
                   "(Ctrl-C stops).")]
MaxFrames = Annotated[int | None, typer.Option(
    "--max-frames", parser=number_option("--max-frames", whole=True, low=1),
    help="With --live: stop after this many scored frames.")]
PredictRoi = Annotated[str | None, typer.Option(
    "--roi", show_default=False,
    help="Read the line elsewhere than the model's ROI: 'center', 'auto' (the band with the most horizontal "
         "texture; for images smaller than the model's crop) or X,Y,W,H in px. The spectrum stays the model's; "
         "the ROI used is written beside each prediction. 'auto' warns when the images' field along the line "
         "differs from the model's by more than 20 %.")]
PredictPxPerMm = Annotated[float | None, typer.Option(
    "--px-per-mm", show_default=False, parser=number_option("--px-per-mm", quantity="px_per_mm",
                                                           must="a positive number (px/mm) from 0.01 to 100000"),
    help="The images' scale, if not the model's: the model's spectrum is in mm^-1, so images from another camera "
         "score once their scale is stated. Refused when the model's band is not below Nyquist at this scale, or "
         "an image's line is shorter than 1/f_min.")]


SameSurface = Annotated[bool, typer.Option(
    "--same-surface", help="The images are presses of one surface: the peak law reads its period from all of them "
                           "together, and a surface roughness with its interval is added (--study groups by "
                           "specimen on its own).")]


def predict(model: ModelFile, images: Images = None, study: PredictStudy = None,
            seed: Annotated[int, typer.Option("--seed", parser=number_option("--seed", quantity="seed"),
                                              help="Seed of --study builtin.")] = 0,
            specimens: Specimens = None, out: PredictionsOut = None, jobs: Jobs = None,
            force: Annotated[bool, typer.Option("--force", help="Replace PRED.csv if it exists.")] = False,
            source: Source = None, live: Live = False, max_frames: MaxFrames = None, roi: PredictRoi = None,
            px_per_mm: PredictPxPerMm = None, same_surface: SameSurface = False) -> None:
    """Predict perceived roughness from contact images with a fitted model.

    Features are recomputed with the model's own definition (camera scale, ROI, band, frequencies).
    A combined model scores trials: group their images with --study DIR [--specimen S] (from the manifest) or
    with --images-1n ... --images-2n ... --images-3n ...; an image whose name says another force than its
    slot (e.g. _1N_ in the 2N slot) is refused. With --live --source SRC, a single-force model scores camera
    frames continuously. --roi and --px-per-mm read images the model's crop or scale does not fit.

    Each row gets its roughness relative to the model's reference specimen, its 90 % prediction interval
    (pi90_low, pi90_high), whether it lies outside what the model was trained on (extrapolates) and how
    (outside); with --study or --same-surface, each surface's mean roughness and interval too.
    """
    from .._util.atomic import check_can_write
    from ..model.modelfile import load_model
    from ..model.predict import SensorOverride, warn_field_of_view

    override = SensorOverride.parse(roi=roi, px_per_mm=px_per_mm)
    positional, by_condition = _split_image_flags(images or [])
    given = [name for name, used in (("IMAGE...", positional), ("--images-XN", by_condition),
                                     ("--study", study is not None)) if used]
    if live or source is not None:
        if not (live and source is not None):
            raise ConfigError("live scoring needs both --live and --source SRC")
        if given:
            raise ConfigError(f"give either {given[0]} or --live --source SRC, not both")
        if same_surface:
            raise ConfigError("--same-surface groups images given at once; live frames are scored one by one")
        _predict_live(load_model(model), source, max_frames, override)
        return
    _check_image_sources(given, specimens, study)
    if same_surface:
        _refuse_repeats([*positional, *(p for paths in by_condition.values() for p in paths)])
    if out is not None:
        check_can_write(out, force=force, inputs=run_inputs(model, positional, *by_condition.values(), study=study))
    loaded = load_model(model)
    reference = None
    if study is not None:
        study = resolve_study(study, seed=seed, jobs=None if jobs < 1 else jobs)
    trials, table, read = _trials(loaded, positional, by_condition, study, specimens or [])
    if read is not None:
        override, reference = _study_scale(loaded, read, override, table)
    surfaces = table["specimen"].astype(str).to_numpy() if "specimen" in table else (
        ["surface"] * len(trials) if same_surface else None)
    scores = _score_into(table, loaded, trials, jobs, override, surfaces, reference)
    warn_field_of_view(loaded, override, [image for trial in trials for image in trial])  # after: an error wins
    _show_or_write(table, out, from_study=study is not None)
    _echo_extrapolation(loaded, scores)
    _warn_plain_interval(loaded)
    _echo_scale(scores.scale)
    _warn_few_presses(loaded.training, surfaces, len(trials))
    _warn_failed_controls(loaded.training)


def _warn_plain_interval(loaded) -> None:
    import warnings

    from ..errors import RoughsenseWarning
    from ..model.predict import plain_fallback_line

    line = plain_fallback_line(loaded)
    if line:
        warnings.warn(RoughsenseWarning(line), stacklevel=2)


def _refuse_repeats(images) -> None:
    """--same-surface averages presses: one file given twice (by any path) would count as two presses and narrow
    the surface's interval."""
    seen: dict[tuple[int, int], str] = {}
    for image in images:
        try:
            info = os.stat(image)
        except OSError:
            continue  # reading it names the problem
        key = (info.st_dev, info.st_ino)
        if key in seen:
            raise ConfigError(f"--same-surface: {image} is the same file as {seen[key]}; give each press once")
        seen[key] = str(image)


def _study_scale(loaded, study, override, table):
    """Images of a study are read at its own study.toml scale (said in one line), unless --px-per-mm says
    otherwise; the trials of specimens of stated period are marked for the scale check."""
    import numpy as np

    from ..model.predict import SensorOverride

    model_px = float(loaded.features["spectrum"]["px_per_mm"])
    if override is None or override.px_per_mm is None:
        stated = float(study.sensor.px_per_mm)
        typer.echo(f"roughsense: images read at {stated:g} px/mm, the scale in {study.root / 'study.toml'} (the model was "
                   f"fitted at {model_px:g} px/mm)", err=True)
        override = SensorOverride(None if override is None else override.roi, stated)
    reference = None
    if "specimen" in table:
        from ..model.scale_check import stated_periods

        periods = stated_periods(study)
        reference = ("the specimens' periods in specimens.csv",
                     np.array([periods.get(s, np.nan) for s in table["specimen"].astype(str)]))
    return override, reference


def _echo_scale(check) -> None:
    """The scale check's one line: a warning when the images' scale is off (every row is flagged), else a note."""
    import warnings

    from ..errors import RoughsenseWarning

    if check is None:
        return
    if check.off:
        warnings.warn(RoughsenseWarning(f"{check.summary()}: every prediction is flagged 'scale'; measure the scale "
                                        "with roughsense calibrate, or pass the images' --px-per-mm"), stacklevel=2)
    else:
        typer.echo(f"roughsense: {check.summary()}", err=True)


def _check_image_sources(given: list[str], specimens, study) -> None:
    if not given:
        raise ConfigError("no images given: pass IMAGE..., --images-1n ... (one flag per force) or --study DIR "
                          "(or --live --source SRC)")
    if len(given) > 1:
        raise ConfigError(f"give images one way: {given[0]} or {given[1]}, not both")
    if specimens and study is None:
        raise ConfigError("--specimen selects from a study: add --study DIR")


def _score_into(table, loaded, trials: list[tuple], jobs: int, override=None, surfaces=None, reference=None):
    """Score the trials and add their images, pad, condition, model, roughness, interval and flags to ``table``.

    Roughness is a ratio to the reference specimen, rounded to 3 significant digits (the panel's own precision is
    coarser); the flag is written ``true``/``false`` (any CSV reader's booleans), and ``outside`` says what lies
    outside the model's domain. An overridden ROI is written in its own column (``roi``); the scale the images were
    read at always is (``px_per_mm``: the model's, the study's or --px-per-mm).
    Returns the scores.
    """
    import numpy as np

    from ..model.predict import model_condition, model_pad, score_trials

    images = [image for trial in trials for image in trial]
    scores = score_trials(loaded, images, n_jobs=jobs, progress=progress, override=override, surfaces=surfaces,
                          reference=reference)
    if len(loaded.conditions) == 1:
        table["image"] = [str(t[0]) for t in trials]
    else:
        for i, condition in enumerate(loaded.conditions):
            table[f"image_{condition}"] = [str(t[i]) for t in trials]
    table["pad"] = model_pad(loaded)
    table["condition"] = model_condition(loaded)
    table["model"] = loaded.family
    if override is not None and override.roi is not None:
        table["roi"] = _roi_text(override.roi)
    scale = override.px_per_mm if override is not None and override.px_per_mm is not None else None
    table["px_per_mm"] = _scale_text(scale if scale is not None else loaded.features["spectrum"]["px_per_mm"])
    name = roughness_column(loaded)
    table[name] = _three_digits(scores.roughness)
    if np.isfinite(scores.low).all():
        table["pi90_low"], table["pi90_high"] = _three_digits(scores.low), _three_digits(scores.high)
        table["pi90_method"] = scores.method
    if scores.surface_roughness is not None:
        table[f"surface_{name}"] = _three_digits(scores.surface_roughness)
        if np.isfinite(scores.surface_low).all():
            table["surface_pi90_low"] = _three_digits(scores.surface_low)
            table["surface_pi90_high"] = _three_digits(scores.surface_high)
            table["surface_pi90_method"] = scores.surface_method
    _surface_flags(table, scores, surfaces)
    table["extrapolates"] = ["true" if flag else "false" for flag in scores.flagged]
    table["outside"] = scores.reasons
    if "surface_extrapolates" in table:
        quiet = (table["surface_extrapolates"] == "true").to_numpy() & ~scores.flagged
        table.loc[quiet, "outside"] = "this press lies inside; other presses of its surface do not (their rows say why)"
    return scores


def _scale_text(px_per_mm) -> str:
    """The scale the images were read at, as written in study.toml or on the command line (34.9, not the CSV's
    17-digit 34.899999999999999): every row says it, whether the images were read alone, as one surface or by study."""
    return repr(float(px_per_mm))


def _surface_flags(table, scores, surfaces) -> None:
    """``read_as`` says how ``extrapolates`` judged each row: ``press`` (read alone) or ``surface`` (a press read
    with the other presses of its surface); grouped, ``surface_extrapolates`` is true when any press of the surface
    is flagged, and a press that is not says so in ``outside`` (its surface's reason is in the other rows)."""
    if surfaces is not None:
        import pandas as pd

        flagged = pd.Series(scores.flagged).groupby(pd.Series(list(surfaces))).transform("any").to_numpy()
        table["surface_extrapolates"] = ["true" if flag else "false" for flag in flagged]
    table["read_as"] = "press" if surfaces is None else "surface"


def roughness_column(loaded) -> str:
    """``roughness_rel_<reference>``: the column says what the number is a ratio to."""
    from ..io.names import is_safe_name

    reference = loaded.training.get("reference_specimen") if isinstance(loaded.training, dict) else None
    # a name no file may carry (an edited model file) still gives a column that says the value is relative
    return f"roughness_rel_{reference}" if is_safe_name(reference) else "roughness_rel_reference"


def _three_digits(values) -> list[str]:
    """Values as text with 3 significant digits (written as is: a float column would print 1.23 as 1.2299...)."""
    import numpy as np

    return [f"{float(f'{v:.3g}'):g}" for v in np.asarray(values, dtype=float)]  # 1234 -> 1230, not 1.23e+03


EXTRAPOLATION_WHY = "outside what the model was trained on; the `outside` column says how"


def _echo_extrapolation(loaded, scores) -> None:
    """How many predictions lie outside the model's domain; every one of them is one line naming the most common
    reason (a wrong pad, scale or ROI does that), and a model without an interval says so. Wrapped to the terminal."""
    import shutil
    import textwrap

    from ..model.predict import model_interval

    def echo(text: str) -> None:
        typer.echo(textwrap.fill(text, width=shutil.get_terminal_size().columns, subsequent_indent="  "))

    flagged = scores.flagged
    count, total = int(flagged.sum()), len(flagged)
    if count == total and total > 1:
        reasons = [r for r in scores.reasons if r]
        common = max(set(reasons), key=reasons.count)
        echo(f"every prediction ({total}) lies outside what the model was trained on, e.g. {common}; check "
                   "that the images are of the model's pad, scale and ROI")
    elif count:
        verb = "lies" if count == 1 else "lie"
        echo(f"{count} of {counted(total, 'prediction')} {verb} {EXTRAPOLATION_WHY}")
    else:
        echo(f"{'all ' if total > 1 else ''}{counted(total, 'prediction')} within what the model was trained on")
    if model_interval(loaded) is None:
        echo("no prediction interval: the model file has none it can use (written before intervals, or from "
                   "too few specimens); refit it with roughsense fit")


def few_presses_line(training: dict, surfaces, n_trials: int) -> str:
    """One line when a surface is read from fewer presses than the model's pad needed, held out of training, to
    beat the training mean clearly (``analysis.presses.presses_needed``, the model file's ``training.presses``)."""
    import numpy as np
    import pandas as pd

    presses = training.get("presses") if isinstance(training, dict) else None
    needed = presses.get("needed") if isinstance(presses, dict) else None
    if not isinstance(needed, int) or needed <= 1:
        return ""
    counts = pd.Series(np.asarray(surfaces)).value_counts() if surfaces is not None else pd.Series([1] * n_trials)
    fewest = int(counts.min()) if len(counts) else 0
    if fewest >= needed:
        return ""
    errors = presses.get("rmse_by_presses", {})
    error = f" (held-out error {errors[str(fewest)]:.2f} vs the training mean's {presses['null_rmse']:.2f})" \
        if str(fewest) in errors and isinstance(presses.get("null_rmse"), float) else ""
    return (f"fewer presses than this model's pad needs: a surface read from {counted(fewest, 'press', 'presses')} here; held "
            f"out of training it needed {needed} to beat the training mean clearly{error}; press each surface {needed} times "
            "(--same-surface or --study groups them)")


def _warn_few_presses(training: dict, surfaces, n_trials: int) -> None:
    line = few_presses_line(training, surfaces, n_trials)
    if line:
        typer.echo(line)


#: Columns with one value for every row: the terminal shows them once, above the table.
_CONSTANT_COLUMNS = ("pad", "condition", "model", "roi", "px_per_mm", "read_as", "pi90_method")


def _show_or_write(table, out: Path | None, *, from_study: bool = False) -> None:
    from .._util.atomic import write_csv

    if out is None:
        typer.echo(_terminal_table(table, from_study=from_study))
    else:
        write_csv(out, table, float_format="%.17g")
        typer.echo(f"wrote {counted(len(table), 'prediction')} to {out}")


def _terminal_table(table, *, from_study: bool) -> str:
    """The predictions for a terminal: columns that never change in a line above, a study's image paths left to
    --out (its specimen and repetition name each trial), and the rest wrapped to the terminal's width; then each
    surface's roughness and each distinct reason a trial lies outside the model's domain."""
    import shutil
    import textwrap

    constant = [c for c in _CONSTANT_COLUMNS if c in table.columns]
    heading = ", ".join(f"{c.replace('_', ' ')} {table[c].iloc[0]}" for c in constant if str(table[c].iloc[0]))
    dropped = constant + ([c for c in table.columns if c.startswith("image")] if from_study else [])
    surface = [c for c in table.columns if c.startswith("surface_")]
    dropped.append("outside")  # too long for a column: said below the table, once per distinct reason
    if from_study:
        heading += "; each trial's images: add --out PRED.csv"
    width = shutil.get_terminal_size().columns
    body = table.drop(columns=dropped + surface).to_string(index=False, line_width=width)
    lines = [*textwrap.wrap(heading, width=width, subsequent_indent="  "), body] if heading else [body]
    if surface:
        key = "specimen" if "specimen" in table else None
        for name, rows in (table.groupby(key, sort=False) if key else [("surface", table)]):
            first = rows.iloc[0]
            interval = (f" (90 % interval {first['surface_pi90_low']}-{first['surface_pi90_high']}, "
                        f"{first['surface_pi90_method']})" if "surface_pi90_low" in rows else "")
            label = f"surface {name}" if key else "the surface (every image: --same-surface)"
            lines.append(f"{label}: {first[surface[0]]}{interval}, mean of {counted(len(rows), 'trial')}")
    reasons = table["outside"][table["outside"].astype(bool)]
    for reason, count in reasons.value_counts().items():
        lines.extend(textwrap.wrap(f"outside what the model was trained on ({counted(int(count), 'trial')}): {reason}",
                                   width=width, subsequent_indent="  "))
    return "\n".join(lines)


def register(app: typer.Typer) -> None:
    app.command("fit")(fit)
    app.command("predict", context_settings={"ignore_unknown_options": True})(predict)


_IMAGE_FLAG = "--images-"



def _slot_force(label: str) -> float | None:
    """The force of an ``--images-XN`` slot label, spelled as every number roughsense reads (io/numbers.py)."""
    from ..io.numbers import NumberError, parse_number

    if not label.endswith("N"):
        return None
    try:
        return float(parse_number(label[:-1], quantity="force_n"))
    except NumberError:
        return None

def _split_image_flags(tokens: list[str]) -> tuple[list[Path], dict[str, list[Path]]]:
    """Bare images, and the images after each ``--images-XN`` flag (up to the next flag), by condition "XN".

    Click cannot give an option several values, so the command takes every token as an argument and splits here;
    any other unknown ``--option`` is refused rather than taken for a file.
    """
    positional: list[Path] = []
    by_condition: dict[str, list[Path]] = {}
    current: list[Path] | None = None
    for token in tokens:
        if token.startswith(_IMAGE_FLAG):
            label, _, first = token[len(_IMAGE_FLAG):].partition("=")
            condition = label.upper()
            force_n = _slot_force(condition)
            if force_n is None:
                raise ConfigError(f"{token.partition('=')[0]}: expected a force like --images-1n or --images-2.5n")
            condition = f"{force_n:g}N"
            current = by_condition.setdefault(condition, [])
            if first:
                current.append(Path(first))
        elif token.startswith("-") and len(token) > 1 and not Path(token).exists():
            raise ConfigError(f"no such option: {token}")
        elif current is not None:
            current.append(Path(token))
        else:
            positional.append(Path(token))
    return positional, by_condition


def _trials(loaded, positional, by_condition, study, specimens):
    """The model's trials (tuples of images in its condition order), the table's leading columns and the study read
    (None without --study)."""
    import pandas as pd

    from ..model.predict import groups_from_flags, groups_from_images, groups_from_study

    if study is not None:
        from ..io.study import read_study

        read = read_study(study)
        groups, meta = groups_from_study(loaded, read, specimens)
        return groups, meta, read
    groups = groups_from_flags(loaded, by_condition) if by_condition else groups_from_images(loaded, positional)
    return groups, pd.DataFrame(index=range(len(groups))), None


def _predict_live(loaded, source: str, max_frames: int | None, override=None) -> None:
    """Wire the model's scorer into the rig's live loop (the rig itself knows nothing of models)."""
    from ..model.predict import frame_scorer
    from ..rig.live import live_scores, render_live

    summary = render_live(live_scores(source, frame_scorer(loaded, override), max_frames=max_frames))
    last = "none" if summary.last_score is None else f"{summary.last_score:.4f}"
    typer.echo(f"{summary.updates} update(s), {summary.updates_per_s:.1f}/s; last roughness {last}")
    if summary.extrapolated:
        why = f"; the last: {summary.reason}" if summary.reason else ""
        typer.echo(f"{summary.extrapolated} frame(s) extrapolated: outside what the model was trained on{why}")
