"""roughsense: perceived macroscopic roughness from contact images (spatial coding).

Reference implementation of Yanwari & Okamoto, Sensors 25:2598 (2025), with a digital twin of the rig.
The public names below are imported lazily so that ``import roughsense`` (and the CLI's startup)
does not pay for scikit-learn, OpenCV or matplotlib until they are used; ``dir(roughsense)`` lists them
all (and tab completion offers them) before any is loaded. Each has numpydoc sections with examples, and
``make docs`` renders them as the API reference (build/api).
"""
from __future__ import annotations

import importlib

from .errors import ConfigError, InputError, ModelFileError, OutputExistsError, RoughsenseError

__version__ = "0.1.0"

_LAZY = {
    "SpatialSpectrum": "sensor.spectrum",
    "spatial_spectrum": "sensor.spectrum",
    "frequency_grid": "sensor.spectrum",
    "SIMPLS": "model.pls",
    "pls_cv": "model.pls_cv",
    "pls_cv_many": "model.pls_cv",
    "PeakPowerLaw": "model.peak_law",
    "peak_law_cv": "model.peak_law",
    "SpreadModel": "analysis.spread",
    "load_model": "model.modelfile",
    "overlap": "analysis.metrics",
    "analyse_study": "analysis.study_analysis",
    "read_study": "io.study",
    "StudyWriter": "io.writer",
    "simulate_study": "sim",
}

__all__ = [
    "__version__",
    "RoughsenseError",
    "InputError",
    "ConfigError",
    "ModelFileError",
    "OutputExistsError",
    *_LAZY,
]


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'roughsense' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The public API and the module's own dunders: what ``dir()`` and tab completion show, loaded or not."""
    return sorted({*__all__, "__all__", "__doc__", "__file__", "__name__", "__path__"})
