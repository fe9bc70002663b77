"""The model families, chosen by name wherever a model is chosen (``--model``, model files, the ``model`` column).

``pls`` is the paper's PLS1 (SIMPLS) on the spectral amplitudes: the paper's reproduction and design sweeps use it
(:data:`PAPER_MODEL`). ``peak-law`` is :class:`roughsense.model.peak_law.PeakPowerLaw`, built to predict surfaces the
model never saw; it passes its controls for unseen surfaces where PLS fails them, so ``fit`` writes it unless told
otherwise (:data:`DEFAULT_MODEL`). This module imports
nothing heavy, so the command line can list and check the names without loading scikit-learn.
"""
from __future__ import annotations

from ..errors import ConfigError

PLS = "pls"
PEAK_LAW = "peak-law"
#: Every family, the paper's first.
MODEL_FAMILIES = (PLS, PEAK_LAW)
#: What ``roughsense fit`` writes unless --model says otherwise: the family that answers "how rough does a surface I
#: never trained on feel?" (the study's "surfaces never seen" section judges it).
DEFAULT_MODEL = PEAK_LAW
#: The paper's model: its reproduction and the design sweeps' default family.
PAPER_MODEL = PLS


def check_model_name(name: object, *, option: str = "--model") -> str:
    """The family's name, case-insensitive; anything else is one line naming the choices."""
    text = str(name).strip().lower() if isinstance(name, str) else None
    if text not in MODEL_FAMILIES:
        raise ConfigError(f"{option} must be one of {', '.join(MODEL_FAMILIES)}, got {name!r}")
    return text
