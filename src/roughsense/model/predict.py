"""Scoring images with a loaded model: the one path shared by ``roughsense predict`` and live mode.

The model file carries its feature definition, so the spectra are recomputed exactly as in training;
a combined-force model takes each trial's images in the order of its conditions (1 N, 2 N, 3 N).
Every model also says, per prediction, what lies outside what it was trained on (its applicability domain: a peak
law's period, peak strength or an unclear peak; PLS's spectrum shape, or a value held to the trained roughness), and
a model file with an interval gives each prediction its 90 % prediction interval: a surface's (and a press read alone)
the jackknife+ over specimens (model/jackknife_file.py), a press read with its surface's others the plain jackknife
(model/interval.py).
:func:`score_images` trusts that order; model/trials.py builds it from what a user gives (a manifest, one flag per
force) and refuses what contradicts a slot.
"""
from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ConfigError, InputError
from .modelfile import FittedModel, check_features, feature_definition_for

if TYPE_CHECKING:
    from ..io.sensor_settings import Roi


@dataclass(frozen=True)
class SensorOverride:
    """Where the line is read (``roi``) and the images' scale (``px_per_mm``), given at scoring time in place of
    the model's.

    Both only change how an image becomes a line in mm: the spectrum itself (band and grid in mm^-1, window, rows,
    normalisation) stays the model's, so the features mean what they meant in training. A scale is refused where
    the model's band cannot be measured (f_max at or above Nyquist here; a line shorter than 1/f_min, per image).
    """

    roi: Roi | None = None
    px_per_mm: float | None = None

    @classmethod
    def parse(cls, roi: str | None = None, px_per_mm: float | None = None) -> SensorOverride | None:
        """From ``--roi`` and ``--px-per-mm`` as given (None when neither was): each refused in one line naming it."""
        from .._util.checks import POSITIVE, check
        from ..io.sensor_settings import parse_roi

        if roi is None and px_per_mm is None:
            return None
        if roi is not None:
            try:
                roi = parse_roi(roi)
            except ConfigError as exc:
                raise ConfigError(f"--roi: {exc.message}") from None
        if px_per_mm is not None:
            px_per_mm = check(px_per_mm, POSITIVE, name="--px-per-mm", must="a positive number (px/mm)")
        return cls(roi, px_per_mm)

    def fields(self) -> dict:
        """The feature-definition fields this override replaces (JSON values, as a model file stores them)."""
        given = {}
        if self.roi is not None:
            given["roi"] = self.roi if isinstance(self.roi, str) else list(self.roi)
        if self.px_per_mm is not None:
            given["px_per_mm"] = float(self.px_per_mm)
        return given


def model_spectrum(loaded: FittedModel, *, n_jobs: int = 1, override: SensorOverride | None = None):
    """The SpatialSpectrum the model was trained with, rebuilt from its file (and checked against it).

    With ``override``, the checked definition is then read where and at the scale the override says.
    """
    from ..sensor.spectrum import SpatialSpectrum

    stored = loaded.model_file_.features["spectrum"]
    spectrum = SpatialSpectrum.from_definition(stored, n_jobs=n_jobs).fit()
    check_features(loaded, feature_definition_for(spectrum, loaded.conditions))
    if override is None:
        return spectrum
    f_max = float(spectrum.freq_per_mm_[-1])
    if override.px_per_mm is not None and f_max >= override.px_per_mm / 2:
        raise ConfigError(f"--px-per-mm {override.px_per_mm:g}: the model's band reaches {f_max:g} mm^-1, not below "
                          f"the Nyquist frequency {override.px_per_mm / 2:g} mm^-1 of images at that scale",
                          path=loaded.path)
    return SpatialSpectrum.from_definition({**stored, **override.fields()}, n_jobs=n_jobs).fit()


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


def image_features(loaded: FittedModel, images: Sequence, *, n_jobs: int = 1, progress=None,
                   override: SensorOverride | None = None) -> np.ndarray:
    """The model's inputs, one row per image (per trial of k images for a k-force model).

    ``images`` are paths or arrays. ``progress(iterable, total=, description=)`` may wrap the image stream
    (the CLI passes its progress display); ``override`` reads the line elsewhere or at another scale.
    """
    return image_readings(loaded, images, n_jobs=n_jobs, progress=progress, override=override)[0]


