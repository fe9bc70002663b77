"""Scoring images with a loaded model: trials in, roughness, interval and reasons out (:class:`Scores`), for
``predict``'s batches (:func:`score_trials`) and live mode's frames (:func:`frame_scorer`).

The model file carries its feature definition, so the spectra are recomputed exactly as in training
(``model/reading.py``); a combined-force model takes each trial's images in the order of its conditions (1 N, 2 N,
3 N), which ``model/trials.py`` builds from what a user gives. Each batch is read once and gated
(``model/press_gate.py``); the trials it keeps are scored, told what lies outside the model's domain
(``model/outside.py``) and given their 90 % intervals (``model/model_intervals.py``).
"""
from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError, InputError
from .modelfile import FittedModel
from .reading import SensorOverride, model_ridge_period_mm, model_spectrum


@dataclass(frozen=True)
class Scores:
    """Per trial: roughness, its interval (NaN without one) and what lies outside the model's domain ('' if
    nothing); per surface (when trials were grouped into surfaces): the mean roughness and its interval; the
    images' scale checked against known structure in them (None when nothing was checked)."""

    roughness: np.ndarray
    low: np.ndarray
    high: np.ndarray
    reasons: list[str]
    surface_roughness: np.ndarray | None = None
    surface_low: np.ndarray | None = None
    surface_high: np.ndarray | None = None
    scale: object | None = None
    #: Per trial, how its interval (``method``) and its surface's (``surface_method``) were built (None: none).
    method: list[str] | None = None
    surface_method: list[str] | None = None
    #: Per trial: withheld (no roughness, no interval; ``reasons`` says why), the grating's orientation (degrees
    #: from the image columns) and the contact-image gate's p-value (NaN without a gate); whether a gate was applied.
    withheld: np.ndarray | None = None
    orientation_deg: np.ndarray | None = None
    contact_p: np.ndarray | None = None
    gated: bool = False

    @property
    def flagged(self) -> np.ndarray:
        return np.array([bool(reason) for reason in self.reasons], dtype=bool)


def score_trials(loaded: FittedModel, images: Sequence, *, n_jobs: int = 1, progress=None,
                 override: SensorOverride | None = None, surfaces=None, reference=None) -> Scores:
    """Roughness, interval and domain reasons of every trial (and of every surface, given ``surfaces``).

    A trial the contact-image gate withholds, or one with an unreadable image, gets no roughness and no interval,
    only its reason (``model/press_gate.py``); the others are scored as if it had never been given. A trial whose
    structure lies outside the spectrum's band says so in place of the family's reading of the band (which would
    name a period the surface does not have); so does a trial the family flags whose outside structure is at least
    as strong as the band's own peak (``sensor.band.NAMING_DOMINANCE``). The scale is checked on the pad's ridges
    and on the trials whose period ``reference`` states (``(what, per-trial period in mm, NaN where none)``: a
    study's specimens of stated period); beyond its tolerance every trial is flagged ``scale: ...``.
    """
    import pandas as pd

    from .gate_file import model_gate
    from .model_intervals import interval_bounds
    from .outside import trial_reasons
    from .press_gate import read_trials

    images = list(images)
    group_images(loaded, images)  # refuse a wrong count before any decoding
    ridge, spectrum = model_ridge_period_mm(loaded), model_spectrum(loaded, n_jobs=n_jobs, override=override)
    gate = model_gate(loaded)
    read = read_trials(spectrum, images, len(loaded.conditions), ridge_period_mm=ridge, gate=gate, progress=progress,
                       contact=reads_contact(loaded))
    keep = np.flatnonzero(~read.withheld)
    scores = None  # every trial withheld: nothing to score
    if keep.size:  # the trials the gate let through, scored as predict always scored a batch
        kept_surfaces = None if surfaces is None else np.asarray(surfaces)[keep]
        if reference is not None:
            reference = (reference[0], np.asarray(reference[1])[keep])
        X, contact = spectra_to_features(loaded, read.spectra), contact_inputs(loaded, read.contact)
        roughness = loaded.predict(X, surfaces=kept_surfaces, **contact)
        reasons, scale = trial_reasons(loaded, spectrum, read.lines, X, kept_surfaces, reference,
                                       ridge_period_mm=ridge, contact=contact)
        surface = None if kept_surfaces is None else (
            pd.Series(roughness).groupby(pd.Series(kept_surfaces)).transform("mean").to_numpy())
        (low, high, method), of_surface = interval_bounds(loaded, X, roughness, kept_surfaces, surface, contact)
        s_low, s_high, s_method = (None, None, None) if of_surface is None else of_surface
        scores = Scores(roughness, low, high, reasons, surface, s_low, s_high, scale=scale, method=method,
                        surface_method=s_method)
    scored = _with_withheld(scores, read, surfaces)
    warn_field_of_view(loaded, override, images)  # after scoring: a refusal of the batch comes first
    return scored


