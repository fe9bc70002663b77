"""Model files: a fitted model as a versioned, self-checking JSON document (never pickle).

A model file is something users send each other, so loading it must never execute anything and must
refuse, with one clear message naming the file, anything damaged, truncated, edited or from another
version. The document::

    {"format": "roughsense-model", "version": 1, "roughsense_version": "...",
     "model":    {"kind": "pls1-simpls", "n_components": A, "n_features": p, "x_mean": [p], "y_mean": y,
                  "coefficients": [[p] for k = 1..A], "intercepts": [A], "pct_var": [[A], [A]],
                  "applicability": {"rotations": [[p] x A], "loadings": [[p] x A], "score_var": [A],
                                    "t2_limit": t, "q_limit": q, "level": 0.95}   (optional: see below)}
                 | {"kind": "peak-power-law", ...}  (the peak law's section: see :mod:`.peak_law_file`),
     "features": {"spectrum": <SpatialSpectrum.feature_definition()>, "conditions": ["1N"] | ["1N","2N","3N"]},
     "training": {study, pad, condition, cv, cv_rmse, best_n_components, ...},
     "sha256":   hex digest of the canonical JSON of everything above}

``coefficients[k-1]`` is the model with k components; the file predicts with ``n_components``.

The checksum is an integrity check, not a signature: it catches a flipped digit or a truncated copy, but it is
unkeyed, so anyone who edits a file can recompute it. What keeps an edited file from predicting nonsense is the
field checks on loading (shapes, finiteness, the bounds below and the peak law's), never the checksum.

PLS bounds. Features are spectra normalised to unit area, so a feature is at most 2 / (frequency step) and a
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

import hashlib
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from .._util import atomic
from .._util.checks import POSITIVE_INT, Real, short_repr
from .._util.files import read_regular
from ..errors import InputError, ModelFileError
from ..io.numbers import BOUNDS
from ..sensor.settings import MAX_N_FREQS
from . import peak_law_file
from .applicability import DOMAIN_LEVEL, SpectrumDomain
from .families import PLS
from .peak_law import PeakPowerLaw
from .peak_law_file import LoadedPeakLaw
from .pls import SIMPLS, linear_predict

FORMAT = "roughsense-model"
VERSION = 1
KIND = "pls1-simpls"
#: Largest model file read. A model is (A + 4) x p numbers (p = 135 for a combined model): well under 1 MB.
MAX_MODEL_BYTES = 10_000_000
_TOP_KEYS = ("format", "version", "roughsense_version", "model", "features", "training", "sha256")
#: Largest |coefficient| and |x_mean| of a PLS model file, and largest |y_mean| (a rating's bound): see above.
MAX_COEFFICIENT = 1e6
MAX_X_MEAN = 1e6
MAX_Y_MEAN = 1e6
#: The least roughness a PLS file without a trained range may predict (a positive ratio to the reference).
MIN_ROUGHNESS = 0.01


@dataclass(frozen=True)
class LoadedModel:
    """A validated PLS model document, ready to predict."""

    family: ClassVar[str] = PLS
    path: Path | None
    n_components: int
    x_mean: np.ndarray
    y_mean: float
    coef_path: np.ndarray  # (p, A): column k-1 is the model with k components
    intercept_path: np.ndarray  # (A,)
    pct_var: np.ndarray  # (2, A)
    features: dict
    training: dict
    roughsense_version: str
    domain: SpectrumDomain | None = None

    @property
    def n_features(self) -> int:
        return int(self.coef_path.shape[0])

    @property
    def floor(self) -> float:
        """The least roughness the model predicts: half the smoothest it was trained on (a positive ratio)."""
        stored = self.training.get("target_range") if isinstance(self.training, dict) else None
        return MIN_ROUGHNESS if stored is None else 0.5 * float(stored[0])  # checked on loading

    @property
    def conditions(self) -> list[str]:
        """Force conditions, in the order a trial's images are concatenated (one for a single-force model)."""
        return list(self.features["conditions"])

    @property
    def coef_(self) -> np.ndarray:
        return self.coef_path[:, self.n_components - 1]

    @property
    def intercept_(self) -> float:
        return float(self.intercept_path[self.n_components - 1])

    def _inputs(self, X) -> np.ndarray:
        X = np.asarray(X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != self.n_features:
            raise ModelFileError(
                f"the model expects {self.n_features} features per sample, got shape {X.shape}", path=self.path
            )
        return X

    def linear_predict(self, X) -> np.ndarray:
        """The fitted :class:`SIMPLS`'s own prediction (may be <= 0: see :meth:`predict`)."""
        k = self.n_components - 1
        return linear_predict(self._inputs(X), self.coef_path[:, k], self.intercept_path[k])

    def predict(self, X, surfaces=None) -> np.ndarray:
        """Predicted perceived roughness, held at :attr:`floor` or above (``surfaces`` is accepted, not needed)."""
        return np.maximum(self.linear_predict(X), self.floor)

    def applicability(self, X, surfaces=None) -> list[str]:
        """Per row, why its prediction is not to be trusted ('' where nothing says so): a spectrum outside the
        applicability domain, or a prediction held at the floor."""
        raw = self.linear_predict(X)
        shape = self.domain.reasons(self._inputs(X), surfaces) if self.domain is not None else [""] * raw.size
        reasons = []
        for value, why in zip(raw, shape):
            parts = [why] if why else []
            if value < self.floor:
                whose = "half the smoothest trained surface" if self.floor != MIN_ROUGHNESS else "the least roughness " \
                    "an older model file may give"
                parts.append(f"PLS gave {value:.3g}, below {whose}; held at {self.floor:.3g}")
            reasons.append("; ".join(parts))
        return reasons

    def extrapolates(self, X, surfaces=None) -> np.ndarray:
        """True where :meth:`applicability` gives a reason."""
        return np.array([bool(reason) for reason in self.applicability(X, surfaces)], dtype=bool)


#: A loaded model file of either family: both predict, say whether they extrapolate, and carry their features.
AnyModel = LoadedModel | LoadedPeakLaw


# --------------------------------------------------------------------------- writing


def _canonical(document: dict) -> bytes:
    return json.dumps(document, sort_keys=True, separators=(",", ":"), allow_nan=False).encode("utf-8")


def _digest(document: dict) -> str:
    body = {k: v for k, v in document.items() if k != "sha256"}
    return hashlib.sha256(_canonical(body)).hexdigest()


def _floats(values) -> list:
    return np.asarray(values, dtype=np.float64).tolist()


def model_document(model: SIMPLS | PeakPowerLaw, *, feature_definition: dict, training: dict,
                   domain: SpectrumDomain | None = None) -> dict:
    """The JSON document of a fitted model (see the module docstring); a law is checked as a loaded file would be.

    ``domain``: a PLS model's applicability domain (:func:`roughsense.model.applicability.fit_domain`).
    """
    section = peak_law_file.law_section(model) if isinstance(model, PeakPowerLaw) else _pls_section(model)
    if domain is not None:
        section["applicability"] = domain.to_dict()
        _domain(section["applicability"], np.asarray(section["x_mean"]), section["n_components"], section["n_features"],
                _check_feature_definition(feature_definition, section["n_features"], None), None)  # as loading will
    features = _check_feature_definition(feature_definition, section["n_features"], None)
    if section["kind"] == peak_law_file.KIND:  # refuse now what load_model would refuse later
        peak_law_file.loaded_law(section, features, training=training, roughsense_version=_version(), path=None)
    else:
        _check_pls_bounds(np.asarray(section["x_mean"]), section["y_mean"], np.asarray(section["coefficients"]),
                          np.asarray(section["intercepts"]), None)
    document = {
        "format": FORMAT,
        "version": VERSION,
        "roughsense_version": _version(),
        "model": section,
        "features": features,
        "training": training,
    }
    try:
        document["sha256"] = _digest(document)
    except (TypeError, ValueError) as exc:
        raise ModelFileError(f"the model or its metadata cannot be stored as JSON ({exc})") from None
    return document


def _pls_section(model: SIMPLS) -> dict:
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
    }