def image_readings(loaded: FittedModel, images: Sequence, *, n_jobs: int = 1, progress=None,
                   override: SensorOverride | None = None):
    """:func:`image_features`, with each image's gray line and the SpatialSpectrum that read them (the band and
    scale checks read the lines, at no second decoding)."""
    images = list(images)
    group_images(loaded, images)  # refuse a wrong count before any decoding
    spectrum = model_spectrum(loaded, n_jobs=n_jobs, override=override)
    stream = spectrum.iter_transform_lines(images)
    if progress is not None:
        stream = progress(stream, total=len(images), description="spectra")
    pairs = list(stream)
    spectra = np.vstack([p[0] for p in pairs]) if pairs else np.empty((0, spectrum.freq_per_mm_.size))
    return spectra_to_features(loaded, spectra), [p[1] for p in pairs], spectrum


def model_ridge_period_mm(loaded: FittedModel) -> float | None:
    """The ridge period (mm) of the model's pad, or None for a smooth pad (or a file that does not say)."""
    training = loaded.training if isinstance(loaded.training, dict) else {}
    stated = training.get("pad_ridge_period_mm", getattr(loaded, "pad_ridge_period_mm", None))
    domain = getattr(loaded, "domain_", None)
    if stated is None and domain is not None and domain.peak is not None:
        stated = domain.peak.pad_ridge_period_mm
    return float(stated) if isinstance(stated, (int, float)) and stated > 0 else None


def trial_band_reasons(loaded: FittedModel, spectrum, lines: list, surfaces=None, *, dominance: float | None = None
                       ) -> list[str]:
    """Per trial, why its structure lies outside the spectrum's band ('' where it lies inside): the one band test
    (``sensor/band.py``) every family's predictions pass, a trial read from the medians of its images."""
    from ..sensor.band import DOMINANCE, band_reading, band_reasons, median_reading

    freq = spectrum.freq_per_mm_
    f_min, f_max = float(freq[0]), float(freq[-1])
    ridge = model_ridge_period_mm(loaded)
    readings = [band_reading(line, float(spectrum.px_per_mm), f_min, f_max, ridge_period_mm=ridge) for line in lines]
    k = len(loaded.conditions)
    trials = [median_reading(readings[i:i + k]) for i in range(0, len(readings), k)]
    return band_reasons(trials, f_min, f_max, surfaces, dominance=DOMINANCE if dominance is None else dominance)


def score_images(loaded: FittedModel, images: Sequence, *, n_jobs: int = 1, progress=None,
                 override: SensorOverride | None = None) -> np.ndarray:
    """Predicted perceived roughness, one value per image (per trial of k images for a k-force model)."""
    return loaded.predict(image_features(loaded, images, n_jobs=n_jobs, progress=progress, override=override))


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


def model_interval(loaded: FittedModel):
    """The model file's prediction interval, or None (a file written before intervals, or too few specimens for a
    trial's). Its fields were checked when the file was loaded (``interval.SCHEMA``, model/schema.py): null is too
    few residuals for the level (no bound; ``alone_log_halfwidth`` absent or null: not known)."""
    from .interval import PredictionInterval

    stored = loaded.training.get("interval") if isinstance(loaded.training, dict) else None
    if stored is None:
        return None

    def width(name: str, missing: float) -> float:
        value = stored.get(name)
        return missing if value is None else float(value)

    interval = PredictionInterval(width("trial_log_halfwidth", math.inf), width("surface_log_halfwidth", math.inf),
                                  float(stored["level"]),
                                  alone_log_halfwidth=width("alone_log_halfwidth", math.nan))
    return interval if math.isfinite(interval.trial_log_halfwidth) else None


