"""``roughsense predict``: roughness from images with a fitted model, with a flag and a reason on every prediction
the model extrapolates, and its 90 % interval; or live, frame by frame from a camera. The table itself is
``model/predict_table.py``'s."""
from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .. import defaults
from .._util.text import counted
from ..errors import ConfigError
from ..paper import press_meaning
from ._common import Jobs, number_option, progress, run_inputs
from ._studies import STUDY_METAVAR, resolve_study
from .fit import _warn_failed_controls
from .image_flags import split_image_flags

ORDER = 20

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
                                              help="Seed of --study builtin.")] = defaults.SEED,
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

    Each row gets its roughness relative to the model's reference specimen, one 90 % interval (pi90_*: the jackknife+;
    jackknife90_*: the plain jackknife, no coverage guarantee), whether and how it lies outside what the model was
    trained on (extrapolates, outside); with --study or --same-surface, each surface's roughness and interval too. The grating's
    orientation is written beside each (orientation_deg; flagged beyond +-6 degrees).

    Each image passes the model's contact-image gate (a conformal test at 1 % per press, fitted by `fit`): a press
    unlike the training presses (a photograph, noise, the other pad, a magnified image), or an unreadable one, is
    withheld (no roughness, withheld=true, the reason in `outside`). Exit status: 0; 3 some rows withheld; 2 an error.
    """
    from .._util.atomic import check_can_write
    from ..model.modelfile import load_model
    from ..model.predict import run_prediction
    from ..model.reading import SensorOverride

    override = SensorOverride.parse(roi=roi, px_per_mm=px_per_mm)
    positional, by_condition = split_image_flags(images or [])
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
    _check_image_sources(given, specimens, study, surface=[*positional, *(p for paths in by_condition.values()
                                                                          for p in paths)] if same_surface else None)
    if out is not None:
        check_can_write(out, force=force, inputs=run_inputs(model, positional, *by_condition.values(), study=study))
    loaded = load_model(model)
    if study is not None:
        study = resolve_study(study, seed=seed, jobs=None if jobs < 1 else jobs)
    run = run_prediction(loaded, positional, study=study, specimens=specimens or [], images_by_force=by_condition,
                         same_surface=same_surface, override=override, n_jobs=jobs, progress=progress,
                         note=lambda line: typer.echo(f"roughsense: {line}", err=True))
    _show_or_write(run.table, out, from_study=study is not None)
    _echo_extrapolation(loaded, run.scores)
    _warn_plain_interval(loaded)
    _echo_scale(run.scores.scale)
    _warn_few_presses(loaded.training, run.trials.surfaces, len(run.trials.groups))
    _warn_failed_controls(loaded.training)
    _exit_if_withheld(run.scores)


def _exit_if_withheld(scores) -> None:
    """One line on stderr, and exit status :data:`WITHHELD_EXIT`, when the gate or an unreadable image withheld
    rows; one line when the model file has no gate to apply."""
    import warnings

    from ..errors import RoughsenseWarning
    from ..model.press_gate import NO_GATE_LINE
    from ._common import WITHHELD_EXIT

    if not scores.gated:
        warnings.warn(RoughsenseWarning(NO_GATE_LINE), stacklevel=2)
    count = int(scores.withheld.sum()) if scores.withheld is not None else 0
    if count:
        typer.echo(f"roughsense: {count} of {counted(len(scores.withheld), 'row')} withheld (no roughness: not a "
                   f"contact image like the model's training presses, or unreadable; the `outside` column says why); "
                   f"exit status {WITHHELD_EXIT}", err=True)
        raise typer.Exit(WITHHELD_EXIT)


def _warn_plain_interval(loaded) -> None:
    import warnings

    from ..errors import RoughsenseWarning
    from ..model.model_intervals import plain_fallback_line

    line = plain_fallback_line(loaded)
    if line:
        warnings.warn(RoughsenseWarning(line), stacklevel=2)


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


def _check_image_sources(given: list[str], specimens, study, *, surface: list | None = None) -> None:
    """One way of giving images, and (``surface``: the presses of one surface) each press given once."""
    from ..model.trials import refuse_repeats

    if not given:
        raise ConfigError("no images given: pass IMAGE..., --images-1n ... (one flag per force) or --study DIR "
                          "(or --live --source SRC)")
    if len(given) > 1:
        raise ConfigError(f"give images one way: {given[0]} or {given[1]}, not both")
    if specimens and study is None:
        raise ConfigError("--specimen selects from a study: add --study DIR")
    if surface is not None:
        refuse_repeats(surface)


EXTRAPOLATION_WHY = "outside what the model was trained on; the `outside` column says how"


def _echo_extrapolation(loaded, scores) -> None:
    """How many predictions lie outside the model's domain; every one of them is one line naming the most common
    reason (a wrong pad, scale or ROI does that), and a model without an interval says so. Wrapped to the terminal."""
    import shutil
    import textwrap

    from ..model.model_intervals import model_interval

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
        echo(no_interval_line(loaded.training))


def no_interval_line(training: dict) -> str:
    """Why a model has no interval, by its real cause: too few specimens (refitting the same study would not help),
    a design too small to be judged on a grating left out, or a file written before intervals."""
    import math

    from ..model.interval import INTERVAL_LEVEL

    training = training if isinstance(training, dict) else {}
    specimens = training.get("specimens")
    fitted = f"fitted on {counted(len(specimens), 'specimen')}, " if isinstance(specimens, list) else ""
    unseen = training.get("unseen")
    if "interval" in training or (isinstance(unseen, dict) and unseen.get("failure")):
        fewest = next(n for n in range(1, 1000) if math.ceil((n + 1) * INTERVAL_LEVEL) <= n)
        return (f"no prediction interval: the model was {fitted}too few for a {100 * INTERVAL_LEVEL:g} % interval "
                f"(at least {fewest}); fit it on a study of more specimens")
    return "no prediction interval: the model file was written before intervals; refit it with roughsense fit"


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
    meaning = press_meaning(str(training.get("condition", "")))
    return (f"fewer presses than this model's pad needs: a surface read from {counted(fewest, 'press', 'presses')} here; held "
            f"out of training it needed {needed} to beat the training mean clearly{error}; press each surface {needed} times "
            f"(--same-surface or --study groups them{'; ' + meaning if meaning else ''})")


def _warn_few_presses(training: dict, surfaces, n_trials: int) -> None:
    line = few_presses_line(training, surfaces, n_trials)
    if line:
        typer.echo(line)


def _show_or_write(table, out: Path | None, *, from_study: bool = False) -> None:
    """The table on the terminal, or its CSV (``model/predict_table.py``, as :func:`roughsense.predict` gives it)."""
    from .._util.atomic import write_text
    from ..model.predict_table import csv_text, text_table

    if out is None:
        typer.echo(_terminal_table(text_table(table), from_study=from_study))
    else:
        write_text(out, csv_text(table))
        typer.echo(f"wrote {counted(len(table), 'prediction')} to {out}")


def _terminal_table(table, *, from_study: bool) -> str:
    """The predictions for a terminal: columns that never change in a line above, a study's image paths left to
    --out (its specimen and repetition name each trial), and the rest wrapped to the terminal's width; then each
    surface's roughness and each distinct reason a trial lies outside the model's domain."""
    import shutil
    import textwrap

    from ..model.predict_table import CONSTANT_COLUMNS
    from ._common import terminal_table

    constant = [c for c in CONSTANT_COLUMNS if c in table.columns]
    firsts = {c: next((str(v) for v in table[c] if str(v)), "") for c in constant}  # a withheld row has none
    heading = ", ".join(f"{c.replace('_', ' ')} {firsts[c]}" for c in constant if firsts[c])
    dropped = constant + ([c for c in table.columns if c.startswith("image")] if from_study else [])
    surface = [c for c in table.columns if c.startswith("surface_")]
    dropped.append("outside")  # too long for a column: said below the table, once per distinct reason
    # the gate's and the orientation's columns are in --out's CSV; a withheld or turned row's reason is said below
    dropped.extend(c for c in ("orientation_deg", "contact_p", "withheld") if c in table.columns)
    if from_study:
        heading += "; each trial's images: add --out PRED.csv"
    width = shutil.get_terminal_size().columns
    body = terminal_table(table.drop(columns=dropped + surface))
    lines = [*textwrap.wrap(heading, width=width, subsequent_indent="  "), body] if heading else [body]
    if surface:
        key = "specimen" if "specimen" in table else None
        for name, rows in (table.groupby(key, sort=False) if key else [("surface", table)]):
            first = rows.iloc[0]
            interval = _surface_interval(first)
            label = f"surface {name}" if key else "the surface (every image: --same-surface)"
            lines.append(f"{label}: {first[surface[0]]}{interval}, mean of {counted(len(rows), 'trial')}")
    reasons = table["outside"][table["outside"].astype(bool)]
    for reason, count in reasons.value_counts().items():
        lines.extend(textwrap.wrap(f"outside what the model was trained on ({counted(int(count), 'trial')}): {reason}",
                                   width=width, subsequent_indent="  "))
    return "\n".join(lines)


def _surface_interval(row) -> str:
    """' (90 % interval a-b, method)' of a surface's row: the jackknife+ named by its residuals, the plain jackknife
    as such ('' without an interval)."""
    from ..model.model_intervals import PLAIN_METHOD

    if "surface_pi90_low" in row:
        return f" (90 % interval {row['surface_pi90_low']}-{row['surface_pi90_high']}, {row['surface_pi90_method']})"
    if "surface_jackknife90_low" in row:
        return f" (90 % interval {row['surface_jackknife90_low']}-{row['surface_jackknife90_high']}, {PLAIN_METHOD})"
    return ""


def _predict_live(loaded, source: str, max_frames: int | None, override=None) -> None:
    """Wire the model's scorer into the rig's live loop (the rig itself knows nothing of models)."""
    from ..model.scoring import frame_scorer
    from ..rig.live import live_scores, render_live

    summary = render_live(live_scores(source, frame_scorer(loaded, override), max_frames=max_frames))
    last = "none" if summary.last_score is None else f"{summary.last_score:.4f}"
    typer.echo(f"{summary.updates} update(s), {summary.updates_per_s:.1f}/s; last roughness {last}")
    if summary.extrapolated:
        why = f"; the last: {summary.reason}" if summary.reason else ""
        typer.echo(f"{summary.extrapolated} frame(s) extrapolated: outside what the model was trained on{why}")


def register(app: typer.Typer) -> None:
    app.command("predict", context_settings={"ignore_unknown_options": True})(predict)