def save_model(path: str | os.PathLike[str], model: SIMPLS | PeakPowerLaw, *, feature_definition: dict,
               training: dict, force: bool = False, domain: SpectrumDomain | None = None) -> Path:
    """Write the model file atomically; an existing file is replaced only with ``force``."""
    target = atomic.check_can_write(path, force=force)
    document = model_document(model, feature_definition=feature_definition, training=training, domain=domain)
    text = json.dumps(document, indent=1, allow_nan=False) + "\n"
    return atomic.write_text(target, text)


def _version() -> str:
    from .. import __version__

    return __version__


# --------------------------------------------------------------------------- reading


def load_model(path: str | os.PathLike[str]) -> AnyModel:
    """Read and validate a model file; anything wrong raises :class:`ModelFileError` naming the file.

    A model file is JSON, never pickle, so loading one from someone else runs nothing. ``roughsense fit`` writes
    them (``save_model`` in roughsense.model.modelfile from Python).

    Parameters
    ----------
    path : str or os.PathLike
        The model file.

    Returns
    -------
    LoadedModel or LoadedPeakLaw
        The model (PLS or the peak law), ready to ``predict`` spectra computed as its ``features`` say, and to
        say which it extrapolates (``applicability``); ``training`` holds what it was fitted on.

    Examples
    --------
    >>> import numpy as np
    >>> import roughsense as rs
    >>> from roughsense.model.modelfile import save_model
    >>> f = rs.frequency_grid()
    >>> periods = np.repeat([2.0, 3.0, 4.0, 5.0], 2)
    >>> X = np.exp(-((f - 1 / periods[:, None]) / 0.05) ** 2) + 0.01
    >>> law = rs.PeakPowerLaw().fit(X, (periods / 3) ** 0.9)
    >>> features = {"spectrum": rs.SpatialSpectrum().feature_definition(), "conditions": ["2N"]}
    >>> _ = save_model("law.json", law, feature_definition=features, training={"study": "gratings"})
    >>> model = rs.load_model("law.json")
    >>> model.family, model.conditions, model.predict(X[::2]).round(2)
    ('peak-law', ['2N'], array([0.69, 1.  , 1.3 , 1.58]))
    """
    path = Path(path)
    try:
        raw = read_regular(path, limit=MAX_MODEL_BYTES + 1, what="model file")  # never more; a FIFO: no wait
    except InputError as exc:
        raise ModelFileError(exc.message, path=path) from None
    except FileNotFoundError:
        raise ModelFileError("model file not found", path=path) from None
    except IsADirectoryError:
        raise ModelFileError("is a folder, expected a model file", path=path) from None
    except OSError as exc:
        raise ModelFileError(f"cannot read the model file ({exc.strerror or exc})", path=path) from None
    if len(raw) > MAX_MODEL_BYTES:
        raise ModelFileError(f"is larger than {MAX_MODEL_BYTES // 1_000_000} MB; a roughsense model file is a few "
                             "hundred kB, so this is not one", path=path)
    try:
        document = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ModelFileError(f"is not a valid model file: damaged or truncated JSON ({exc})", path=path) from None
    return model_from_document(document, path=path)


