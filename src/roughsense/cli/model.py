"""Old home of ``roughsense fit`` and ``roughsense predict``, now cli/fit.py and cli/predict.py (the predict table:
model/predict_table.py); it registers nothing."""
from __future__ import annotations

# re-exported for one release
from .fit import _warn_failed_controls, fit, parse_condition  # noqa: F401
from .image_flags import split_image_flags as _split_image_flags  # noqa: F401
from .predict import EXTRAPOLATION_WHY, few_presses_line, predict  # noqa: F401


def __getattr__(name: str):
    """``roughness_column``, re-exported for one release without loading NumPy for ``--help``."""
    if name == "roughness_column":
        from ..model.predict_table import roughness_column

        return roughness_column
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
