"""Groove-model files: the model section of kind :data:`KIND`, written from a fitted law and checked on reading.

The section beside the document's ``features`` (whose spectra fix the rows' width; the model reads none)::

    {"kind": KIND, "n_features": p, "contact_names": ["land_mm@1N", "groove_mm@1N", ...],
     "terms": ["log_groove_mm", ...], "intercept": b0, "coefficients": [b, ...],
     "term_mean": [...], "term_min": [...], "term_max": [...], "selection_se": 1.0,
     "domain": {"axes": ["log_groove_mm", "log_land_mm"], "low": [2], "high": [2], "margin": [2]}}

``contact_names`` are the columns a prediction passes as ``contact``, in this order (their conditions are the
feature definition's); ``terms`` the chosen ones, in the fixed physical order; each term is held to
[``term_min``, ``term_max``] when predicting and put at ``term_mean`` where unreadable; ``domain`` is the trained
box of log groove and log land width with each axis's margin (model/groove/domain.py).

Why each field is bounded: the checksum is unkeyed, so anyone can edit a number and re-sign it; the checks refuse a
file that would predict nonsense (a law whose exponent leaves 1e-6..1e6 anywhere in its term box is refused).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..._util.checks import POSITIVE_INT, shown
from ...errors import ModelFileError
from .. import schema
from ..loaded import ModelFileInfo
from ..readout_file import BOUNDED, bounded
from .domain import AXES
from .law import GrooveLaw
from .terms import TERM_NAMES, term_names

KIND = "groove-contact-law"
_MAX_LOG_ROUGHNESS = math.log(1e6)
_PER_TERM = ("coefficients", "term_mean", "term_min", "term_max")
FIELDS = ("kind", "n_features", "contact_names", "terms", "intercept", *_PER_TERM, "selection_se", "domain")
_NUMBERS = {"type": "array", "maxItems": len(TERM_NAMES), "items": bounded(BOUNDED)}
_PAIR = {"type": "array", "minItems": 2, "maxItems": 2, "items": bounded(BOUNDED)}
#: The section as JSON Schema (model/schema.py), checked after the field code below.
SCHEMA = schema.strict({
    "kind": {"const": KIND},
    "n_features": schema.integer(1, None),
    "contact_names": {"type": "array", "minItems": 2, "items": {"type": "string", "pattern": "^[a-z_]+@.+$"},
                      "uniqueItems": True},
    "terms": {"type": "array", "items": {"enum": list(TERM_NAMES)}, "uniqueItems": True},
    "intercept": bounded(BOUNDED),
    **dict.fromkeys(_PER_TERM, _NUMBERS),
    "selection_se": schema.number(0.0, 10.0),
    "domain": schema.strict({"axes": {"const": list(AXES)}, "low": _PAIR, "high": _PAIR,
                             "margin": {**_PAIR, "items": schema.number(0.0, 10.0)}},
                            required=("axes", "low", "high", "margin")),
}, required=FIELDS)


def groove_section(model: GrooveLaw) -> dict:
    """The ``"model"`` section of a fitted law (floats written with repr, so they read back bit-identically)."""
    if not hasattr(model, "coef_"):
        raise ModelFileError("the model is not fitted")
    return {"kind": KIND, "n_features": int(model.n_features_in_), "contact_names": list(model.contact_names_),
            "terms": list(model.terms_), "intercept": float(model.intercept_),
            "coefficients": [float(v) for v in model.coef_], "term_mean": [float(v) for v in model.term_mean_],
            "term_min": [float(v) for v in model.term_min_], "term_max": [float(v) for v in model.term_max_],
            "selection_se": float(model.selection_se),
            "domain": {"axes": list(AXES), "low": [float(v) for v in model.domain_low_],
                       "high": [float(v) for v in model.domain_high_],
                       "margin": [float(v) for v in model.domain_margin_]}}


def check_fields(section: dict, path: Path | None) -> int:
    """Exactly the model's fields, and a usable feature count (returned: the feature definition is checked on it)."""
    missing = [name for name in FIELDS if name not in section]
    if missing:
        raise ModelFileError(f"the groove model lacks the field(s) {', '.join('model.' + m for m in missing)}",
                             path=path)
    unknown = sorted(set(section) - set(FIELDS))
    if unknown:
        raise ModelFileError(f"the groove model has unknown field(s) {', '.join('model.' + str(u) for u in unknown)}",
                             path=path)
    value = section["n_features"]
    if not POSITIVE_INT.accepts(value):
        raise ModelFileError(f"model.n_features must be {POSITIVE_INT.describe()}, got {shown(value)}", path=path)
    return int(value)


