"""Model files: a fitted model as a versioned, self-checking JSON document (never pickle).

A model file is something users send each other, so loading it must never execute anything and must
refuse, with one clear message naming the file, anything damaged, truncated, edited or from another
version. This module holds the envelope; the ``model`` section is its family's to write, check and load (the
registry's family of that ``kind``: model/registry.py). The document::

    {"format": "roughsense-model", "version": 1, "roughsense_version": "...",
     "model":    {"kind": <the family's kind>, ...}  (the family's section),
     "features": {"spectrum": <SpatialSpectrum.feature_definition()>, "conditions": ["1N"] | ["1N","2N","3N"]},
     "training": {study, pad, condition, cv, cv_rmse, best_n_components, ...},
     "sha256":   hex digest of the canonical JSON of everything above}

The checksum is an integrity check, not a signature: it catches a flipped digit or a truncated copy, but it is
unkeyed, so anyone who edits a file can recompute it. What keeps an edited file from predicting nonsense is the
field checks on loading, never the checksum: every section's JSON Schema and cross-field facts (model/schema.py;
the ``features`` section's is :data:`FEATURES_SCHEMA` here), each family's section by its own module (shapes,
finiteness, bounds derived from what a fit gives), and the feature definition rebuilt as the spectrum it names.
A file that holds a key twice is refused: JSON readers disagree on which value counts.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path

import numpy as np

from .._util import atomic
from .._util.checks import POSITIVE_INT, short_repr
from .._util.files import read_regular
from ..errors import InputError, ModelFileError
from ..io.numbers import BOUNDS
from ..sensor.settings import MAX_N_FREQS
from . import jackknife_file, schema
from .loaded import FromModelFile
from .registry import engine, engine_of_kind, kinds, names

FORMAT = "roughsense-model"
VERSION = 1
#: Largest model file read. A model is (A + 4) x p numbers (p = 135 for a combined model): well under 1 MB.
MAX_MODEL_BYTES = 10_000_000
#: The document's keys, every one required, and the top-level sections a file may lack (a section added after
#: version 1 goes there, and into model/schema.py's ``sections``, so that older files still load).
TOP_KEYS = ("format", "version", "roughsense_version", "model", "features", "training", "sha256")
OPTIONAL_TOP_KEYS: tuple[str, ...] = ()
#: The ``features`` section: the spectrum's definition (its settings are rebuilt on loading, so its numbers are
#: checked by the spectrum's own rules) and the force conditions in the order a trial's spectra are concatenated.
FEATURES_SCHEMA = schema.strict({
    "spectrum": {"type": "object", "required": ["kind", "version", "n_freqs", "freq_per_mm", "px_per_mm", "roi"],
                 "properties": {"px_per_mm": schema.number(BOUNDS["px_per_mm"].low, BOUNDS["px_per_mm"].high,
                                                           description="a scale a study can state, from "
                                                                       f"{BOUNDS['px_per_mm'].low:g} to "
                                                                       f"{BOUNDS['px_per_mm'].high:g} px/mm")}},
    "conditions": {"type": "array", "items": {"type": "string", "minLength": 1}, "minItems": 1, "uniqueItems": True},
}, required=("spectrum", "conditions"))
#: A model of any registered family, fitted here or loaded from a file: each predicts and says whether it
#: extrapolates; a loaded one also carries its file's part (``model_file_``: features, training).
FittedModel = FromModelFile


# --------------------------------------------------------------------------- writing


def _canonical(document: dict) -> bytes:
    return json.dumps(document, sort_keys=True, separators=(",", ":"), allow_nan=False).encode("utf-8")


def _digest(document: dict) -> str:
    body = {k: v for k, v in document.items() if k != "sha256"}
    return hashlib.sha256(_canonical(body)).hexdigest()


def model_document(model: FittedModel, *, feature_definition: dict, training: dict, path: Path | None = None) -> dict:
    """The JSON document of a fitted model (see the module docstring), checked as :func:`load_model` will check it.

    ``path``: the file it is for, which a refusal names.
    """
    family = _family_of(model)
    section = family.section(model)
    features = _check_feature_definition(feature_definition, section["n_features"], None)
    family.check_written(section, features, training)  # refuse now what load_model would refuse later
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
    model_from_document(json.loads(_canonical(document)), path=path)  # refuse now what load_model would refuse
    return document


def _family_of(model):
    """The registry's engine of the model's family (``model.family``), or a refusal naming what it is."""
    name = getattr(model, "family", None)
    if name not in names():
        raise ModelFileError(f"cannot save a {type(model).__name__}: not a model of a registered family")
    return engine(name)


def save_model(path: str | os.PathLike[str], model: FittedModel, *, feature_definition: dict,
               training: dict, force: bool = False) -> Path:
    """Write the model file atomically; an existing file is replaced only with ``force``."""
    target = atomic.check_can_write(path, force=force)
    document = model_document(model, feature_definition=feature_definition, training=training, path=target)
    text = json.dumps(document, indent=1, allow_nan=False) + "\n"
    return atomic.write_text(target, text)


def _version() -> str:
    from .. import __version__

    return __version__


# --------------------------------------------------------------------------- reading


def load_model(path: str | os.PathLike[str]) -> FittedModel:
    """Read and validate a model file; anything wrong raises :class:`ModelFileError` naming the file.

    A model file is JSON, never pickle, so loading one from someone else runs nothing. ``roughsense fit`` writes
    them (``save_model`` in roughsense.model.modelfile from Python).

    Parameters
    ----------
    path : str or os.PathLike
        The model file.

    Returns
    -------
    FittedModel
        The fitted estimator of its family (PLS's SIMPLS, the PeakPowerLaw), ready to ``predict`` spectra computed
        as its file's feature definition says (``model_file_.features``), and to say which it extrapolates
        (``applicability``); ``model_file_.training`` holds what it was fitted on.

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
    from .._util.arguments import path_argument

    path = Path(path_argument(path, "path", "a model file"))
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
        document = schema.loads_unique(raw.decode("utf-8"))
    except schema.RepeatedKeyError as exc:
        raise ModelFileError(str(exc), path=path) from None
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ModelFileError(f"is not a valid model file: damaged or truncated JSON ({exc})", path=path) from None
    return model_from_document(document, path=path)


def model_from_document(document, *, path: Path | None = None) -> FittedModel:
    """A checked document (format, version, fields, checksum) loaded as its model kind."""
    def fail(message: str):
        raise ModelFileError(message, path=path)

    if not isinstance(document, dict) or document.get("format") != FORMAT:
        fail(f"is not a roughsense model file (expected \"format\": \"{FORMAT}\")")
    version = document.get("version")
    if type(version) is not int or version != VERSION:  # 1.0 and true are not the integer 1
        fail(f"model file version {version!r} is not supported (this roughsense {_version()} reads version {VERSION})")
    missing = [k for k in TOP_KEYS if k not in document]
    if missing:
        fail(f"model file lacks {', '.join(missing)}")
    unknown = sorted(set(document) - set(TOP_KEYS) - set(OPTIONAL_TOP_KEYS))
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
    family = engine_of_kind(model.get("kind"))
    if family is None:
        fail(f"model kind {short_repr(model.get('kind'))} is not supported (expected "
             f"{' or '.join(repr(kind) for kind in kinds())})")
    n_features = family.check_fields(model, path)
    features = _check_feature_definition(document["features"], n_features, path)
    schema.check_document(document, path)
    _check_spectrum(features["spectrum"], path)
    loaded = family.load(model, features, training=training, roughsense_version=document["roughsense_version"],
                         path=path)
    schema.check_document(document, path, after_family=True)
    jackknife_file.deployed_jackknife(loaded)  # its folds and residuals, checked against the model now
    return loaded


def _check_spectrum(spectrum: dict, path: Path | None) -> None:
    """The stored spectrum is the one its own settings define: rebuilt from them (the spectrum's own rules refuse
    a scale of 0 or a band upside down), every stored field must be what roughsense writes for them, so a grid
    edited to run backwards is refused here, naming the file, not later as if the user's options were wrong."""
    from ..errors import RoughsenseError
    from ..sensor.spectrum import SpatialSpectrum

    try:
        rebuilt = SpatialSpectrum.from_definition(spectrum).fit().feature_definition()
    except (RoughsenseError, ValueError, TypeError, OverflowError) as exc:
        raise ModelFileError(f"features.spectrum: {getattr(exc, 'message', exc)}", path=path) from None
    unknown = sorted(set(spectrum) - set(rebuilt))
    if unknown:
        raise ModelFileError(f"features.spectrum.{unknown[0]}: unknown field", path=path)
    found = _first_difference({k: rebuilt[k] for k in spectrum}, spectrum, "")
    if found is not None:
        key, own, given = found
        raise ModelFileError(f"features.spectrum.{key}: is {_short(given)}, but the spectrum's own settings give "
                             f"{_short(own)}", path=path)


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


def check_features(loaded: FittedModel, feature_definition: dict) -> None:
    """Refuse features computed differently from the model's (scale, ROI, band, frequencies, forces)."""
    difference = _first_difference(loaded.model_file_.features, feature_definition, "")
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