def model_from_document(document, *, path: Path | None = None) -> AnyModel:
    """A checked document (format, version, fields, checksum) loaded as its model kind."""
    def fail(message: str):
        raise ModelFileError(message, path=path)

    if not isinstance(document, dict) or document.get("format") != FORMAT:
        fail(f"is not a roughsense model file (expected \"format\": \"{FORMAT}\")")
    version = document.get("version")
    if type(version) is not int or version != VERSION:  # 1.0 and true are not the integer 1
        fail(f"model file version {version!r} is not supported (this roughsense {_version()} reads version {VERSION})")
    missing = [k for k in _TOP_KEYS if k not in document]
    if missing:
        fail(f"model file lacks {', '.join(missing)}")
    unknown = sorted(set(document) - set(_TOP_KEYS))
    if unknown:
        fail(f"model file has unknown field(s) {', '.join(unknown)}")
    try:
        digest = _digest(document)
    except (TypeError, ValueError):
        digest = None
    if not isinstance(document["sha256"], str) or document["sha256"] != digest:
        fail("model file is damaged or was edited: its checksum does not match its content")
    if not isinstance(document["roughsense_version"], str):
        fail("roughsense_version must be a string")
    model, training = document["model"], document["training"]
    if not isinstance(model, dict):
        fail("\"model\" must be an object")
    if not isinstance(training, dict):
        fail("\"training\" must be an object")
    _check_target_range(training.get("target_range", None), path)
    if model.get("kind") == peak_law_file.KIND:
        n_features = peak_law_file.check_fields(model, path)
        features = _check_feature_definition(document["features"], n_features, path)
        return peak_law_file.loaded_law(model, features, training=training,
                                        roughsense_version=document["roughsense_version"], path=path)
    return _pls_from_document(document, path)


