"""Peak-law model files: the ``"peak-power-law"`` model section, written from a fitted law and checked on reading.

The section beside the document's ``features`` (whose spectrum holds the frequency grid the peak is read on)::

    {"kind": "peak-power-law", "n_features": p, "n_blocks": B, "pad_ridge_period_mm": 1.0 | null,
     "exclusion_per_mm": e, "epsilon": h, "intercept": b0, "coefficients": [b1, b2, b3], "scale": s,
     "feature_min": [3], "feature_max": [3], "feature_names": ["log_peak_frequency_per_mm", "log_peak_amplitude",
     "log_second_harmonic_ratio"], "clarity_limit": c, "press_scatter": {"spread": [4], "trained_presses": k}}

A coefficient of 0 is a feature that is no term of the law (the amplitude always; the harmonic ratio where a
training surface did not show it), and such a harmonic ratio's range is null (unbounded). A file written before the
harmonic ratio existed has two of each and loads as a law without it.

``feature_min``/``feature_max`` are the range of the rows the fit kept and ``clarity_limit`` the least clear peak it
accepts (:func:`~roughsense.model.peak_law.domain_reasons`); a file written before ``clarity_limit`` existed loads
without it, and its predictions are then not checked for a clear peak. ``press_scatter`` is the training presses'
scatter about their surfaces (log frequency, log amplitude, harmonic ratio, clarity) and the presses per trained
surface (model/press_spread.py), which widen the flag for a surface read from fewer presses; a file without it
flags on the surface margins alone.

Why each field is bounded. The checksum of a model file is unkeyed, so anyone can edit a number and re-sign it: the
field checks are what refuse a file that would predict nonsense. The bounds are loose enough for any law fitted on
real spectra (log features of a few units, slopes of a few units) and tight enough that every prediction stays a
finite positive number: a law whose exponent could leave floating point anywhere in its feature box is refused.
A loaded law is the fitted :class:`~roughsense.model.peak_law.PeakPowerLaw` itself, its fitted attributes set
from the section, so it predicts with the estimator's own code.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .._util.checks import POSITIVE_INT, Constraint, Real, shown
from ..errors import ModelFileError
from ..io.numbers import BOUNDS
from ..sensor.grid import grid_step
from . import schema
from .loaded import ModelFileInfo
from .peak_law import (
    FEATURE_NAMES,
    HARMONIC,
    LOG_MARGIN,
    PeakPowerLaw,
    check_grid,
    domain_margins,
    search_bins,
)
from .peak_search import AGREEMENT_BINS
from .press_spread import MAD_PER_SD, N_SPREAD, PressScatter

KIND = "peak-power-law"
#: Largest magnitude of the law's numbers and of its features' range (log units; real fits are a few units).
LIMIT = 1e3
_BOUNDED = Real(-LIMIT, LIMIT)
#: |log roughness| the law may reach anywhere in its feature box: predictions between 1e-6 and 1e6, the bound of a
#: rating (``io.numbers.BOUNDS``) and of a PLS file's values; a re-signed law predicting 9e303 is refused.
_MAX_LOG_ROUGHNESS = math.log(1e6)
#: A clarity limit: the least clear trained peak (a log height above the band's median, so >= 0) less LOG_MARGIN; a
#: peak e^50 times its band's median is beyond any 8- or 16-bit image, so a limit above 50 would refuse everything.
CLARITY_LIMIT = Real(-LOG_MARGIN, 50.0)
_SCALARS: dict[str, Constraint] = {
    "exclusion_per_mm": Real(0.0, 10.0, low_open=True),
    "epsilon": Real(0.0, 100.0, low_open=True),
    "intercept": _BOUNDED,
    "scale": Real(0.0, LIMIT, low_open=True),
}
#: A pad's ridge period: the range study.toml accepts (``io.numbers.BOUNDS``), so a law a study can train is loadable.
_PAD_PERIOD = Real(BOUNDS["ridge_period_mm"].low, BOUNDS["ridge_period_mm"].high)
_PAIRS = ("coefficients", "feature_min", "feature_max")
FIELDS = ("kind", "n_features", "n_blocks", "pad_ridge_period_mm", *_SCALARS, *_PAIRS, "feature_names")
#: Fields a file may lack (written before they existed).
OPTIONAL_FIELDS = ("clarity_limit", "press_scatter")
#: One number of the training presses' scatter (log units, >= 0; each column's limit is :func:`spread_limits`).
_SPREAD = Real(0.0)


#: A loaded peak-law file is the fitted estimator: the old name, kept for one release.
LoadedPeakLaw = PeakPowerLaw


def _bounded(constraint: Real, *, null: bool = False, **more) -> dict:
    """A :class:`Real` constraint of this module as a JSON Schema node (the same bounds, one home)."""
    node = schema.number(constraint.low, constraint.high, null=null, **more)
    if constraint.low_open:
        node["exclusiveMinimum"] = node.pop("minimum")
    return node


_PAIR = {"type": "array", "minItems": 2, "maxItems": len(FEATURE_NAMES)}
#: The press scatter (model/press_spread.py); each spread's limit, which depends on the grid, is checked in code.
PRESS_SCATTER_SCHEMA = schema.strict({
    "spread": {"type": "array", "items": schema.number(0.0), "minItems": N_SPREAD, "maxItems": N_SPREAD},
    "trained_presses": schema.number(1.0, BOUNDS["repetition"].high),
}, required=("spread", "trained_presses"))
#: The law's section, as JSON Schema (model/schema.py): checked after the code above has checked it field by field,
#: so this states the whole section in one place and catches what no message above names.
SCHEMA = schema.strict({
    "kind": {"const": KIND},
    "n_features": schema.integer(1, None),
    "n_blocks": schema.integer(1, None),
    "pad_ridge_period_mm": _bounded(_PAD_PERIOD, null=True),
    **{name: _bounded(constraint) for name, constraint in _SCALARS.items()},
    "coefficients": {**_PAIR, "items": _bounded(_BOUNDED)},
    "feature_min": {**_PAIR, "items": _bounded(_BOUNDED, null=True)},
    "feature_max": {**_PAIR, "items": _bounded(_BOUNDED, null=True)},
    "feature_names": {"type": "array", "items": {"enum": list(FEATURE_NAMES)}, "uniqueItems": True},
    "clarity_limit": _bounded(CLARITY_LIMIT),
    "press_scatter": PRESS_SCATTER_SCHEMA,
}, required=FIELDS)
#: A PLS file's peak readout domain (``model.applicability.peak``), as JSON Schema.
PEAK_DOMAIN_SCHEMA = schema.strict({
    "log_frequency_range": {"type": "array", "items": _bounded(_BOUNDED), "minItems": 2, "maxItems": 2},
    "clarity_limit": _bounded(CLARITY_LIMIT),
    "pad_ridge_period_mm": _bounded(_PAD_PERIOD, null=True),
    "exclusion_per_mm": _bounded(_SCALARS["exclusion_per_mm"]),
    "harmonic_range": {"type": "array", "items": _bounded(_BOUNDED, null=True), "minItems": 2, "maxItems": 2},
    "press_scatter": PRESS_SCATTER_SCHEMA,
}, required=("log_frequency_range", "clarity_limit", "pad_ridge_period_mm", "exclusion_per_mm"))


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
        period = _checked(section, "pad_ridge_period_mm", _PAD_PERIOD, path,
                          must=f"a number of mm from {_PAD_PERIOD.low:g} to {_PAD_PERIOD.high:g}, or null")
    scalars = {name: _checked(section, name, constraint, path) for name, constraint in _SCALARS.items()}
    names = section["feature_names"]
    if names not in (list(FEATURE_NAMES), list(FEATURE_NAMES[:2])):
        raise ModelFileError(f"model.feature_names must be {list(FEATURE_NAMES)}, got {shown(names)}", path=path)
    pairs = {name: _pair(section, name, path, len(names)) for name in _PAIRS}
    if np.any(pairs["feature_min"] > pairs["feature_max"]):
        raise ModelFileError("model.feature_min exceeds model.feature_max: the training range is empty", path=path)
    freq = _grid(features["spectrum"], path)
    _check_log_frequencies([pairs["feature_min"][0], pairs["feature_max"][0]], freq,
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


def press_scatter(section: dict, where: str, freq: np.ndarray, path: Path | None) -> PressScatter | None:
    """The section's ``press_scatter`` ({"spread": 4 numbers >= 0, "trained_presses": a count >= 1}), or None where
    the file predates it (or the law was fitted without surfaces); each spread within :func:`spread_limits`."""
    if "press_scatter" not in section:
        return None
    value = section["press_scatter"]
    spread = value.get("spread") if isinstance(value, dict) else None
    count = value.get("trained_presses") if isinstance(value, dict) else None
    if not isinstance(value, dict) or set(value) != {"spread", "trained_presses"} or not isinstance(spread, list) \
            or len(spread) != N_SPREAD or not all(_SPREAD.accepts(v) for v in spread) \
            or not Real(1.0, BOUNDS["repetition"].high).accepts(count):
        raise ModelFileError(f"{where}.press_scatter must be {{\"spread\": {N_SPREAD} numbers >= 0, \"trained_presses\": "
                             f"a count of presses >= 1}}, got {shown(value)}", path=path)
    for i, (number, limit) in enumerate(zip(spread, spread_limits(freq))):
        if number > limit:
            raise ModelFileError(f"{where}.press_scatter.spread[{i}] is {shown(number)}; a fit gives at most "
                                 f"{limit:.4g} (robust SD of {SPREAD_NAMES[i]})", path=path)
    return PressScatter(np.array(spread, dtype=np.float64), float(count))


#: What each spread is the robust SD of (model/press_spread.py).
SPREAD_NAMES = ("a press's log peak frequency", "its log peak amplitude", "its second-harmonic ratio",
                "its peak's clarity")


def spread_limits(freq: np.ndarray) -> np.ndarray:
    """The largest spread a fit gives, per column: the robust SD is the median absolute deviation of every training
    press from its surface's reading, / 0.6745. A press that agrees with its surface on where the peak is (within
    AGREEMENT_BINS bins, as a surface's presses must mostly agree for its reading to stand) reads a log frequency
    within log(1 + AGREEMENT_BINS step / (f_lowest - step / 2)) of it, so a median over presses most of which agree
    lies within that (0.44 on the default grid; real spreads: 0.01-0.05). The amplitude, shape and clarity are log
    heights of one 8- or 16-bit image's spectrum, which differ by less than CLARITY_LIMIT's e^50 (an edited spread
    of 1000 would switch every flag off)."""
    step = grid_step(freq)
    lowest = float(freq[0]) - 0.5 * step if freq.size > 1 else float(freq[0])
    period = math.log1p(AGREEMENT_BINS * step / max(lowest, 1e-12)) / MAD_PER_SD
    heights = CLARITY_LIMIT.high / MAD_PER_SD
    return np.array([period, heights, heights, heights])


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
        elif _BOUNDED.accepts(value):
            out.append(float(value))
        else:
            raise ModelFileError(f"model.{name}[{i}] must be {_BOUNDED.describe()}, got {shown(value)}", path=path)
    if length < len(FEATURE_NAMES):
        out.append({"feature_min": -np.inf, "feature_max": np.inf}.get(name, 0.0))
    return np.array(out, dtype=np.float64)


def _grid(spectrum: dict, path: Path | None) -> np.ndarray:
    """The spectrum's frequencies (mm^-1): the grid the peak is located on, so it must be a real, even grid."""
    freq = spectrum.get("freq_per_mm")
    n_freqs = spectrum["n_freqs"]
    if not isinstance(freq, list) or len(freq) != n_freqs or not all(Real(0.0, LIMIT, low_open=True).accepts(f)
                                                                     for f in freq):
        raise ModelFileError(f"features.spectrum.freq_per_mm must be {n_freqs} positive frequencies (mm^-1)", path=path)
    try:
        return check_grid(freq, min_bins=1)  # the estimator's own rule for a grid the peak can be located on
    except ValueError:
        raise ModelFileError("features.spectrum.freq_per_mm must be evenly spaced and increasing", path=path) from None


