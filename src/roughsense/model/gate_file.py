"""The contact-image gate's section of a model file: ``training.contact_gate``, written, checked and loaded here.

Everything the gate needs to score is numbers (``model/contact_gate.py``): the descriptors' names, their
standardisation, one robust detector per held-out specimen (location and precision), the held-out calibration scores
with the detector that made each, the training ranges the reasons quote and alpha. JSON, never pickle. A file
without the section (written before the gate) predicts without one and says so once; a damaged section is refused
in one line naming the field.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ModelFileError
from ..sensor.descriptors import DESCRIPTORS
from . import schema
from .contact_gate import ContactGate
from .schema import integer, number, strict

#: The key in a model file's ``training`` record.
KEY = "contact_gate"
#: Most detectors (held-out specimens) and calibration presses a file may hold.
MAX_FOLDS, MAX_PRESSES = 10_000, 1_000_000


def gate_section(gate: ContactGate) -> dict:
    """The gate as JSON values."""
    return {"alpha": gate.alpha, "descriptors": list(gate.names), "center": gate.center.tolist(),
            "scale": gate.scale.tolist(), "locations": gate.locations.tolist(),
            "precisions": gate.precisions.tolist(), "calibration_scores": gate.calibration.tolist(),
            "calibration_folds": gate.folds.tolist(), "training_low": gate.low.tolist(),
            "training_high": gate.high.tolist()}


_NUMBERS = {"type": "array", "items": number(), "minItems": 1}
#: The section's fields and bounds (model/schema.py checks them, then :func:`check` the facts that relate them).
SCHEMA = strict({
    "alpha": number(None, 0.5, exclusiveMinimum=0, description="a number above 0 and at most 0.5"),
    "descriptors": {"type": "array", "items": {"enum": list(DESCRIPTORS)}, "minItems": 1, "uniqueItems": True,
                    "description": f"distinct descriptors of {', '.join(DESCRIPTORS)}"},
    "center": _NUMBERS, "scale": {**_NUMBERS, "items": number(exclusiveMinimum=0), "description": "positive numbers"},
    "locations": {"type": "array", "items": _NUMBERS, "minItems": 2, "maxItems": MAX_FOLDS},
    "precisions": {"type": "array", "items": {"type": "array", "items": _NUMBERS}, "minItems": 2,
                   "maxItems": MAX_FOLDS},
    "calibration_scores": {**_NUMBERS, "items": number(0.0), "maxItems": MAX_PRESSES,
                           "description": "squared distances (0 or more)"},
    "calibration_folds": {**_NUMBERS, "items": integer(0, MAX_FOLDS - 1), "maxItems": MAX_PRESSES},
    "training_low": _NUMBERS, "training_high": _NUMBERS,
}, required=("alpha", "descriptors", "center", "scale", "locations", "precisions", "calibration_scores",
             "calibration_folds", "training_low", "training_high"))


def check(stored: dict, document: dict, fail) -> None:
    """The fields' shapes agree: one value per descriptor, one d x d symmetric precision per detector, one detector
    number per calibration score, each below the number of detectors, and every low at most its high."""
    d, g, n = len(stored["descriptors"]), len(stored["locations"]), len(stored["calibration_scores"])
    shapes = {"center": (d,), "scale": (d,), "training_low": (d,), "training_high": (d,), "locations": (g, d),
              "precisions": (g, d, d), "calibration_folds": (n,)}
    for field, shape in shapes.items():
        try:
            found = np.asarray(stored[field], dtype=np.float64).shape
        except ValueError:  # ragged
            found = None
        if found != shape:
            fail(field, f"must have shape {list(shape)} (descriptors, detectors, calibration presses)")
    precisions = np.asarray(stored["precisions"], dtype=np.float64)
    if not np.allclose(precisions, np.swapaxes(precisions, 1, 2)):
        fail("precisions", "must be symmetric matrices")
    if max(stored["calibration_folds"]) >= g:
        fail("calibration_folds", f"must be detector numbers 0-{g - 1}")
    if (np.asarray(stored["training_low"]) > np.asarray(stored["training_high"])).any():
        fail("training_low", "must not exceed training_high")


def loaded_gate(stored, path: Path | None) -> ContactGate | None:
    """The gate a model file keeps (None for a file without one), every field checked (:data:`SCHEMA`,
    :func:`check`) as the model file's loader checks it, so a section handed in alone is refused the same way."""
    if stored is None:
        return None
    where = f"training.{KEY}"
    refusal = schema.first_refusal(stored, SCHEMA, where)
    if refusal is not None:
        raise ModelFileError(refusal, path=path)
    check(stored, {}, schema.failing(where, path))

    def numbers(field: str) -> np.ndarray:
        return np.asarray(stored[field], dtype=np.float64)

    return ContactGate(tuple(stored["descriptors"]), numbers("center"), numbers("scale"), numbers("locations"),
                       numbers("precisions"), numbers("calibration_scores"),
                       np.asarray(stored["calibration_folds"], dtype=int), numbers("training_low"),
                       numbers("training_high"), float(stored["alpha"]))


def model_gate(loaded) -> ContactGate | None:
    """A loaded model's gate (None: a file written before the gate, or a model fitted in memory)."""
    training = getattr(loaded, "training", None) if hasattr(loaded, "model_file_") else None
    return loaded_gate(training.get(KEY), loaded.path) if isinstance(training, dict) else None
