"""Peak-law model files: the model section of kind :data:`KIND`, written from a fitted law and checked on reading.

The section beside the document's ``features`` (whose spectrum holds the frequency grid the peak is read on)::

    {"kind": KIND, "n_features": p, "n_blocks": B, "pad_ridge_period_mm": 1.0 | null,
     "exclusion_per_mm": e, "epsilon": h, "intercept": b0, "coefficients": [b1, 0, b3], "scale": s,
     "feature_min": [3], "feature_max": [3], "feature_names": ["log_peak_frequency_per_mm", "log_peak_amplitude",
     "log_second_harmonic_ratio"], "clarity_limit": c, "press_scatter": {"spread": [4], "trained_presses": k}}

A coefficient of 0 is a feature that is no term of the law (the amplitude always; the harmonic ratio where a
training surface did not show it), and such a harmonic ratio's range is null (unbounded). A file written before the
harmonic ratio existed has two of each and loads as a law without it.

``feature_min``/``feature_max`` are the range of the rows the fit kept and ``clarity_limit`` the least clear peak it
accepts (:func:`~roughsense.model.readout_domain.domain_reasons`); a file written before ``clarity_limit`` existed loads
without it, and its predictions are then not checked for a clear peak. ``press_scatter`` is the training presses'
scatter about their surfaces (log frequency, log amplitude, harmonic ratio, clarity) and the presses per trained
surface (model/press_spread.py), which widen the flag for a surface read from fewer presses; a file without it
flags on the surface margins alone.

Why each field is bounded. The checksum of a model file is unkeyed, so anyone can edit a number and re-sign it: the
field checks are what refuse a file that would predict nonsense. The bounds are loose enough for any law fitted on
real spectra (log features of a few units, slopes of a few units) and tight enough that every prediction stays a
finite positive number: a law whose exponent could leave floating point anywhere in its feature box is refused.
A loaded law is the fitted :class:`~roughsense.model.peak_law.law.PeakPowerLaw` itself, its fitted attributes set
from the section, so it predicts with the estimator's own code.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..._util.checks import POSITIVE_INT, Constraint, Real, shown
from ...errors import ModelFileError
from ...sensor.grid import grid_step
from .. import schema
from ..loaded import ModelFileInfo
from ..peak_search import FEATURE_NAMES, HARMONIC, search_bins
from ..readout_domain import domain_margins
from ..readout_file import (
    BOUNDED,
    CLARITY_LIMIT,
    EXCLUSION,
    LIMIT,
    PAD_PERIOD,
    PRESS_SCATTER_SCHEMA,
    bounded,
    check_log_frequencies,
    press_scatter,
    spectrum_grid,
)
from .law import PeakPowerLaw

KIND = "peak-power-law"
#: |log roughness| the law may reach anywhere in its feature box: predictions between 1e-6 and 1e6, the bound of a
#: rating (``io.numbers.BOUNDS``) and of a PLS file's values; a re-signed law predicting 9e303 is refused.
_MAX_LOG_ROUGHNESS = math.log(1e6)
_SCALARS: dict[str, Constraint] = {
    "exclusion_per_mm": EXCLUSION,
    "epsilon": Real(0.0, 100.0, low_open=True),
    "intercept": BOUNDED,
    "scale": Real(0.0, LIMIT, low_open=True),
}
_PAIRS = ("coefficients", "feature_min", "feature_max")
FIELDS = ("kind", "n_features", "n_blocks", "pad_ridge_period_mm", *_SCALARS, *_PAIRS, "feature_names")
#: Fields a file may lack (written before they existed).
OPTIONAL_FIELDS = ("clarity_limit", "press_scatter")


_PAIR = {"type": "array", "minItems": 2, "maxItems": len(FEATURE_NAMES)}
#: The law's section, as JSON Schema (model/schema.py): checked after the code above has checked it field by field,
#: so this states the whole section in one place and catches what no message above names.
SCHEMA = schema.strict({
    "kind": {"const": KIND},
    "n_features": schema.integer(1, None),
    "n_blocks": schema.integer(1, None),
    "pad_ridge_period_mm": bounded(PAD_PERIOD, null=True),
    **{name: bounded(constraint) for name, constraint in _SCALARS.items()},
    "coefficients": {**_PAIR, "items": bounded(BOUNDED)},
    "feature_min": {**_PAIR, "items": bounded(BOUNDED, null=True)},
    "feature_max": {**_PAIR, "items": bounded(BOUNDED, null=True)},
    "feature_names": {"type": "array", "items": {"enum": list(FEATURE_NAMES)}, "uniqueItems": True},
    "clarity_limit": bounded(CLARITY_LIMIT),
    "press_scatter": PRESS_SCATTER_SCHEMA,
}, required=FIELDS)
def law_section(model: PeakPowerLaw) -> dict:
    """The ``"model"`` section of a fitted law (floats written with repr, so they read back bit-identically)."""
    if not hasattr(model, "coef_"):
        raise ModelFileError("the model is not fitted")
    period = model.pad_ridge_period_mm
    return {
        "kind": KIND,
        "n_features": int(model.n_features_in_),
        "n_blocks": int(model.n_blocks),
        "pad_ridge_period_mm": None if period is None else float(period),
        "exclusion_per_mm": float(model.exclusion_per_mm),
        "epsilon": float(model.epsilon),
        "intercept": float(model.intercept_),
        "coefficients": [float(v) for v in model.coef_],
        "scale": float(model.scale_),
        "feature_min": [float(v) if math.isfinite(v) else None for v in model.feature_min_],
        "feature_max": [float(v) if math.isfinite(v) else None for v in model.feature_max_],
        "feature_names": list(FEATURE_NAMES),
        "clarity_limit": float(model.clarity_limit_),
        **({} if model.press_scatter_ is None else {"press_scatter": model.press_scatter_.to_dict()}),
    }


def check_fields(section: dict, path: Path | None) -> int:
    """Exactly the law's fields, and a usable feature count (returned: the feature definition is checked on it)."""
    missing = [name for name in FIELDS if name not in section]
    if missing:
        raise ModelFileError(f"the peak-law model lacks the field(s) {', '.join('model.' + m for m in missing)}",
                             path=path)
    unknown = sorted(set(section) - set(FIELDS) - set(OPTIONAL_FIELDS))
    if unknown:
        raise ModelFileError(f"the peak-law model has unknown field(s) {', '.join('model.' + str(u) for u in unknown)}",
                             path=path)
    return _checked(section, "n_features", POSITIVE_INT, path)