def _check_target_range(stored, path: Path | None) -> None:
    """``training.target_range``, when there: the smallest and largest rating trained on, each a rating within its
    bounds. PLS's floor is half the smallest, so a forged 5e-324 would make every prediction 0."""
    rating = BOUNDS["rating"]
    if stored is None:
        return
    if not (isinstance(stored, list) and len(stored) == 2 and all(rating.accepts(v) for v in stored)
            and stored[0] <= stored[1]):
        raise ModelFileError(f"training.target_range must be [smallest, largest] of the ratings trained on, each "
                             f"from {rating.low:g} to {rating.high:g}, got {short_repr(stored)}", path=path)


def _pls_from_document(document: dict, path: Path | None) -> LoadedModel:
    def fail(message: str):
        raise ModelFileError(message, path=path)

    model = document["model"]
    if model.get("kind") != KIND:
        fail(f"model kind {short_repr(model.get('kind'))} is not supported (expected {KIND!r} or {peak_law_file.KIND!r})")
    expected = {"kind", "n_components", "n_features", "x_mean", "y_mean", "coefficients", "intercepts", "pct_var"}
    if set(model) - {"applicability"} != expected:
        fail(f"\"model\" must have exactly the fields {', '.join(sorted(expected))} (and optionally applicability)")
    A, p = model["n_components"], model["n_features"]
    for name, value in (("n_components", A), ("n_features", p)):
        if not POSITIVE_INT.accepts(value):
            fail(f"model.{name} must be a positive whole number, got {value!r}")
    x_mean = _array(model["x_mean"], (p,), "model.x_mean", path)
    coef = _array(model["coefficients"], (A, p), "model.coefficients", path)
    intercepts = _array(model["intercepts"], (A,), "model.intercepts", path)
    pct_var = _array(model["pct_var"], (2, A), "model.pct_var", path)
    y_mean = model["y_mean"]
    if not Real().accepts(y_mean):
        fail(f"model.y_mean must be a finite number, got {short_repr(y_mean)}")
    _check_pls_bounds(x_mean, y_mean, coef, intercepts, path)
    features = _check_feature_definition(document["features"], p, path)
    domain = _domain(model["applicability"], x_mean, A, p, features, path) if "applicability" in model else None
    return LoadedModel(
        path=path,
        n_components=A,
        x_mean=x_mean,
        y_mean=float(y_mean),
        coef_path=np.ascontiguousarray(coef.T),
        intercept_path=intercepts,
        pct_var=pct_var,
        features=features,
        training=document["training"],
        roughsense_version=document["roughsense_version"],
        domain=domain,
    )


