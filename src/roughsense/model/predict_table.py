"""The predict table's one home: :func:`predict` scores images with a model file and returns one row per trial,
:func:`prediction_table` builds that table from scores (as numbers), and :func:`csv_text` writes it as
``roughsense predict --out`` does (as text).

The CLI and the Python call share these three, so a script's table and the command's CSV cannot drift apart.
The text keeps 3 significant digits (the panel's own precision is coarser), ``true``/``false`` for flags (any CSV
reader's booleans) and the scale as typed (34.9, not 34.899999999999999).
"""
from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ConfigError

if TYPE_CHECKING:
    import pandas as pd

    from .modelfile import FittedModel
    from .predict import Scores, SensorOverride

#: Every column the table may hold, in its order, with what it says. ``<reference>`` is the model's reference
#: specimen and ``<condition>`` each force of a combined model; ``roi`` is there only when the ROI was overridden,
#: the interval columns only where the model file has an interval, the ``surface_*`` ones only for grouped presses.
PREDICTION_COLUMNS: dict[str, str] = {
    "specimen": "with a study: the trial's specimen",
    "repetition": "with a study: the trial's repetition",
    "image": "a single-force model's image (image_<condition> per force of a combined model)",
    "pad": "the model's pad",
    "condition": "the model's force condition (1N, 2N, 3N or combined)",
    "model": "the model family",
    "passes_controls": "whether the model beat its controls for surfaces never seen (fit's check; '' if untested)",
    "roi": "where the line was read, when not the model's ROI",
    "px_per_mm": "the scale the images were read at",
    "roughness_rel_<reference>": "perceived roughness relative to the reference specimen",
    "pi90_low": "the trial's 90 % prediction interval, lower bound",
    "pi90_high": "the trial's 90 % prediction interval, upper bound",
    "pi90_method": "how that interval was built",
    "surface_roughness_rel_<reference>": "the surface's mean roughness over its trials",
    "surface_pi90_low": "the surface's 90 % prediction interval, lower bound",
    "surface_pi90_high": "the surface's 90 % prediction interval, upper bound",
    "surface_pi90_method": "how the surface's interval was built",
    "surface_extrapolates": "any press of the surface lies outside the model's domain",
    "orientation_deg": "the grating lines' angle from the image columns, degrees (flagged beyond +-6)",
    "read_as": "press (read alone) or surface (read with the other presses of its surface)",
    "contact_p": "the contact-image gate's p-value (empty for a model file without a gate)",
    "withheld": "no roughness given: not a contact image like the training presses, or unreadable (`outside` says why)",
    "extrapolates": "the trial lies outside what the model was trained on (every withheld trial does)",
    "outside": "how it lies outside, or why it is withheld ('' where it lies inside)",
}

#: Columns with one value for every row: the terminal shows them once, above the table.
CONSTANT_COLUMNS = ("pad", "condition", "model", "passes_controls", "roi", "px_per_mm", "read_as", "pi90_method")

_INTERVAL_COLUMNS = ("pi90_low", "pi90_high", "surface_pi90_low", "surface_pi90_high")
_QUIET = "this press lies inside; other presses of its surface do not (their rows say why)"


def roughness_column(loaded: FittedModel) -> str:
    """``roughness_rel_<reference>``: the column says what the number is a ratio to."""
    from ..io.names import is_safe_name

    reference = loaded.training.get("reference_specimen") if isinstance(loaded.training, dict) else None
    # a name no file may carry (an edited model file) still gives a column that says the value is relative
    return f"roughness_rel_{reference}" if is_safe_name(reference) else "roughness_rel_reference"


def controls_verdict(loaded: FittedModel) -> str:
    """'true' or 'false': whether the model beat its controls for surfaces never seen (fit's nested check); ''
    where its file does not say (written before the check, or a design too small for it)."""
    unseen = loaded.training.get("unseen") if isinstance(loaded.training, dict) else None
    verdict = unseen.get("passes_controls") if isinstance(unseen, dict) else None
    return "" if not isinstance(verdict, bool) else "true" if verdict else "false"


def roi_text(roi) -> str:
    """An ROI as a user would type it after --roi."""
    return roi if isinstance(roi, str) else ",".join(str(v) for v in roi)