def loaded_law(section: dict, features: dict, *, training: dict, roughsense_version: str,
               path: Path | None) -> PeakPowerLaw:
    """Check every field of a law's section (``features`` already checked against ``n_features``) and load it."""
    n_blocks = _checked(section, "n_blocks", POSITIVE_INT, path)
    if n_blocks != len(features["conditions"]):
        raise ModelFileError(f"model.n_blocks is {n_blocks}, but the feature definition has "
                             f"{len(features['conditions'])} force condition(s)", path=path)
    period = section["pad_ridge_period_mm"]
    if period is not None:
        period = _checked(section, "pad_ridge_period_mm", PAD_PERIOD, path,
                          must=f"a number of mm from {PAD_PERIOD.low:g} to {PAD_PERIOD.high:g}, or null")
    scalars = {name: _checked(section, name, constraint, path) for name, constraint in _SCALARS.items()}
    names = section["feature_names"]
    if names not in (list(FEATURE_NAMES), list(FEATURE_NAMES[:2])):
        raise ModelFileError(f"model.feature_names must be {list(FEATURE_NAMES)}, got {shown(names)}", path=path)
    pairs = {name: _pair(section, name, path, len(names)) for name in _PAIRS}
    if np.any(pairs["feature_min"] > pairs["feature_max"]):
        raise ModelFileError("model.feature_min exceeds model.feature_max: the training range is empty", path=path)
    freq = spectrum_grid(features["spectrum"], path)
    check_log_frequencies([pairs["feature_min"][0], pairs["feature_max"][0]], freq,
                           "model.feature_min[0] and model.feature_max[0]", path)
    try:
        search_bins(freq, period, scalars["exclusion_per_mm"])
    except ValueError as exc:
        raise ModelFileError(f"model.pad_ridge_period_mm and model.exclusion_per_mm: {exc}", path=path) from None
    step = grid_step(freq)  # predictions reach the domain's widened edges
    low, high = domain_margins(step, pairs["feature_min"], pairs["feature_max"])
    _check_finite_predictions(scalars["intercept"], {**pairs, "feature_min": low, "feature_max": high}, path)
    clarity = _checked(section, "clarity_limit", CLARITY_LIMIT, path) if "clarity_limit" in section else None
    law = PeakPowerLaw(freq_per_mm=freq, n_blocks=n_blocks, pad_ridge_period_mm=period,
                       exclusion_per_mm=scalars["exclusion_per_mm"], epsilon=scalars["epsilon"])
    law.freq_per_mm_, law.n_features_in_ = freq, n_blocks * freq.size
    law.intercept_, law.coef_, law.scale_ = scalars["intercept"], pairs["coefficients"], scalars["scale"]
    law.feature_min_, law.feature_max_, law.clarity_limit_ = pairs["feature_min"], pairs["feature_max"], clarity
    law.press_scatter_ = press_scatter(section, "model", freq, path)
    law.model_file_ = ModelFileInfo(path, features, training, roughsense_version)
    return law