def _check_log_frequencies(values, freq: np.ndarray, where: str, path: Path | None) -> None:
    """A peak is read on the grid (to within half a bin), so a stored log peak frequency outside the grid's range
    is no fitted value; refused here, before the domain's margins divide by exp() of it and overflow."""
    step = grid_step(freq)
    low = math.log(max(float(freq[0]) - step, 0.5 * float(freq[0])))
    high = math.log(float(freq[-1]) + step)
    if not all(low <= float(v) <= high for v in values):
        raise ModelFileError(f"{where} (log peak frequency) must lie within the grid's {low:.4g} to {high:.4g}, got "
                             f"{shown([float(v) for v in values])}", path=path)


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


def peak_domain(section, features: dict, path: Path | None):
    """A PLS file's peak readout domain (``model.applicability.peak``), checked like the law's own fields."""
    from .applicability import PeakDomain

    where = "model.applicability.peak"
    fields = {"log_frequency_range", "clarity_limit", "pad_ridge_period_mm", "exclusion_per_mm"}
    if not isinstance(section, dict) or set(section) - {"harmonic_range", "press_scatter"} != fields:
        raise ModelFileError(f"{where} must have exactly the fields log_frequency_range, clarity_limit, "
                             "pad_ridge_period_mm, exclusion_per_mm (and harmonic_range, press_scatter)", path=path)
    harmonic = section.get("harmonic_range", [None, None])
    if not isinstance(harmonic, list) or len(harmonic) != 2 or not all(v is None or _BOUNDED.accepts(v)
                                                                       for v in harmonic):
        raise ModelFileError(f"{where}.harmonic_range must be two numbers or nulls, got {shown(harmonic)}", path=path)
    harmonic = (-np.inf if harmonic[0] is None else float(harmonic[0]),
                np.inf if harmonic[1] is None else float(harmonic[1]))
    span = section["log_frequency_range"]
    if not isinstance(span, list) or len(span) != 2 or not all(_BOUNDED.accepts(v) for v in span) or span[0] > span[1]:
        raise ModelFileError(f"{where}.log_frequency_range must be two increasing numbers, got {shown(span)}",
                             path=path)
    period = section["pad_ridge_period_mm"]
    if period is not None and not _PAD_PERIOD.accepts(period):
        raise ModelFileError(f"{where}.pad_ridge_period_mm must be {_PAD_PERIOD.describe()} or null", path=path)
    for name in ("clarity_limit", "exclusion_per_mm"):
        constraint = CLARITY_LIMIT if name == "clarity_limit" else _SCALARS["exclusion_per_mm"]
        if not constraint.accepts(section[name]):
            raise ModelFileError(f"{where}.{name} must be {constraint.describe()}, got {shown(section[name])}",
                                 path=path)
    freq = _grid(features["spectrum"], path)
    _check_log_frequencies(span, freq, f"{where}.log_frequency_range", path)
    try:
        search_bins(freq, period, section["exclusion_per_mm"])
    except ValueError as exc:
        raise ModelFileError(f"{where}: {exc}", path=path) from None
    return PeakDomain(freq, (float(span[0]), float(span[1])), float(section["clarity_limit"]),
                      None if period is None else float(period), float(section["exclusion_per_mm"]), harmonic,
                      press_scatter(section, where, freq, path))
