"""roughsense: perceived macroscopic roughness from contact images (spatial coding).

Reference implementation of Yanwari & Okamoto, Sensors 25:2598 (2025), with a digital twin of the rig.
The public names below are imported lazily so that ``import roughsense`` (and the CLI's startup)
does not pay for scikit-learn, OpenCV or matplotlib until they are used.
"""
from __future__ import annotations

import importlib

from .errors import ConfigError, InputError, ModelFileError, OutputExistsError, RoughsenseError

__version__ = "0.1.0"

_LAZY = {
    "SpatialSpectrum": "sensor",
    "spatial_spectrum": "sensor",
    "frequency_grid": "sensor",
    "SIMPLS": "pls",
    "pls_cv": "pls",
    "pls_cv_many": "pls",
    "SpreadModel": "spread",
    "load_model": "modelfile",
    "overlap": "metrics",
    "read_study": "study",
    "StudyWriter": "study",
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