def prediction_table(loaded: FittedModel, trials: Sequence[tuple], scores: Scores, *, meta: pd.DataFrame | None = None,
                     override: SensorOverride | None = None, surfaces=None) -> pd.DataFrame:
    """One row per trial, as numbers: the columns of :data:`PREDICTION_COLUMNS` that apply, after ``meta``'s (a
    study's specimen and repetition). Flags are booleans; roughness and bounds keep full precision."""
    import pandas as pd

    from .trials import model_condition, model_pad

    table = pd.DataFrame(index=range(len(trials))) if meta is None else meta.copy()
    if len(loaded.conditions) == 1:
        table["image"] = [str(t[0]) for t in trials]
    else:
        for i, condition in enumerate(loaded.conditions):
            table[f"image_{condition}"] = [str(t[i]) for t in trials]
    table["pad"] = model_pad(loaded)
    table["condition"] = model_condition(loaded)
    table["model"] = loaded.family
    table["passes_controls"] = controls_verdict(loaded)
    if override is not None and override.roi is not None:
        table["roi"] = roi_text(override.roi)
    scale = override.px_per_mm if override is not None and override.px_per_mm is not None else None
    table["px_per_mm"] = float(scale if scale is not None else loaded.model_file_.features["spectrum"]["px_per_mm"])
    name = roughness_column(loaded)
    table[name] = np.asarray(scores.roughness, dtype=float)
    withheld = np.zeros(len(trials), dtype=bool) if scores.withheld is None else scores.withheld
    if np.isfinite(scores.low[~withheld]).all() and not withheld.all():
        table["pi90_low"], table["pi90_high"] = scores.low, scores.high
        table["pi90_method"] = scores.method
    if scores.surface_roughness is not None:
        table[f"surface_{name}"] = scores.surface_roughness
        if np.isfinite(scores.surface_low[~withheld]).all() and not withheld.all():
            table["surface_pi90_low"], table["surface_pi90_high"] = scores.surface_low, scores.surface_high
            table["surface_pi90_method"] = scores.surface_method
    if surfaces is not None:  # a surface is flagged when any of its presses is
        flagged = pd.Series(scores.flagged).groupby(pd.Series(list(surfaces))).transform("any").to_numpy()
        table["surface_extrapolates"] = flagged.astype(bool)
    if scores.orientation_deg is not None:
        table["orientation_deg"] = scores.orientation_deg
    table["read_as"] = "press" if surfaces is None else "surface"
    if scores.withheld is not None:
        table["contact_p"] = scores.contact_p
        table["withheld"] = withheld
    table["extrapolates"] = scores.flagged
    table["outside"] = scores.reasons
    if "surface_extrapolates" in table:  # its surface's reason is in the other rows
        table.loc[table["surface_extrapolates"].to_numpy() & ~scores.flagged, "outside"] = _QUIET
    return table


def _three_digits(values) -> list[str]:
    """Values as text with 3 significant digits (written as is: a float column would print 1.23 as 1.2299...)."""
    return [f"{float(f'{v:.3g}'):g}" if np.isfinite(v) else "" for v in np.asarray(values, dtype=float)]  # 1234 -> 1230


def text_table(table: pd.DataFrame) -> pd.DataFrame:
    """:func:`prediction_table`'s table as the CSV and the terminal show it: every cell text."""
    text = table.copy()
    for column in table.columns:
        if column.startswith(("roughness_rel_", "surface_roughness_rel_")) or column in _INTERVAL_COLUMNS:
            text[column] = _three_digits(table[column])
        elif column in ("orientation_deg", "contact_p"):
            text[column] = [f"{v:.2g}" if column == "contact_p" and np.isfinite(v) else f"{v:.1f}" if np.isfinite(v)
                            else "" for v in table[column]]
        elif column == "px_per_mm":  # as written in study.toml or on the command line
            text[column] = [repr(float(v)) for v in table[column]]
        elif table[column].dtype == bool:
            text[column] = ["true" if flag else "false" for flag in table[column]]
    return text


def csv_text(table: pd.DataFrame) -> str:
    """The CSV ``roughsense predict --out`` writes, for :func:`prediction_table`'s (or :func:`predict`'s) table."""
    from .._util.text import spreadsheet_safe

    return spreadsheet_safe(text_table(table)).to_csv(index=False, lineterminator="\n", float_format="%.17g")


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


def study_scale(loaded: FittedModel, study, override: SensorOverride | None, meta: pd.DataFrame):
    """A study's images are read at its own study.toml scale unless ``override`` states one; the trials of
    specimens of stated period are marked for the scale check. Returns (override, reference, the note saying
    which scale was used, or '')."""
    from .predict import SensorOverride

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


