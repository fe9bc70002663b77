"""The PLS section of a model file (of kind :data:`KIND`): written from a fitted :class:`SIMPLS`, checked field by
field and loaded as the fitted :class:`SIMPLS` itself, as model/peak_law/file.py does for the peak law;
model/modelfile.py holds the envelope (format, version, checksum, feature definition) around either.

The section::

    {"kind": KIND, "n_components": A, "n_features": p, "x_mean": [p], "y_mean": y,
     "coefficients": [[p] for k = 1..A], "intercepts": [A], "pct_var": [[A], [A]],
     "applicability": {"rotations": [[p] x A], "loadings": [[p] x A], "score_var": [A],
                       "t2_limit": t, "q_limit": q, "level": 0.95}   (optional: see below)}

``coefficients[k-1]`` is the model with k components; the file predicts with ``n_components``.

Bounds. Features are spectra normalised to unit area, so a feature is at most 2 / (frequency step) and a
row's features sum to a few hundred at most; responses are ratings, within 1e6 (``io.numbers.BOUNDS``). A fit
on such data gives coefficients of order one (|c| <= :data:`MAX_COEFFICIENT` is a millionfold margin), and
each intercept is ``y_mean - x_mean . c`` by construction, so it is bounded by ``|y_mean| + |x_mean| . |c|``.
Within these bounds every prediction of a computed spectrum is a finite number.

Impossible values. Perceived roughness is a positive ratio to the reference, but PLS is linear and can predict a
value <= 0. A loaded PLS model holds its predictions at or above a floor, half the smoothest roughness it was trained
on (``training``'s ``target_range``; :data:`MIN_ROUGHNESS` for a file without one), and flags every value it held.
``applicability`` is PLS's applicability domain (:mod:`.applicability`); a file written before it existed loads
without it, and its spectra are then not checked.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..._util.checks import POSITIVE_INT, Real, short_repr, shown
from ...errors import ModelFileError
from .. import schema
from ..loaded import ModelFileInfo
from ..peak_search import search_bins
from ..readout_file import (
    BOUNDED,
    CLARITY_LIMIT,
    EXCLUSION,
    PAD_PERIOD,
    PRESS_SCATTER_SCHEMA,
    bounded,
    check_log_frequencies,
    press_scatter,
    spectrum_grid,
)
from .applicability import DOMAIN_LEVEL, PeakDomain, SpectrumDomain
from .simpls import MIN_ROUGHNESS, SIMPLS

KIND = "pls1-simpls"
_FIELDS = {"kind", "n_components", "n_features", "x_mean", "y_mean", "coefficients", "intercepts", "pct_var"}

#: Largest |coefficient| and |x_mean| of a PLS model file, and largest |y_mean| (a rating's bound): see above.
MAX_COEFFICIENT = 1e6
MAX_X_MEAN = 1e6
MAX_Y_MEAN = 1e6
#: The whole variance, to rounding: no share explained exceeds it.
_WHOLE = 1.0 + 1e-9


#: A PLS file's peak readout domain (``model.applicability.peak``), as JSON Schema.
PEAK_DOMAIN_SCHEMA = schema.strict({
    "log_frequency_range": {"type": "array", "items": bounded(BOUNDED), "minItems": 2, "maxItems": 2},
    "clarity_limit": bounded(CLARITY_LIMIT),
    "pad_ridge_period_mm": bounded(PAD_PERIOD, null=True),
    "exclusion_per_mm": bounded(EXCLUSION),
    "harmonic_range": {"type": "array", "items": bounded(BOUNDED, null=True), "minItems": 2, "maxItems": 2},
    "press_scatter": PRESS_SCATTER_SCHEMA,
}, required=("log_frequency_range", "clarity_limit", "pad_ridge_period_mm", "exclusion_per_mm"))

def _matrix(limit: float | None = None, **more) -> dict:
    return {"type": "array", "items": {"type": "array", "items": schema.number(None if limit is None else -limit, limit)},
            **more}


#: The section as JSON Schema (model/schema.py), checked after the code below has checked shapes and bounds:
#: ``pct_var`` is each component's share of the variance of X and of y, so within 0 to 1 (its rows sum to at most
#: 1: :func:`check_section`).
SCHEMA = schema.strict({
    "kind": {"const": KIND},
    "n_components": schema.integer(1, None),
    "n_features": schema.integer(1, None),
    "x_mean": {"type": "array", "items": schema.number(-MAX_X_MEAN, MAX_X_MEAN)},
    "y_mean": schema.number(-MAX_Y_MEAN, MAX_Y_MEAN),
    "coefficients": _matrix(MAX_COEFFICIENT),
    "intercepts": {"type": "array", "items": schema.number()},
    "pct_var": {"type": "array", "items": {"type": "array", "items": schema.number(0.0, _WHOLE)}, "minItems": 2,
                "maxItems": 2},
    "applicability": schema.strict({
        "rotations": _matrix(MAX_COEFFICIENT), "loadings": _matrix(MAX_COEFFICIENT),
        "score_var": {"type": "array", "items": schema.number(exclusiveMinimum=0.0)},
        "t2_limit": schema.number(None, MAX_COEFFICIENT, exclusiveMinimum=0.0),
        "q_limit": schema.number(None, MAX_COEFFICIENT, exclusiveMinimum=0.0),
        "level": {"const": DOMAIN_LEVEL},
        "peak": PEAK_DOMAIN_SCHEMA,
    }, required=("rotations", "loadings", "score_var", "t2_limit", "q_limit", "level")),
}, required=tuple(sorted(_FIELDS)))


def check_section(section: dict, document: dict, fail) -> None:
    """Each share of variance explained is of the whole: a row of ``pct_var`` sums to at most 1 (to rounding)."""
    for i, row in enumerate(section["pct_var"]):
        if sum(row) > _WHOLE:
            fail(f"pct_var[{i}]", f"sums to {sum(row):.6g}; shares of the variance explained sum to at most 1")


def _floats(values) -> list:
    return np.asarray(values, dtype=np.float64).tolist()


def pls_section(model: SIMPLS) -> dict:
    """The section of a fitted :class:`SIMPLS` (every component count's coefficients: the file predicts with all), and
    its applicability domain (``domain_``, model/pls/applicability.py) where it has one."""
    if not hasattr(model, "coef_path_"):
        raise ModelFileError("the model is not fitted")
    p, A = model.coef_path_.shape
    return {
        "kind": KIND,
        "n_components": int(A),
        "n_features": int(p),
        "x_mean": _floats(model.x_mean_),
        "y_mean": float(model.y_mean_),
        "coefficients": _floats(model.coef_path_.T),
        "intercepts": _floats(model.intercept_path_),
        "pct_var": _floats(model.pct_var_),
        **({} if getattr(model, "domain_", None) is None else {"applicability": model.domain_.to_dict()}),
    }


def check_written(section: dict, features: dict) -> None:
    """Before a file is written: its domain and bounds as loading checks them (what it would refuse later)."""
    x_mean = np.asarray(section["x_mean"])
    if "applicability" in section:
        checked_domain(section["applicability"], x_mean, section["n_components"], section["n_features"], features,
                       None)
    check_bounds(x_mean, section["y_mean"], np.asarray(section["coefficients"]), np.asarray(section["intercepts"]),
                 None)


def check_fields(section: dict, path: Path | None) -> int:
    """Exactly the section's fields, its arrays' shapes and finiteness, and the bounds above; returns the feature
    count (the feature definition is checked on it)."""
    def fail(message: str):
        raise ModelFileError(message, path=path)

    if set(section) - {"applicability"} != _FIELDS:
        fail(f"\"model\" must have exactly the fields {', '.join(sorted(_FIELDS))} (and optionally applicability)")
    A, p = section["n_components"], section["n_features"]
    for name, value in (("n_components", A), ("n_features", p)):
        if not POSITIVE_INT.accepts(value):
            fail(f"model.{name} must be a positive whole number, got {value!r}")
    x_mean, coef, intercepts, _ = _arrays(section, path)
    y_mean = section["y_mean"]
    if not Real().accepts(y_mean):
        fail(f"model.y_mean must be a finite number, got {short_repr(y_mean)}")
    check_bounds(x_mean, y_mean, coef, intercepts, path)
    return p


def _arrays(section: dict, path: Path | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    A, p = section["n_components"], section["n_features"]
    return (_array(section["x_mean"], (p,), "model.x_mean", path),
            _array(section["coefficients"], (A, p), "model.coefficients", path),
            _array(section["intercepts"], (A,), "model.intercepts", path),
            _array(section["pct_var"], (2, A), "model.pct_var", path))


def loaded_pls(section: dict, features: dict, *, training: dict, roughsense_version: str,
               path: Path | None) -> SIMPLS:
    """A section that passed :func:`check_fields`, with its checked feature definition, as the fitted
    :class:`SIMPLS` (``coef_path_``, ``floor_``, ``domain_``, ``model_file_``: what the file records)."""
    A, p = section["n_components"], section["n_features"]
    x_mean, coef, intercepts, pct_var = _arrays(section, path)
    model = SIMPLS(n_components=A)
    model.n_features_in_ = p
    model.x_mean_, model.y_mean_ = x_mean, float(section["y_mean"])
    model.coef_path_, model.intercept_path_, model.pct_var_ = np.ascontiguousarray(coef.T), intercepts, pct_var
    model.coef_, model.intercept_ = model.coef_path_[:, A - 1], float(intercepts[A - 1])
    stored = training.get("target_range")  # checked on loading
    model.floor_ = MIN_ROUGHNESS if stored is None else 0.5 * float(stored[0])
    model.domain_ = checked_domain(section["applicability"], x_mean, A, p, features, path) \
        if "applicability" in section else None
    model.model_file_ = ModelFileInfo(path, features, training, roughsense_version)
    return model


def checked_domain(section, x_mean: np.ndarray, A: int, p: int, features: dict, path: Path | None) -> SpectrumDomain:
    """A PLS file's applicability section, checked: shapes, finite numbers, positive variances and limits."""
    fields = {"rotations", "loadings", "score_var", "t2_limit", "q_limit", "level"}
    if not isinstance(section, dict) or set(section) - {"peak"} != fields:
        raise ModelFileError("model.applicability must have exactly the fields rotations, loadings, score_var, "
                             "t2_limit, q_limit, level (and optionally peak)", path=path)
    rotations = _array(section["rotations"], (A, p), "model.applicability.rotations", path)
    loadings = _array(section["loadings"], (A, p), "model.applicability.loadings", path)
    score_var = _array(section["score_var"], (A,), "model.applicability.score_var", path)
    for name in ("t2_limit", "q_limit"):
        if not Real(0.0, MAX_COEFFICIENT, low_open=True).accepts(section[name]):
            raise ModelFileError(f"model.applicability.{name} must be a positive number, got "
                                 f"{short_repr(section[name])}", path=path)
    if not (Real().accepts(section["level"]) and section["level"] == DOMAIN_LEVEL):  # the level its limits are at
        raise ModelFileError(f"model.applicability.level must be {DOMAIN_LEVEL} (the percentile roughsense's T2 and Q "
                             f"limits are drawn at), got {short_repr(section['level'])}", path=path)
    if np.any(score_var <= 0) or max(np.abs(rotations).max(), np.abs(loadings).max()) > MAX_COEFFICIENT:
        raise ModelFileError("model.applicability holds a non-positive score variance or a value beyond "
                             f"{MAX_COEFFICIENT:g}", path=path)
    peak = peak_domain(section["peak"], features, path) if "peak" in section else None
    return SpectrumDomain(x_mean, rotations.T.copy(), loadings.T.copy(), score_var, float(section["t2_limit"]),
                          float(section["q_limit"]), peak, len(features["conditions"]))


def check_bounds(x_mean: np.ndarray, y_mean: float, coef: np.ndarray, intercepts: np.ndarray,
                 path: Path | None) -> None:
    """Refuse numbers no fit on spectra and ratings produces (see the module docstring): an edited, re-signed
    file with coefficients of 1e308 would otherwise predict ``inf``."""
    def fail(message: str):
        raise ModelFileError(message, path=path)

    for name, values, limit in (("coefficients", coef, MAX_COEFFICIENT), ("x_mean", x_mean, MAX_X_MEAN)):
        worst = float(np.max(np.abs(values))) if values.size else 0.0
        if worst > limit:
            fail(f"model.{name} holds {worst:g}; a fitted model's are at most {limit:g} in magnitude")
    if abs(y_mean) > MAX_Y_MEAN:
        fail(f"model.y_mean is {y_mean:g}; a rating is at most {MAX_Y_MEAN:g}")
    # intercept_k = y_mean - x_mean . c_k for a fit: its magnitude is at most this (with rounding slack).
    reach = (abs(y_mean) + np.abs(coef) @ np.abs(x_mean)) * (1 + 1e-9) + 1e-12
    over = np.flatnonzero(np.abs(intercepts) > reach)
    if over.size:
        k = int(over[0])
        fail(f"model.intercepts[{k}] is {intercepts[k]:g}, beyond what a fit can give (|y_mean| + |x_mean|.|c| = "
             f"{reach[k]:g})")


def _all_numbers(value) -> bool:
    """Nested lists of JSON numbers only: no strings ("1.5" would convert), booleans or nulls."""
    if isinstance(value, list):
        return all(_all_numbers(v) for v in value)
    return type(value) in (int, float)


def _array(value, shape: tuple[int, ...], name: str, path: Path | None) -> np.ndarray:
    try:
        numbers = isinstance(value, list) and _all_numbers(value)
    except RecursionError:
        numbers = False
    if not numbers:
        raise ModelFileError(f"{name} must be an array of numbers", path=path)
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ModelFileError(f"{name} must be an array of numbers", path=path) from None
    if array.shape != shape:
        raise ModelFileError(f"{name} has shape {array.shape}, expected {shape}", path=path)
    if not np.all(np.isfinite(array)):
        raise ModelFileError(f"{name} holds a value that is not a finite number", path=path)
    return array


def peak_domain(section, features: dict, path: Path | None):
    """A PLS file's peak readout domain (``model.applicability.peak``), checked like the law's own fields."""
    where = "model.applicability.peak"
    fields = {"log_frequency_range", "clarity_limit", "pad_ridge_period_mm", "exclusion_per_mm"}
    if not isinstance(section, dict) or set(section) - {"harmonic_range", "press_scatter"} != fields:
        raise ModelFileError(f"{where} must have exactly the fields log_frequency_range, clarity_limit, "
                             "pad_ridge_period_mm, exclusion_per_mm (and harmonic_range, press_scatter)", path=path)
    harmonic = section.get("harmonic_range", [None, None])
    if not isinstance(harmonic, list) or len(harmonic) != 2 or not all(v is None or BOUNDED.accepts(v)
                                                                       for v in harmonic):
        raise ModelFileError(f"{where}.harmonic_range must be two numbers or nulls, got {shown(harmonic)}", path=path)
    harmonic = (-np.inf if harmonic[0] is None else float(harmonic[0]),
                np.inf if harmonic[1] is None else float(harmonic[1]))
    span = section["log_frequency_range"]
    if not isinstance(span, list) or len(span) != 2 or not all(BOUNDED.accepts(v) for v in span) or span[0] > span[1]:
        raise ModelFileError(f"{where}.log_frequency_range must be two increasing numbers, got {shown(span)}",
                             path=path)
    period = section["pad_ridge_period_mm"]
    if period is not None and not PAD_PERIOD.accepts(period):
        raise ModelFileError(f"{where}.pad_ridge_period_mm must be {PAD_PERIOD.describe()} or null", path=path)
    for name in ("clarity_limit", "exclusion_per_mm"):
        constraint = CLARITY_LIMIT if name == "clarity_limit" else EXCLUSION
        if not constraint.accepts(section[name]):
            raise ModelFileError(f"{where}.{name} must be {constraint.describe()}, got {shown(section[name])}",
                                 path=path)
    freq = spectrum_grid(features["spectrum"], path)
    check_log_frequencies(span, freq, f"{where}.log_frequency_range", path)
    try:
        search_bins(freq, period, section["exclusion_per_mm"])
    except ValueError as exc:
        raise ModelFileError(f"{where}: {exc}", path=path) from None
    return PeakDomain(freq, (float(span[0]), float(span[1])), float(section["clarity_limit"]),
                      None if period is None else float(period), float(section["exclusion_per_mm"]), harmonic,
                      press_scatter(section, where, freq, path))
