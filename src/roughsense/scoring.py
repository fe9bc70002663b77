"""Scoring images with a loaded model: the one path shared by ``roughsense predict`` and live mode.

The model file carries its feature definition, so the spectra are recomputed exactly as in training;
a combined-force model takes each trial's images in the order of its conditions (1 N, 2 N, 3 N).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .errors import InputError
from .modelfile import LoadedModel, check_features, feature_definition_for


def model_spectrum(loaded: LoadedModel, *, n_jobs: int = 1):
    """The SpatialSpectrum the model was trained with, rebuilt from its file (and checked against it)."""
    from .sensor import SpatialSpectrum

    spectrum = SpatialSpectrum.from_definition(loaded.features["spectrum"], n_jobs=n_jobs).fit()
    check_features(loaded, feature_definition_for(spectrum, loaded.conditions))
    return spectrum


def group_images(loaded: LoadedModel, images: Sequence) -> list[tuple]:
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


def spectra_to_features(loaded: LoadedModel, spectra: np.ndarray) -> np.ndarray:
    """(n_images, n_freqs) spectra in trial order -> (n_trials, n_features) model inputs."""
    from .sensor import combine_forces

    k = len(loaded.conditions)
    spectra = np.asarray(spectra, dtype=np.float64)
    return combine_forces([spectra[i::k] for i in range(k)]) if k > 1 else spectra


def score_images(loaded: LoadedModel, images: Sequence, *, n_jobs: int = 1, spectrum=None,
                 progress=None) -> np.ndarray:
    """Predicted perceived roughness, one value per image (per trial of k images for a k-force model).

    ``images`` are paths or arrays. Pass a prebuilt ``spectrum`` (from :func:`model_spectrum`) when
    scoring frame after frame, so the feature check runs once. ``progress(iterable, total=, description=)``
    may wrap the image stream (the CLI passes its progress display).
    """
    images = list(images)
    group_images(loaded, images)  # refuse a wrong count before any decoding
    spectrum = spectrum if spectrum is not None else model_spectrum(loaded, n_jobs=n_jobs)
    if progress is None:
        spectra = spectrum.transform(images)
    else:
        spectra = np.vstack(list(progress(spectrum.iter_transform(images), total=len(images), description="spectra")))
    return loaded.predict(spectra_to_features(loaded, spectra))
