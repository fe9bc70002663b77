"""Which trials of a batch predict may read: the contact-image gate and unreadable images, before any model sees them.

Each image is read once (``SpatialSpectrum.iter_readings``): its spectrum, its line and its descriptors, or the error
that refused it. A trial is withheld when one of its images cannot be read or the gate (``model/contact_gate.py``)
finds it unlike the training presses; the others go on, scored exactly as if the withheld ones had never been given,
so the gate never changes a prediction it lets through. A batch none of whose images can be read is refused with the
first one's error (there is no table to write for the others). Each trial's orientation (its images' mean) is kept for the
table and flagged beyond the tolerance.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError, ModelFileError
from .contact_gate import orientation_reason

if TYPE_CHECKING:
    from .contact_gate import ContactGate
    from .modelfile import FittedModel

#: A model file without a gate predicts without one, and says so once (a refusal would strand every file written
#: before the gate, with nothing the user can do but refit; a line lets them decide).
NO_GATE_LINE = ("this model file has no contact-image gate (written before it existed): images are not checked for "
                "being contact images of its pad; refit it with roughsense fit")


@dataclass(frozen=True)
class TrialReadings:
    """A batch read for the gate: per trial, whether it is withheld and why, its gate p-value (NaN: not gated) and
    orientation; the kept trials' spectra and lines, in order."""

    withheld: np.ndarray  # (n_trials,) bool
    withheld_reasons: list[str]
    contact_p: np.ndarray
    orientation_deg: np.ndarray
    orientation_reasons: list[str]
    spectra: np.ndarray  # (n_kept_images, n_freqs)
    lines: list
    gated: bool
    #: (n_kept_images, len(CONTACT_MEASURES)): each kept image's contact measures (sensor/contact_geometry.py).
    contact: np.ndarray | None = None


def read_trials(spectrum, images, k: int, *, ridge_period_mm: float | None, gate: ContactGate | None,
                progress=None, contact: bool = False) -> TrialReadings:
    """Read every image of ``images`` (trial order, ``k`` per trial) with the model's ``spectrum`` and gate its
    trials with the model's ``gate`` (None: a file without one, every readable trial kept); with ``contact``, keep
    the kept images' contact measures too (a family that reads them)."""
    stream = spectrum.iter_readings(images, ridge_period_mm=ridge_period_mm)
    if progress is not None:
        stream = progress(stream, total=len(images), description="spectra")
    readings = list(stream)
    errors = [r for r in readings if isinstance(r, InputError)]
    if errors and len(errors) == len(readings):  # no other row to write: the one error, as before
        raise errors[0]
    n_trials = len(readings) // k
    reasons = [""] * n_trials
    for i, reading in enumerate(readings):
        if isinstance(reading, InputError) and not reasons[i // k]:
            reasons[i // k] = f"unreadable: {reading}"
    angles = np.array([_mean_angle(readings[t * k:(t + 1) * k]) for t in range(n_trials)])
    p = np.full(n_trials, math.nan)
    if gate is not None:
        p = _gate(gate, readings, reasons, k)
    withheld = np.array([bool(r) for r in reasons], dtype=bool)
    kept = [readings[i] for i in range(len(readings)) if not withheld[i // k]]
    n_freqs = spectrum.freq_per_mm_.size
    spectra = np.vstack([r[0] for r in kept]) if kept else np.empty((0, n_freqs))
    return TrialReadings(withheld, reasons, p, angles, [orientation_reason(a) for a in angles], spectra,
                         [r[1] for r in kept], gate is not None,
                         described_contact([r[2] for r in kept]) if contact else None)


def described_contact(descriptors: list[dict]) -> np.ndarray:
    """(n_images, len(CONTACT_MEASURES)) contact measures of each image's descriptors, in the measures' order."""
    from ..sensor.contact_geometry import CONTACT_MEASURES

    return np.array([[d[name] for name in CONTACT_MEASURES] for d in descriptors],
                    dtype=np.float64).reshape(len(descriptors), len(CONTACT_MEASURES))


def _mean_angle(readings) -> float:
    angles = [r[2]["orientation_deg"] for r in readings if not isinstance(r, InputError)]
    return float(np.mean(angles)) if angles and all(map(math.isfinite, angles)) else math.nan


def _gate(gate, readings, reasons: list[str], k: int) -> np.ndarray:
    """Each trial's gate p-value (NaN for an unreadable one), writing the reasons of those at or below alpha."""
    n_trials = len(reasons)
    values = np.full((len(readings), len(gate.names)), math.nan)
    readable = np.array([not isinstance(r, InputError) for r in readings])
    for i in np.flatnonzero(readable):
        values[i] = [readings[i][2][n] for n in gate.names]
    if not readable.any():
        return np.full(n_trials, math.nan)
    press_p = np.full(len(readings), math.nan)
    press_p[readable] = gate.p_values(values[readable])
    trial_p = np.minimum(1.0, k * np.nanmin(press_p.reshape(-1, k), axis=1)) if readable.all() else np.array(
        [min(1.0, k * np.nanmin(press_p[t * k:(t + 1) * k])) if readable[t * k:(t + 1) * k].all() else math.nan
         for t in range(n_trials)])
    far = np.zeros(len(readings), dtype=bool)
    far[readable] = gate.withholds(values[readable], np.ones(int(readable.sum())))  # the range rule, per image
    for t in range(n_trials):
        if not reasons[t] and (trial_p[t] <= gate.alpha or far[t * k:(t + 1) * k].any()):
            worst = t * k + int(np.nanargmin(press_p[t * k:(t + 1) * k] - far[t * k:(t + 1) * k]))
            reasons[t] = gate.reason(values[worst], float(trial_p[t]))
    return trial_p


def press_checker(loaded: FittedModel) -> Callable[[object], str]:
    """For ``capture --model``: one press at a time as it is taken, why the model's gate would withhold it (at alpha
    per press) or why it is turned, '' where it passes. The press is read as the model reads it (the model's band,
    scale and crop), so an operator hears at once that the camera shows no contact image of the model's pad."""
    from .gate_file import model_gate
    from .reading import model_ridge_period_mm, model_spectrum

    gate = model_gate(loaded)
    if gate is None:
        raise ModelFileError(f"--model: {NO_GATE_LINE}", path=loaded.path)
    spectrum = model_spectrum(loaded)
    ridge_period_mm = model_ridge_period_mm(loaded)

    def check(image) -> str:
        [reading] = list(spectrum.iter_readings([image], ridge_period_mm=ridge_period_mm))
        if isinstance(reading, InputError):
            return f"unreadable: {reading}"
        reasons = [""]
        _gate(gate, [reading], reasons, 1)
        return reasons[0] or orientation_reason(reading[2]["orientation_deg"])

    return check