def domain_reasons(loaded: FittedModel, spectrum, lines: list, X: np.ndarray, surfaces=None) -> list[str]:
    """Why each trial lies outside the model's domain ('' where it lies inside): the band's reason first, then the
    family's own, named by the band when the structure outside it is at least as strong as the band's own peak.
    Shared by predict's trials and live mode's frames, so a frame says what its image would say."""
    from ..sensor.band import NAMING_DOMINANCE

    band = trial_band_reasons(loaded, spectrum, lines, surfaces)
    named = trial_band_reasons(loaded, spectrum, lines, surfaces, dominance=NAMING_DOMINANCE)
    return [b or (n if f else "") or f for b, n, f in zip(band, named, loaded.applicability(X, surfaces=surfaces))]


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
    from .press_gate import read_trials

    images = list(images)
    group_images(loaded, images)  # refuse a wrong count before any decoding
    spectrum = model_spectrum(loaded, n_jobs=n_jobs, override=override)
    read = read_trials(loaded, spectrum, images, progress=progress)
    kept = ~read.withheld
    keep = np.flatnonzero(kept)
    if reference is not None:
        reference = (reference[0], np.asarray(reference[1])[keep])
    kept_surfaces = None if surfaces is None else np.asarray(surfaces)[keep]
    scores = _score_kept(loaded, spectrum, read.spectra, read.lines, kept_surfaces, reference) if keep.size else None
    return _with_withheld(scores, read, surfaces)


def _score_kept(loaded: FittedModel, spectrum, spectra: np.ndarray, lines: list, surfaces, reference) -> Scores:
    """The trials the gate let through, scored as predict always scored a batch."""
    X = spectra_to_features(loaded, spectra)
    roughness = loaded.predict(X, surfaces=surfaces)
    reasons = domain_reasons(loaded, spectrum, lines, X, surfaces)
    scale = images_scale_check(loaded, spectrum, lines, reference)
    if scale.off:
        reasons = [f"{r}; {scale.reason()}" if r else scale.reason() for r in reasons]
    low, high, method = trial_intervals(loaded, X, roughness, surfaces)
    if surfaces is None:
        return Scores(roughness, low, high, reasons, scale=scale, method=method)
    import pandas as pd

    surface = pd.Series(roughness).groupby(pd.Series(np.asarray(surfaces))).transform("mean").to_numpy()
    s_low, s_high, s_method = surface_intervals(loaded, X, surface, surfaces)
    return Scores(roughness, low, high, reasons, surface, s_low, s_high, scale=scale, method=method,
                  surface_method=s_method)


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


#: How predict names the plain jackknife's interval (model/interval.py), beside the jackknife+'s.
PLAIN_METHOD = "jackknife (no coverage guarantee)"


def trial_intervals(loaded: FittedModel, X: np.ndarray, roughness: np.ndarray, surfaces=None):
    """Each trial's 90 % bounds and method: a press read alone is a surface of one press, so it gets the
    jackknife+ of one-press surfaces where the file keeps one; a press read with its surface's others gets the plain
    jackknife (the peak law reads it less surely alone: its own calibration). NaN and None without an interval."""
    from .jackknife_file import deployed_jackknife

    jackknife = deployed_jackknife(loaded) if surfaces is None else None
    if jackknife is not None and jackknife.bounded:
        return jackknife.intervals(X)
    interval = model_interval(loaded)
    if interval is None:
        nan = np.full(roughness.shape, np.nan)
        return nan, nan, None
    low, high = interval.trial_bounds(roughness, read_alone=surfaces is None)
    return low, high, [PLAIN_METHOD] * roughness.size


def surface_intervals(loaded: FittedModel, X: np.ndarray, surface: np.ndarray, surfaces):
    """Each trial's surface's 90 % bounds and method: the jackknife+ with the residuals of surfaces read from as
    many presses as this one (model/jackknife_file.py), else (an older file) the plain jackknife."""
    from .jackknife_file import deployed_jackknife

    jackknife = deployed_jackknife(loaded)
    if jackknife is not None and jackknife.bounded:
        return jackknife.intervals(X, surfaces)
    interval = model_interval(loaded)
    if interval is None or not math.isfinite(interval.surface_log_halfwidth):
        nan = np.full(surface.shape, np.nan)
        return nan, nan, None
    low, high = interval.surface_bounds(surface)
    return low, high, [PLAIN_METHOD] * surface.size


