"""``roughsense fit``: a model (the peak law, or the paper's PLS1) from a study, with its CV, how the study judges
it for new surfaces, and the interval and domain it records for ``roughsense predict``."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from .. import defaults
from .._util.text import counted
from ..model.registry import model_help
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
    help=f"Largest number of PLS components to cross-validate. Default: {defaults.MAX_COMPONENTS}, or fewer if the "
         "data support fewer. PLS only.",
)]
CV = Annotated[str, typer.Option(
    "--cv", help="Cross-validation: loo (the paper's leave-one-out), loso (leave one specimen out) or K (shuffled K-fold).")]
Rule = Annotated[str | None, typer.Option(
    "--rule", show_default=False,
    help="PLS component choice: min (lowest CV RMSE, the paper's rule; the default) or 1se (fewest within one SE "
         "of it).")]
ModelName = Annotated[str | None, typer.Option("--model", help=model_help(), show_default=False)]
FitSeed = Annotated[int, typer.Option(
    "--seed", parser=number_option("--seed", quantity="seed"),
    help="Seed for the K-fold shuffle (LOO and LOSO use no randomness), the presses drawn for the interval's "
         "residuals of 1-, 3- and 5-press surfaces, and --study builtin.")]
FitRoi = Annotated[str | None, typer.Option(
    "--roi", show_default=False,
    help=f"Crop where the line is read: 'center' ({defaults.CENTER_CROP_PX[0]}x{defaults.CENTER_CROP_PX[1]} px "
         f"centred, as in the paper), 'auto' (the {defaults.CENTER_CROP_PX[1]}-row band "
         "with the most horizontal texture) or X,Y,W,H in px. Default: the study's [sensor] roi. Stored in the "
         "model file, so predict reads its images the same way.")]


def fit(study: StudyDir, pad: Pad, condition: Condition, out: ModelOut, max_components: MaxComponents = None,
        cv: CV = "loo", rule: Rule = None, seed: FitSeed = defaults.SEED, jobs: Jobs = None,
        model: ModelName = None,
        force: Annotated[bool, typer.Option("--force", help="Replace MODEL.json if it exists.")] = False,
        roi: FitRoi = None) -> None:
    """Fit a model for one pad and force condition: by default the peak law, or the groove model where the study's
    rectangles vary land against groove at a period; or the paper's PLS1 (SIMPLS, X centred).

    Use the default to score surfaces you never trained on, of the kinds the study's specimens cover (its report
    names their shapes, periods and land widths); use --model pls to reproduce the paper.
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
    from ..model.predict_table import roi_text
    from ..model.reading import SensorOverride

    condition = parse_condition(condition)
    check_training_options(condition, rule, max_components, model)
    override = SensorOverride.parse(roi=roi)
    scheme = parse_cv(cv)
    check_seed(seed)
    check_can_write(out, force=force, inputs=run_inputs(study=study))
    study = resolve_study(study, seed=seed, jobs=None if jobs < 1 else jobs)
    loaded, scale = checked_scale(read_study(study, require_ratings=True), pad=pad)
    trained = train_model(loaded, pad=pad, condition=condition, cv=scheme, rule=rule, seed=seed,
                          max_components=max_components, study_path=str(study), n_jobs=jobs, progress=progress,
                          model=model, roi=None if override is None else override.roi)
    save_model(out, trained.model, feature_definition=trained.feature_definition,
               training={**trained.training, "scale_check": scale}, force=force)
    typer.echo(f"{loaded.name}: pad {pad}, {condition}, {counted(trained.n_samples, 'sample')} x "
               f"{counted(trained.n_features, 'feature')}, {trained.cv.scheme} CV, model {trained.family}")
    if override is not None:
        typer.echo(f"line read at --roi {roi_text(override.roi)} (the study's [sensor] roi: "
                   f"{roi_text(loaded.sensor.roi)})")
    _echo_cv(trained)
    _echo_unseen(trained.unseen)
    typer.echo(f"wrote {out}")
    _echo_gate(trained.training)
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
    from ..report.control_tables import permutation_p_text

    text = permutation_p_text(p, n_permutations, at_most="<=")
    return text if text.startswith("<=") or text == "—" else f"= {text}"


def _echo_gate(training) -> None:
    """One line on the contact-image gate predict will apply: its presses, specimens and false-alarm rate."""
    from ..model.gate_file import KEY, loaded_gate

    gate = loaded_gate(training.get(KEY), None)
    if gate is None:
        return
    n, groups = gate.calibration.size, gate.locations.shape[0]
    line = (f"contact-image gate: {n} training presses of {groups} specimens, calibrated over specimens; predict "
            f"withholds a press at p <= {gate.alpha:g}")
    if not gate.can_reach_alpha:
        line += (f" (too few presses for that test: {math.ceil(1 / gate.alpha) - 1} are needed; only presses far "
                 "outside the training ranges are withheld)")
    typer.echo(line)


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
    """The family's CV table and its lines (PLS: the curve and the chosen count; the peak law: its CV beside the
    training mean's, and the law)."""
    from ..model.registry import engine
    from ._common import terminal_table

    table, lines = engine(trained.family).fit_report(trained)
    typer.echo(terminal_table(table, float_format=lambda v: f"{v:.5f}"))
    for line in lines:
        typer.echo(line)


def parse_condition(text: str) -> str:
    """A --condition as typed, in the form the study and model files use: "2n" -> "2N", "Combined" -> "combined"."""
    value = text.strip()
    return value.lower() if value.lower() == "combined" else value.upper()


def register(app: typer.Typer) -> None:
    app.command("fit")(fit)