def _domain(section, x_mean: np.ndarray, A: int, p: int, features: dict, path: Path | None) -> SpectrumDomain:
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
    peak = peak_law_file.peak_domain(section["peak"], features, path) if "peak" in section else None
    return SpectrumDomain(x_mean, rotations.T.copy(), loadings.T.copy(), score_var, float(section["t2_limit"]),
                          float(section["q_limit"]), peak, len(features["conditions"]))


def _check_pls_bounds(x_mean: np.ndarray, y_mean: float, coef: np.ndarray, intercepts: np.ndarray,
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


def _check_feature_definition(features, n_features: int, path: Path | None) -> dict:
    """A feature definition: {"spectrum": {..., "n_freqs": k}, "conditions": [...]} with k x len(conditions) = p."""
    def fail(message: str):
        raise ModelFileError(message, path=path)

    if not isinstance(features, dict):
        fail("the feature definition must be an object")
    spectrum, conditions = features.get("spectrum"), features.get("conditions")
    if not isinstance(spectrum, dict):
        fail("the feature definition lacks its \"spectrum\" object")
    if not isinstance(conditions, list) or not conditions or not all(isinstance(c, str) for c in conditions):
        fail("the feature definition needs \"conditions\": a non-empty list of force conditions")
    if len(set(conditions)) != len(conditions):
        fail(f"the feature definition repeats a force condition: {conditions}")
    n_freqs = spectrum.get("n_freqs")
    if not POSITIVE_INT.accepts(n_freqs):
        fail("the feature definition's spectrum needs a positive whole n_freqs")
    if n_freqs > MAX_N_FREQS:  # before a grid of that size is built for every image
        fail(f"the feature definition's spectrum has n_freqs {n_freqs}; at most {MAX_N_FREQS} are accepted")
    if n_freqs * len(conditions) != n_features:
        fail(
            f"the feature definition gives {n_freqs} frequencies x {len(conditions)} condition(s), "
            f"but the model has {n_features} coefficients"
        )
    return features


def feature_definition_for(spectrum, conditions) -> dict:
    """The feature definition of spectra from ``spectrum`` at the given force conditions, in order."""
    return {"spectrum": spectrum.feature_definition(), "conditions": list(conditions)}


def check_features(loaded: AnyModel, feature_definition: dict) -> None:
    """Refuse features computed differently from the model's (scale, ROI, band, frequencies, forces)."""
    difference = _first_difference(loaded.features, feature_definition, "")
    if difference is not None:
        key, model_value, given = difference
        raise ModelFileError(
            f"the features differ from the model's: {key or 'definition'} is {_short(given)} here "
            f"but {_short(model_value)} in the model",
            path=loaded.path,
        )


def _short(value) -> str:
    text = json.dumps(value) if not isinstance(value, str) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _first_difference(model_value, given, key: str):
    if isinstance(model_value, dict) and isinstance(given, dict):
        for name in sorted(set(model_value) | set(given)):
            sub = f"{key}.{name}" if key else name
            if name not in model_value or name not in given:
                return sub, model_value.get(name), given.get(name)
            found = _first_difference(model_value[name], given[name], sub)
            if found:
                return found
        return None
    if isinstance(model_value, (list, tuple)) and isinstance(given, (list, tuple)):
        if len(model_value) != len(given):
            return key, model_value, given
        for a, b in zip(model_value, given):
            if _first_difference(a, b, key):
                return key, model_value, given
        return None
    numbers = (int, float, np.integer, np.floating)
    if isinstance(model_value, numbers) and isinstance(given, numbers) and not isinstance(model_value, bool):
        if math.isclose(float(model_value), float(given), rel_tol=1e-9, abs_tol=1e-12):
            return None
        return key, model_value, given
    return None if model_value == given else (key, model_value, given)