def _numbers(value, length: int, where: str, path: Path | None) -> np.ndarray:
    if not isinstance(value, list) or len(value) != length or not all(BOUNDED.accepts(v) for v in value):
        raise ModelFileError(f"{where} must be a list of {length} number(s) within {BOUNDED.describe()}, got "
                             f"{shown(value)}", path=path)
    return np.array(value, dtype=np.float64)


def _contact(section: dict, features: dict, path: Path | None) -> tuple[str, ...]:
    """The contact columns: names of measures at the feature definition's conditions, giving the chosen terms."""
    names = section["contact_names"]
    if not isinstance(names, list) or not all(isinstance(n, str) and "@" in n for n in names):
        raise ModelFileError(f"model.contact_names must be a list of MEASURE@CONDITION names, got {shown(names)}",
                             path=path)
    conditions = {n.partition("@")[2] for n in names}
    if conditions != set(features["conditions"]):
        raise ModelFileError(f"model.contact_names are at {', '.join(sorted(conditions))}, but the feature "
                             f"definition's conditions are {', '.join(features['conditions'])}", path=path)
    try:
        offered = term_names(names)
    except ValueError as exc:
        raise ModelFileError(f"model.contact_names: {exc}", path=path) from None
    terms = section["terms"]
    if not isinstance(terms, list) or terms != [t for t in offered if t in terms]:
        raise ModelFileError(f"model.terms must be some of {', '.join(offered)}, in that order, got {shown(terms)}",
                             path=path)
    return tuple(names)


def loaded_groove(section: dict, features: dict, *, training: dict, roughsense_version: str,
                  path: Path | None) -> GrooveLaw:
    """Check every field of the section (``features`` already checked against ``n_features``) and load it."""
    names = _contact(section, features, path)
    k = len(section["terms"])
    per_term = {name: _numbers(section[name], k, f"model.{name}", path) for name in _PER_TERM}
    intercept = _numbers([section["intercept"]], 1, "model.intercept", path)[0]
    se = section["selection_se"]
    if not (isinstance(se, (int, float)) and not isinstance(se, bool) and 0 <= se <= 10):
        raise ModelFileError(f"model.selection_se must be a number from 0 to 10, got {shown(se)}", path=path)
    domain = section["domain"]
    if not isinstance(domain, dict) or domain.get("axes") != list(AXES):
        raise ModelFileError(f"model.domain must be an object with axes {list(AXES)}", path=path)
    low, high, margin = (_numbers(domain.get(n), 2, f"model.domain.{n}", path) for n in ("low", "high", "margin"))
    if np.any(low > high) or np.any(margin < 0) or np.any(per_term["term_min"] > per_term["term_max"]):
        raise ModelFileError("model.domain or model.term_min/term_max: an empty training range or a negative margin",
                             path=path)
    _check_finite_predictions(intercept, per_term, path)
    law = GrooveLaw(selection_se=float(se))
    law.n_features_in_, law.contact_names_ = int(section["n_features"]), names
    law.term_names_, law.terms_ = term_names(names), tuple(section["terms"])
    law.intercept_, law.coef_ = float(intercept), per_term["coefficients"]
    law.term_mean_, law.term_min_, law.term_max_ = per_term["term_mean"], per_term["term_min"], per_term["term_max"]
    law.domain_low_, law.domain_high_, law.domain_margin_ = low, high, margin
    law.model_file_ = ModelFileInfo(path, features, training, roughsense_version)
    return law


def _check_finite_predictions(intercept: float, per_term: dict, path: Path | None) -> None:
    """The exponent at the corners of the term box (a linear law's extremes; terms are held to it) stays in range."""
    corners = np.column_stack([per_term["term_min"], per_term["term_max"]]) * per_term["coefficients"][:, None]
    highest = intercept + float(corners.max(axis=1).sum()) if corners.size else intercept
    lowest = intercept + float(corners.min(axis=1).sum()) if corners.size else intercept
    if max(abs(highest), abs(lowest)) > _MAX_LOG_ROUGHNESS:
        raise ModelFileError(f"model.intercept and model.coefficients give log roughness from {lowest:.4g} to "
                             f"{highest:.4g} over the trained terms; a prediction must stay within 1e-6 to 1e6",
                             path=path)
    if not np.all((per_term["term_min"] <= per_term["term_mean"]) & (per_term["term_mean"] <= per_term["term_max"])):
        raise ModelFileError("model.term_mean must lie within model.term_min and model.term_max", path=path)
