"""roughsense: perceived macroscopic roughness from contact images of a compliant pad (spatial coding).

Reference implementation of Yanwari & Okamoto, Sensors 25:2598 (2025), with a digital twin of the rig.

From images to perceived roughness, the five calls a newcomer needs:

1. ``simulate_study(out, config, force=False)``: the digital twin writes a study folder (a rig's folder, or
   yours, reads the same).
2. ``read_study(folder)``: read and validate a study folder (images, manifest, specimens, ratings).
3. ``analyse_study(study)``: the paper's analysis, as ``roughsense study`` runs it: per-specimen results,
   controls and the paper's claims.
4. ``load_model(path)``: a model file that ``roughsense fit`` wrote, validated on load.
5. ``predict(model, images, study=...)``: a fitted model's table of perceived roughness, interval and flags per
   trial, as ``roughsense predict`` writes it (``roughsense.model.predict.predict``).

Then the estimators (``SpatialSpectrum``: image -> spectrum; ``SIMPLS``; ``PeakPowerLaw``; ``SpreadModel``), the
functions behind them, ``__version__`` and the errors. Each name has numpydoc sections with a running example, and
``make docs`` renders them as the API reference (build/api).
"""
from __future__ import annotations

import lazy_loader

from .errors import ConfigError, InputError, ModelFileError, OutputExistsError, RoughsenseError

__version__ = "0.1.0"

# The public names are imported on first use (lazy_loader, SPEC 1), so that ``import roughsense`` and the CLI's
# startup do not pay for scikit-learn, OpenCV or matplotlib until they are needed. ``dir(roughsense)`` lists them
# all, loaded or not, and tab completion offers them.
__getattr__ = lazy_loader.attach(__name__, submod_attrs={
    "sim": ["simulate_study"],
    "io.study": ["read_study"],
    "analysis.study_analysis": ["analyse_study"],
    "model.modelfile": ["load_model"],
    "model.predict": ["predict"],
    "sensor.spectrum": ["SpatialSpectrum"],
    "sensor.line": ["spatial_spectrum"],
    "sensor.grid": ["frequency_grid"],
    "model.pls.simpls": ["SIMPLS"],
    "model.peak_law.law": ["PeakPowerLaw"],
    "model.peak_law.cv": ["peak_law_cv"],
    "analysis.spread": ["SpreadModel"],
    "model.pls.cv": ["pls_cv", "pls_cv_many"],
    "analysis.metrics": ["overlap"],
    "io.writer": ["StudyWriter"],
})[0]

__all__ = [
    # the calls from images to perceived roughness
    "simulate_study",
    "read_study",
    "analyse_study",
    "load_model",
    "predict",
    # the estimators, then the functions behind them
    "SpatialSpectrum",
    "SIMPLS",
    "PeakPowerLaw",
    "SpreadModel",
    "spatial_spectrum",
    "frequency_grid",
    "pls_cv",
    "pls_cv_many",
    "peak_law_cv",
    "overlap",
    "StudyWriter",
    "__version__",
    "RoughsenseError",
    "InputError",
    "ConfigError",
    "ModelFileError",
    "OutputExistsError",
]


def __dir__() -> list[str]:
    """The public API and the module's own dunders: what ``dir()`` and tab completion show, loaded or not."""
    return sorted({*__all__, "__all__", "__doc__", "__file__", "__name__", "__path__"})
