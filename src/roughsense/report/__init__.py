"""Presentation: figures (matplotlib) and the self-contained HTML report of a study analysis or a sweep.

It renders what the analysis returns and computes nothing of its own; it sits above analysis/, below explore/ and cli/.
The names below are imported on first use, so a light renderer (the ratings sheet) does not load matplotlib.
"""
from __future__ import annotations

import importlib

__all__ = ["FigureStyle", "check_report_dir", "open_report_dir", "write_report", "write_report_files"]


def __getattr__(name: str):
    if name not in __all__:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(".html", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