@dataclass(frozen=True)
class PredictionRun:
    """What one prediction produced: the table, the scores behind it (the CLI's summary lines read them), the
    model that made them and the trials' surfaces (None when each press was read alone)."""

    table: pd.DataFrame
    scores: Scores
    model: FittedModel
    surfaces: object
    n_trials: int


def run_prediction(model, images: Sequence | None = None, *, study=None, specimens: Sequence[str] = (),
                   images_by_force: Mapping[str, Sequence] | None = None, same_surface: bool = False,
                   override: SensorOverride | None = None, n_jobs: int = 1, progress=None,
                   note: Callable[[str], None] | None = None) -> PredictionRun:
    """:func:`predict`, keeping the scores; ``note`` hears the one line on which scale a study was read at."""
    import pandas as pd

    from .modelfile import load_model
    from .predict import score_trials, warn_field_of_view
    from .trials import groups_from_flags, groups_from_images, groups_from_study

    loaded = load_model(model) if isinstance(model, (str, os.PathLike)) else model
    reference = None
    if study is not None:
        from ..io.study import read_study

        read = read_study(study) if isinstance(study, (str, os.PathLike)) else study
        trials, meta = groups_from_study(loaded, read, list(specimens or ()))
        override, reference, scale_note = study_scale(loaded, read, override, meta)
        if scale_note and note is not None:
            note(scale_note)
    else:
        if same_surface:
            refuse_repeats([*(images or ()), *(p for paths in (images_by_force or {}).values() for p in paths)])
        trials = (groups_from_flags(loaded, images_by_force) if images_by_force
                  else groups_from_images(loaded, list(images or ())))
        meta = pd.DataFrame(index=range(len(trials)))
    surfaces = meta["specimen"].astype(str).to_numpy() if "specimen" in meta else (
        ["surface"] * len(trials) if same_surface else None)
    flat = [image for trial in trials for image in trial]
    scores = score_trials(loaded, flat, n_jobs=n_jobs, progress=progress, override=override, surfaces=surfaces,
                          reference=reference)
    warn_field_of_view(loaded, override, flat)  # after scoring: an error there wins
    table = prediction_table(loaded, trials, scores, meta=meta, override=override, surfaces=surfaces)
    return PredictionRun(table, scores, loaded, surfaces, len(trials))


def predict(model, images: Sequence | None = None, *, study=None, specimens: Sequence[str] | None = None,
            images_by_force: Mapping[str, Sequence] | None = None, same_surface: bool = False, roi=None,
            px_per_mm: float | None = None, n_jobs: int = 1, progress=None) -> pd.DataFrame:
    """Perceived roughness of images, one row per trial: the table ``roughsense predict`` writes, as numbers.

    Each row holds the trial's roughness relative to the model's reference specimen, its 90 % interval where the
    model file keeps one, and whether (``extrapolates``) and how (``outside``) it lies outside what the model was
    trained on (:data:`PREDICTION_COLUMNS`; a ``withheld`` row has no roughness); :func:`csv_text` writes it as the CLI
    does. What the CLI says beside its table comes as a RoughsenseWarning.

    Parameters
    ----------
    model : str, os.PathLike or a loaded model
        A model file written by ``roughsense fit`` (or ``save_model``), or what ``load_model`` returned.
    images, images_by_force, study : optional, exactly one of them
        One image per trial (a single-force model); ``{"1N": [...], "2N": [...]}``, whose i-th images form trial i
        (a combined model); or a study folder (or read study), grouped into trials by its manifest (``specimens``:
        only these).
    same_surface : bool
        The images are presses of one surface: the peak law reads its period from all of them together, and the
        surface's mean roughness and interval are added.
    roi, px_per_mm : optional
        Where to read the line (``"center"``, ``"auto"``, ``"X,Y,W,H"`` px) and the images' scale, if not the model's.
    n_jobs, progress
        Images decoded at once; ``progress(iterable, total=, description=)`` wrapping the image stream.

    Returns
    -------
    pandas.DataFrame
        One row per trial.

    Examples
    --------
    A peak law fitted on square gratings of 2-5 mm, then two new surfaces, one far wider than any trained:

    >>> import numpy as np, cv2, roughsense as rs
    >>> from roughsense.model.modelfile import save_model
    >>> def grating(period_mm, name):
    ...     row = 128 + 100 * np.sign(np.sin(2 * np.pi * np.arange(1920) / 34.9 / period_mm))
    ...     return name if cv2.imwrite(name, np.tile(row, (160, 1)).astype(np.uint8)) else None
    >>> periods = np.repeat([2.0, 3.0, 4.0, 5.0], 2)
    >>> spectrum = rs.SpatialSpectrum().fit()
    >>> X = spectrum.transform([grating(p, f"train{i}.png") for i, p in enumerate(periods)])
    >>> law = rs.PeakPowerLaw(freq_per_mm=spectrum.freq_per_mm_).fit(X, (periods / 3) ** 0.9)
    >>> features = {"spectrum": spectrum.feature_definition(), "conditions": ["2N"]}
    >>> _ = save_model("law.json", law, feature_definition=features, training={"reference_specimen": "R3"})
    >>> table = rs.predict("law.json", [grating(2.5, "new_2N.png"), grating(8.0, "wide_2N.png")])
    >>> table[["image", "roughness_rel_R3", "extrapolates"]].round(2)
             image  roughness_rel_R3  extrapolates
    0   new_2N.png              0.85         False
    1  wide_2N.png              1.66          True
    """
    from .predict import SensorOverride

    model, images, study, specimens, images_by_force = _checked_arguments(
        model, images, study, specimens, images_by_force, same_surface, n_jobs, progress)
    run = run_prediction(model, images, study=study, specimens=specimens or (), images_by_force=images_by_force,
                         same_surface=same_surface, override=SensorOverride.parse(roi=roi, px_per_mm=px_per_mm),
                         n_jobs=n_jobs, progress=progress)
    return _warn_as_the_cli(run).table