def group_images(loaded: FittedModel, images: Sequence) -> list[tuple]:
    """Images grouped into trials: one image each, or one per condition for a combined model."""
    k = len(loaded.conditions)
    if len(images) == 0:
        raise InputError("no images to score")
    if len(images) % k:
        raise InputError(
            f"this model combines {k} forces ({', '.join(loaded.conditions)}): give images in groups of {k}, "
            f"one per force in that order; got {len(images)} image(s), which is not a multiple of {k}"
        )
    return [tuple(images[i : i + k]) for i in range(0, len(images), k)]


def spectra_to_features(loaded: FittedModel, spectra: np.ndarray) -> np.ndarray:
    """(n_images, n_freqs) spectra in trial order -> (n_trials, n_features) model inputs."""
    from ..sensor.spectrum import combine_forces

    k = len(loaded.conditions)
    spectra = np.asarray(spectra, dtype=np.float64)
    return combine_forces([spectra[i::k] for i in range(k)]) if k > 1 else spectra


def reads_contact(loaded: FittedModel) -> bool:
    """Whether the model's family reads each press's contact measures beside its spectra."""
    from .registry import engine

    return bool(engine(loaded.family).reads_contact)


def contact_inputs(loaded: FittedModel, contact: np.ndarray | None) -> dict:
    """The keyword a model of a family that reads the contact (:func:`reads_contact`) takes beside X: each trial's
    images' contact measures side by side in its force order (the file's ``contact_names``:
    ``land_mm@1N, groove_mm@1N, ..., groove_mm@3N``); nothing for the others, whose methods take no such keyword."""
    if contact is None or not reads_contact(loaded):
        return {}
    return {"contact": spectra_to_features(loaded, contact)}


def _with_withheld(scores: Scores | None, read, surfaces) -> Scores:
    """Every trial's scores: the kept ones' as scored, the withheld ones empty but for their reason; the
    orientation beside each, and a kept trial turned beyond the tolerance flagged."""
    n = read.withheld.size
    keep = np.flatnonzero(~read.withheld)
    if scores is None:  # every trial withheld: nothing was scored
        scores = Scores(np.empty(0), np.empty(0), np.empty(0), [], *(3 * [None if surfaces is None else np.empty(0)]))
    reasons = _spread(scores.reasons, keep, n, "")
    scale = scores.scale.reason() if scores.scale is not None and scores.scale.off else ""
    for i in range(n):
        extra = read.withheld_reasons[i] or read.orientation_reasons[i]
        if read.withheld[i] and scale:  # every row says the scale is off, a withheld one too
            extra = f"{extra}; {scale}"
        reasons[i] = f"{reasons[i]}; {extra}" if reasons[i] and extra else reasons[i] or extra
    return Scores(_spread(scores.roughness, keep, n), _spread(scores.low, keep, n), _spread(scores.high, keep, n),
                  reasons, _spread(scores.surface_roughness, keep, n), _spread(scores.surface_low, keep, n),
                  _spread(scores.surface_high, keep, n), scale=scores.scale,
                  method=_spread(scores.method, keep, n, ""), surface_method=_spread(scores.surface_method, keep, n, ""),
                  withheld=read.withheld, orientation_deg=read.orientation_deg, contact_p=read.contact_p,
                  gated=read.gated)


def _spread(values, keep: np.ndarray, n: int, fill=math.nan):
    """Kept trials' values back in their places among ``n`` trials, ``fill`` in the withheld ones."""
    if values is None:
        return None
    if isinstance(values, list):
        out = [fill] * n
        for i, v in zip(keep, values):
            out[i] = v
        return out
    out = np.full(n, fill, dtype=float)
    out[keep] = values
    return out


#: ``--roi auto`` on images whose field along the line differs from the model's by more than this warns.
FIELD_TOLERANCE = 0.20


def warn_field_of_view(loaded: FittedModel, override: SensorOverride | None, images: Sequence) -> float | None:
    """With ``--roi auto``, warn when the first image's field along the line (crop width / px_per_mm, in mm) differs
    from the model's by more than :data:`FIELD_TOLERANCE`: the spectrum then averages over a different length of
    contact, so amplitudes shift even where the grating is the same. Returns the relative difference (or None).

    The first image that can be read is measured: one that cannot is a withheld row already, never an abort here."""
    import warnings

    from ..defaults import CENTER_CROP_PX
    from ..errors import RoughsenseWarning

    first = _first_size(images) if override is not None and override.roi == "auto" else None
    if first is None or first[1] is None:
        return None
    image, size = first
    stored = loaded.model_file_.features["spectrum"]
    roi = stored["roi"]
    model_mm = (roi[2] if not isinstance(roi, str) else CENTER_CROP_PX[0]) / float(stored["px_per_mm"])
    px_per_mm = override.px_per_mm or float(stored["px_per_mm"])
    field_mm = min(CENTER_CROP_PX[0], size[0]) / px_per_mm
    change = field_mm / model_mm - 1
    if abs(change) > FIELD_TOLERANCE:
        warnings.warn(RoughsenseWarning(
            f"--roi auto reads {field_mm:.1f} mm of line in {Path(image).name}, the model was trained on "
            f"{model_mm:.1f} mm ({change:+.0%}): spectra over a different field are not comparable; crop the images "
            "to the model's field (--roi X,Y,W,H) or fit a model on images like these"), stacklevel=2)
    return change


