"""The contact-image gate's section of a model file: ``training.contact_gate``, written, checked and loaded here.

Everything the gate needs to score is numbers (``model/contact_gate.py``): the descriptors' names, their
standardisation, one robust detector per held-out specimen (location and precision), the held-out calibration scores
with the detector that made each, the training ranges the reasons quote and alpha. JSON, never pickle. A file
without the section (written before the gate) predicts without one and says so once; a damaged section is refused
in one line naming the field.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import ModelFileError
from ..sensor.descriptors import DESCRIPTORS
from .contact_gate import ContactGate

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


def _numbers(stored: dict, field: str, shape: tuple, path: Path | None, *, positive: bool = False) -> np.ndarray:
    value = stored.get(field)
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        array = None
    if array is None or array.shape != shape or not np.isfinite(array).all() or (positive and (array <= 0).any()):
        raise ModelFileError(f"training.{KEY}.{field} must be {'positive ' if positive else ''}finite numbers of shape "
                             f"{list(shape)}", path=path)
    return array


def loaded_gate(stored, path: Path | None) -> ContactGate | None:
    """The gate a model file keeps (None for a file without one), every field checked."""
    if stored is None:
        return None
    if not isinstance(stored, dict):
        raise ModelFileError(f"training.{KEY} must be an object", path=path)
    names = stored.get("descriptors")
    if (not isinstance(names, list) or not names or len(set(names)) != len(names)
            or not all(isinstance(n, str) and n in DESCRIPTORS for n in names)):
        raise ModelFileError(f"training.{KEY}.descriptors must name distinct descriptors of {', '.join(DESCRIPTORS)}",
                             path=path)
    alpha = stored.get("alpha")
    if not (isinstance(alpha, float) and 0 < alpha <= 0.5):
        raise ModelFileError(f"training.{KEY}.alpha must be a number above 0 and at most 0.5", path=path)
    d = len(names)
    folds_given = stored.get("calibration_folds")
    n = len(folds_given) if isinstance(folds_given, list) else -1
    g = len(stored.get("locations")) if isinstance(stored.get("locations"), list) else -1
    if not (2 <= g <= MAX_FOLDS and 1 <= n <= MAX_PRESSES):
        raise ModelFileError(f"training.{KEY} needs 2-{MAX_FOLDS} detectors and 1-{MAX_PRESSES} calibration presses",
                             path=path)
    folds = _numbers(stored, "calibration_folds", (n,), path)
    if not (np.all(folds == np.round(folds)) and folds.min() >= 0 and folds.max() < g):
        raise ModelFileError(f"training.{KEY}.calibration_folds must be detector numbers 0-{g - 1}", path=path)
    precisions = _numbers(stored, "precisions", (g, d, d), path)
    if not np.allclose(precisions, np.swapaxes(precisions, 1, 2)):
        raise ModelFileError(f"training.{KEY}.precisions must be symmetric matrices", path=path)
    low, high = _numbers(stored, "training_low", (d,), path), _numbers(stored, "training_high", (d,), path)
    if (low > high).any():
        raise ModelFileError(f"training.{KEY}.training_low must not exceed training_high", path=path)
    scores = _numbers(stored, "calibration_scores", (n,), path)
    if (scores < -1e-9).any() or not math.isfinite(float(scores.max())):
        raise ModelFileError(f"training.{KEY}.calibration_scores must be squared distances (0 or more)", path=path)
    return ContactGate(tuple(names), _numbers(stored, "center", (d,), path),
                       _numbers(stored, "scale", (d,), path, positive=True), _numbers(stored, "locations", (g, d), path),
                       precisions, scores, folds.astype(int), low, high, float(alpha))


def model_gate(loaded) -> ContactGate | None:
    """A loaded model's gate (None: a file written before the gate, or a model fitted in memory)."""
    training = getattr(loaded, "training", None) if hasattr(loaded, "model_file_") else None
    return loaded_gate(training.get(KEY), loaded.path) if isinstance(training, dict) else None