def _checked_arguments(model, images, study, specimens, images_by_force, same_surface, n_jobs, progress):
    """Each of :func:`predict`'s arguments refused in one line naming it (``_util/arguments.py``); a str where a
    list is wanted is one path (one specimen). Returns model, images, study, specimens and images_by_force."""
    from .._util.arguments import callable_argument, flag_argument, jobs_argument, names_argument, path_argument, paths_argument

    if not hasattr(model, "model_file_"):
        path_argument(model, "model", "a model file or what load_model returned")
    if study is not None and not hasattr(study, "manifest"):
        path_argument(study, "study", "a study folder or what read_study returned")
    images = None if images is None else paths_argument(images, "images")
    if images_by_force is not None:
        if not isinstance(images_by_force, Mapping):
            raise ConfigError(f"images_by_force must be a mapping like {{'1N': [...], '2N': [...]}}, got "
                              f"{type(images_by_force).__name__}")
        images_by_force = {str(k): paths_argument(v, f"images_by_force[{k!r}]") for k, v in images_by_force.items()}
    specimens = None if specimens is None else names_argument(specimens, "specimens")
    flag_argument(same_surface, "same_surface")
    jobs_argument(n_jobs)
    callable_argument(progress)
    _check_one_source(images, images_by_force, study, specimens)
    return model, images, study, specimens, images_by_force


def _warn_as_the_cli(run: PredictionRun) -> PredictionRun:
    """What the CLI says beside its table, as warnings of roughsense's own class: a model that fails its controls,
    a model file without a gate, rows withheld."""
    import warnings

    from ..errors import RoughsenseWarning
    from .press_gate import NO_GATE_LINE

    unseen = run.model.training.get("unseen") if isinstance(run.model.training, dict) else None
    failure = unseen.get("failure") if isinstance(unseen, dict) else None
    if isinstance(failure, str) and failure:
        warnings.warn(RoughsenseWarning(failure), stacklevel=3)
    if not run.scores.gated:
        warnings.warn(RoughsenseWarning(NO_GATE_LINE), stacklevel=3)
    count = int(run.scores.withheld.sum()) if run.scores.withheld is not None else 0
    if count:
        warnings.warn(RoughsenseWarning(f"{count} of {len(run.scores.withheld)} rows withheld (no roughness: not a "
                                        "contact image like the model's training presses, or unreadable; the "
                                        "`outside` column says why)"), stacklevel=3)
    return run


def _check_one_source(images, images_by_force, study, specimens) -> None:
    """Python's names in the refusal: the CLI has its own options and words for the same mistake."""
    given = [name for name, used in (("images", images), ("images_by_force", images_by_force),
                                     ("study", study is not None)) if used]
    if len(given) != 1:
        raise ConfigError("give images one way: images, images_by_force or study"
                          + (f" (got {' and '.join(given)})" if given else ""))
    if specimens and study is None:
        raise ConfigError("specimens selects from a study: pass study too")
