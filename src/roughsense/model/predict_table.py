"""The predict table: its columns (:data:`PREDICTION_COLUMNS`), built from a batch's scores as numbers
(:func:`prediction_table`) and written as text (:func:`text_table`, :func:`csv_text`, the CSV ``roughsense predict
--out`` writes).

:func:`roughsense.predict` and the CLI share these, so a script's table and the command's CSV cannot drift apart.
The text keeps 3 significant digits (the panel's own precision is coarser), ``true``/``false`` for flags (any CSV
reader's booleans) and the scale as typed (34.9, not 34.899999999999999).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

    from .modelfile import FittedModel
    from .scoring import Scores
    from .trials import Trials


#: Every column the table may hold, in its order, with what it says. ``<reference>`` is the model's reference
#: specimen and ``<condition>`` each force of a combined model; ``roi`` is there only when the ROI was overridden,
#: the interval columns only where the model file has an interval, the ``surface_*`` ones only for grouped presses.
#: One prediction carries one interval, named by its method: ``pi90_*`` is always the jackknife+ over specimens
#: (the interval with a coverage guarantee), ``jackknife90_*`` the plain jackknife (none), never both for one.
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
    "pi90_low": "the trial's 90 % prediction interval, the jackknife+ over specimens (its guarantee), lower bound",
    "pi90_high": "the trial's 90 % jackknife+ interval, upper bound",
    "pi90_method": "which residuals set that jackknife+ interval",
    "jackknife90_low": "in place of pi90_*: the plain jackknife's 90 % interval (no coverage guarantee; a press read "
                       "with its surface's others, or a file without the jackknife+), lower bound",
    "jackknife90_high": "the plain jackknife's 90 % interval, upper bound",
    "surface_roughness_rel_<reference>": "the surface's mean roughness over its trials",
    "surface_pi90_low": "the surface's 90 % jackknife+ interval, lower bound",
    "surface_pi90_high": "the surface's 90 % jackknife+ interval, upper bound",
    "surface_pi90_method": "which residuals set the surface's interval",
    "surface_jackknife90_low": "in place of surface_pi90_*: the plain jackknife's (no guarantee), lower bound",
    "surface_jackknife90_high": "the surface's plain jackknife 90 % interval, upper bound",
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


_INTERVAL_COLUMNS = ("pi90_low", "pi90_high", "jackknife90_low", "jackknife90_high", "surface_pi90_low",
                     "surface_pi90_high", "surface_jackknife90_low", "surface_jackknife90_high")
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


def prediction_table(loaded: FittedModel, trials: Trials, scores: Scores) -> pd.DataFrame:
    """One row per trial, as numbers: the columns of :data:`PREDICTION_COLUMNS` that apply, after ``trials.meta``'s
    (a study's specimen and repetition). Flags are booleans; roughness and bounds keep full precision."""
    import pandas as pd

    groups, override, surfaces = trials.groups, trials.override, trials.surfaces
    table = pd.DataFrame(index=range(len(groups))) if trials.meta is None else trials.meta.copy()
    if len(loaded.conditions) == 1:
        table["image"] = [str(t[0]) for t in groups]
    else:
        for i, condition in enumerate(loaded.conditions):
            table[f"image_{condition}"] = [str(t[i]) for t in groups]
    table["pad"] = trials.pad
    table["condition"] = trials.condition
    table["model"] = loaded.family
    table["passes_controls"] = controls_verdict(loaded)
    if override is not None and override.roi is not None:
        table["roi"] = roi_text(override.roi)
    scale = override.px_per_mm if override is not None and override.px_per_mm is not None else None
    table["px_per_mm"] = float(scale if scale is not None else loaded.model_file_.features["spectrum"]["px_per_mm"])
    name = roughness_column(loaded)
    table[name] = np.asarray(scores.roughness, dtype=float)
    withheld = np.zeros(len(groups), dtype=bool) if scores.withheld is None else scores.withheld
    if np.isfinite(scores.low[~withheld]).all() and not withheld.all():
        _interval_columns(table, "", scores.low, scores.high, scores.method)
    if scores.surface_roughness is not None:
        table[f"surface_{name}"] = scores.surface_roughness
        if np.isfinite(scores.surface_low[~withheld]).all() and not withheld.all():
            _interval_columns(table, "surface_", scores.surface_low, scores.surface_high, scores.surface_method)
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


def _interval_columns(table: pd.DataFrame, prefix: str, low, high, method) -> None:
    """One interval's columns, named by its method: ``pi90_*`` (with ``pi90_method``, which residuals) for the
    jackknife+ over specimens, ``jackknife90_*`` for the plain jackknife (model/model_intervals.py), so the plain
    one is never read as the guaranteed one."""
    from .model_intervals import PLAIN_METHOD

    if PLAIN_METHOD in set(method or ()):
        table[f"{prefix}jackknife90_low"], table[f"{prefix}jackknife90_high"] = low, high
        return
    table[f"{prefix}pi90_low"], table[f"{prefix}pi90_high"] = low, high
    table[f"{prefix}pi90_method"] = method


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