def _first_size(images: Sequence):
    """(path, (width, height) from its header, or None) of the first image whose file reads; None for arrays, or
    when no file reads."""
    from ..io.images import header_size, read_bytes

    for image in images:
        if not isinstance(image, (str, os.PathLike)):
            return None
        try:
            return image, header_size(read_bytes(image))
        except InputError:
            continue  # unreadable: its row says so
    return None


def frame_scorer(loaded: FittedModel, override: SensorOverride | None = None
                 ) -> Callable[[np.ndarray], tuple[float, str]]:
    """Live mode's scorer: one camera frame (an array) -> (roughness, why it lies outside the model's domain, ''
    where it lies inside: the reason predict gives the same image read alone), the spectrum built once."""
    if len(loaded.conditions) != 1:
        raise ConfigError(
            f"live scoring needs a single-force model; this one combines {', '.join(loaded.conditions)} "
            "(fit one with --condition 1N, 2N or 3N)"
        )
    from .contact_gate import orientation_reason
    from .gate_file import model_gate
    from .outside import domain_reasons
    from .press_gate import described_contact

    spectrum = model_spectrum(loaded, override=override)
    gate, ridge, contact = model_gate(loaded), model_ridge_period_mm(loaded), reads_contact(loaded)

    def score_frame(frame: np.ndarray) -> tuple[float, str]:
        [reading] = list(spectrum.iter_readings([frame], ridge_period_mm=ridge))
        if isinstance(reading, InputError):
            raise reading
        row, line, described = reading
        if gate is not None:  # a frame the gate withholds gets no number, as predict's row gets none
            values = np.array([described[name] for name in gate.names])
            p = float(gate.p_values(values[None, :])[0])
            if gate.withholds(values[None, :], p)[0]:
                return math.nan, f"withheld: {gate.reason(values, p)}"
        X = row[None, :]
        measures = contact_inputs(loaded, described_contact([described]) if contact else None)
        reasons = [r for r in (str(domain_reasons(loaded, spectrum, [line], X, ridge_period_mm=ridge,
                                                  contact=measures)[0]),
                               orientation_reason(described["orientation_deg"])) if r]
        return float(loaded.predict(X, **measures)[0]), "; ".join(reasons)

    return score_frame


def score_images(loaded: FittedModel, images: Sequence, *, n_jobs: int = 1, progress=None,
                 override: SensorOverride | None = None) -> np.ndarray:
    """Predicted perceived roughness, one value per image (per trial of k images for a k-force model)."""
    X, _, _, contact = image_readings(loaded, images, n_jobs=n_jobs, progress=progress, override=override)
    return loaded.predict(X, **contact)


def image_readings(loaded: FittedModel, images: Sequence, *, n_jobs: int = 1, progress=None,
                   override: SensorOverride | None = None):
    """The model's inputs, one row per image (per trial of k images for a k-force model), with each image's gray
    line, the SpatialSpectrum that read them (the band and scale checks read the lines, at no second decoding) and
    the contact keyword of a family that reads the contact (:func:`contact_inputs`).

    ``images`` are paths or arrays. ``progress(iterable, total=, description=)`` may wrap the image stream
    (the CLI passes its progress display); ``override`` reads the line elsewhere or at another scale.
    """
    images = list(images)
    group_images(loaded, images)  # refuse a wrong count before any decoding
    spectrum = model_spectrum(loaded, n_jobs=n_jobs, override=override)
    contact = reads_contact(loaded)
    stream = (spectrum.iter_readings(images, ridge_period_mm=model_ridge_period_mm(loaded)) if contact
              else spectrum.iter_transform_lines(images))
    if progress is not None:
        stream = progress(stream, total=len(images), description="spectra")
    readings = list(stream)
    refused = next((r for r in readings if isinstance(r, InputError)), None)
    if refused is not None:
        raise refused
    spectra = np.vstack([r[0] for r in readings]) if readings else np.empty((0, spectrum.freq_per_mm_.size))
    measures = None
    if contact:
        from .press_gate import described_contact

        measures = described_contact([r[2] for r in readings])
    return (spectra_to_features(loaded, spectra), [r[1] for r in readings], spectrum,
            contact_inputs(loaded, measures))
