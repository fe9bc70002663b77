"""``roughsense.predict``: perceived roughness of images with a model file, one row per trial, as ``roughsense
predict`` writes it; :func:`run_prediction` is the same call keeping its scores, for the CLI.

The chain reads top-down, each module calling only those below it (tests/model/test_predict.py): ``model/modelfile.py``
loads the model, ``model/trials.py`` groups what was given into trials, ``model/scoring.py`` scores them (reading,
gating, domain, intervals) and ``model/predict_table.py`` makes the table.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..errors import ConfigError

if TYPE_CHECKING:
    import pandas as pd

    from .modelfile import FittedModel
    from .reading import SensorOverride
    from .scoring import Scores
    from .trials import Trials


def predict(model, images: Sequence | None = None, *, study=None, specimens: Sequence[str] | None = None,
            images_by_force: Mapping[str, Sequence] | None = None, same_surface: bool = False, roi=None,
            px_per_mm: float | None = None, n_jobs: int = 1, progress=None) -> pd.DataFrame:
    """Perceived roughness of images, one row per trial: the table ``roughsense predict`` writes, as numbers.

    Each row holds the trial's roughness relative to the model's reference specimen, its 90 % interval where the
    model file keeps one, and whether (``extrapolates``) and how (``outside``) it lies outside what the model was
    trained on (``model/predict_table.py``'s ``PREDICTION_COLUMNS``; a ``withheld`` row has no roughness); its
    ``csv_text`` writes it as the CLI does. What the CLI says beside its table comes as a RoughsenseWarning.

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
    from .reading import SensorOverride

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


def _check_one_source(images, images_by_force, study, specimens) -> None:
    """Python's names in the refusal: the CLI has its own options and words for the same mistake."""
    given = [name for name, used in (("images", images), ("images_by_force", images_by_force),
                                     ("study", study is not None)) if used]
    if len(given) != 1:
        raise ConfigError("give images one way: images, images_by_force or study"
                          + (f" (got {' and '.join(given)})" if given else ""))
    if specimens and study is None:
        raise ConfigError("specimens selects from a study: pass study too")


@dataclass(frozen=True)
class PredictionRun:
    """What one prediction produced: the table, the scores behind it (the CLI's summary lines read them), the
    model that made them and the trials it read."""

    table: pd.DataFrame
    scores: Scores
    model: FittedModel
    trials: Trials


def run_prediction(model, images: Sequence | None = None, *, study=None, specimens: Sequence[str] = (),
                   images_by_force: Mapping[str, Sequence] | None = None, same_surface: bool = False,
                   override: SensorOverride | None = None, n_jobs: int = 1, progress=None,
                   note: Callable[[str], None] | None = None) -> PredictionRun:
    """:func:`predict`, keeping the scores; ``note`` hears the one line on which scale a study was read at."""
    from .modelfile import load_model
    from .predict_table import prediction_table
    from .scoring import score_trials
    from .trials import gather_trials

    loaded = load_model(model) if isinstance(model, (str, os.PathLike)) else model
    trials = gather_trials(loaded, images, study=study, specimens=specimens, images_by_force=images_by_force,
                           same_surface=same_surface, override=override)
    if trials.note and note is not None:
        note(trials.note)
    scores = score_trials(loaded, trials.images, n_jobs=n_jobs, progress=progress, override=trials.override,
                          surfaces=trials.surfaces, reference=trials.reference)
    return PredictionRun(prediction_table(loaded, trials, scores), scores, loaded, trials)


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