def plain_fallback_line(loaded: FittedModel) -> str:
    """One line when a file's intervals fall back to the plain jackknife: written before the jackknife+ was kept,
    or from too few specimens for it (9 at 90 %). Said, never failed."""
    from .jackknife_file import deployed_jackknife

    jackknife = deployed_jackknife(loaded)
    if model_interval(loaded) is None or (jackknife is not None and jackknife.bounded):
        return ""
    if jackknife is not None:
        return (f"the {jackknife.name} needs at least {jackknife.fewest_specimens} training specimens for a 90 % "
                "interval: these intervals are "
                f"the plain {PLAIN_METHOD}, where it has one")
    return ("this model file keeps no leave-one-specimen-out fold models (written before they were kept): its "
            f"intervals are the plain {PLAIN_METHOD}; refit it with roughsense fit for the jackknife+ over specimens")


def images_scale_check(loaded: FittedModel, spectrum, lines: list, reference=None):
    """The images' scale against the pad's ridges (every image) and the stated periods of ``reference``'s trials,
    at the scale the spectrum read them (``model/scale_check.py``)."""
    from .scale_check import check_study_lines

    groups = []
    k = len(loaded.conditions)
    mounts = [i // k for i in range(len(lines))]  # a trial's images are one mount of the surface
    ridge = model_ridge_period_mm(loaded)
    if ridge is not None:
        groups.append((f"the pad's {ridge:g} mm ridges", ridge, lines, mounts))
    if reference is not None:
        what, periods = reference
        for period_mm in dict.fromkeys(p for p in periods if np.isfinite(p)):
            chosen = [i for i in range(len(lines)) if periods[i // k] == period_mm]
            groups.append((what, float(period_mm), [lines[i] for i in chosen], [mounts[i] for i in chosen]))
    return check_study_lines(groups, float(spectrum.px_per_mm))


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

    spectrum = model_spectrum(loaded, override=override)
    gate, ridge = model_gate(loaded), model_ridge_period_mm(loaded)

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
        reasons = [r for r in (str(domain_reasons(loaded, spectrum, [line], X)[0]),
                               orientation_reason(described["orientation_deg"])) if r]
        return float(loaded.predict(X)[0]), "; ".join(reasons)

    return score_frame


#: ``--roi auto`` on images whose field along the line differs from the model's by more than this warns.
FIELD_TOLERANCE = 0.20


def warn_field_of_view(loaded: FittedModel, override: SensorOverride | None, images: Sequence) -> float | None:
    """With ``--roi auto``, warn when the first image's field along the line (crop width / px_per_mm, in mm) differs
    from the model's by more than :data:`FIELD_TOLERANCE`: the spectrum then averages over a different length of
    contact, so amplitudes shift even where the grating is the same. Returns the relative difference (or None)."""
    import warnings

    from ..defaults import CENTER_CROP_PX
    from ..errors import RoughsenseWarning
    from ..io.images import header_size, read_bytes

    if override is None or override.roi != "auto" or not images or not isinstance(images[0], (str, os.PathLike)):
        return None
    stored = loaded.model_file_.features["spectrum"]
    size = header_size(read_bytes(images[0]))
    if size is None:
        return None
    roi = stored["roi"]
    model_mm = (roi[2] if not isinstance(roi, str) else CENTER_CROP_PX[0]) / float(stored["px_per_mm"])
    px_per_mm = override.px_per_mm or float(stored["px_per_mm"])
    field_mm = min(CENTER_CROP_PX[0], size[0]) / px_per_mm
    change = field_mm / model_mm - 1
    if abs(change) > FIELD_TOLERANCE:
        warnings.warn(RoughsenseWarning(
            f"--roi auto reads {field_mm:.1f} mm of line in {Path(images[0]).name}, the model was trained on "
            f"{model_mm:.1f} mm ({change:+.0%}): spectra over a different field are not comparable; crop the images "
            "to the model's field (--roi X,Y,W,H) or fit a model on images like these"), stacklevel=2)
    return change