def _checked(section: dict, name: str, constraint: Constraint, path: Path | None, *, must: str | None = None):
    value = section[name]
    if not constraint.accepts(value):
        raise ModelFileError(f"model.{name} must be {must or constraint.describe()}, got {shown(value)}", path=path)
    return int(value) if constraint is POSITIVE_INT else float(value)


def _pair(section: dict, name: str, path: Path | None, length: int) -> np.ndarray:
    """One number per feature; the harmonic ratio's range may be null (unbounded: no term). A two-feature file
    (before the harmonic ratio) gains it as no term."""
    values = section[name]
    if not isinstance(values, list) or len(values) != length:
        raise ModelFileError(f"model.{name} must be a list of {length} numbers, got {shown(values)}", path=path)
    unbounded = {"feature_min": -np.inf, "feature_max": np.inf}.get(name)
    out = []
    for i, value in enumerate(values):
        if value is None and unbounded is not None and i == HARMONIC:
            out.append(unbounded)
        elif BOUNDED.accepts(value):
            out.append(float(value))
        else:
            raise ModelFileError(f"model.{name}[{i}] must be {BOUNDED.describe()}, got {shown(value)}", path=path)
    if length < len(FEATURE_NAMES):
        out.append({"feature_min": -np.inf, "feature_max": np.inf}.get(name, 0.0))
    return np.array(out, dtype=np.float64)


def _check_finite_predictions(intercept: float, pairs: dict, path: Path | None) -> None:
    """The law's exponent at the corners of its feature box (its extremes, as it is linear) stays in range."""
    used = pairs["coefficients"] != 0  # a feature that is no term may have an unbounded range
    if not np.all(np.isfinite(pairs["feature_min"][used]) & np.isfinite(pairs["feature_max"][used])):
        raise ModelFileError("model.feature_min and model.feature_max must be numbers for every feature with a "
                             "coefficient", path=path)
    corners = np.column_stack([pairs["feature_min"][used], pairs["feature_max"][used]]) * \
        pairs["coefficients"][used][:, None]
    highest = intercept + float(corners.max(axis=1).sum())
    lowest = intercept + float(corners.min(axis=1).sum())
    if not (math.isfinite(highest) and math.isfinite(lowest)) or max(abs(highest), abs(lowest)) > _MAX_LOG_ROUGHNESS:
        raise ModelFileError(
            f"model.intercept and model.coefficients give log roughness from {lowest:.4g} to {highest:.4g} over the "
            f"training range; a prediction must stay within 1e-6 to 1e6", path=path)


