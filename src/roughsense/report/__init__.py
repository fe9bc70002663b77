"""Presentation: figures (matplotlib) and the self-contained HTML report of a study analysis or a sweep.

It renders what the analysis returns and computes nothing of its own; it sits above analysis/, below explore/ and cli/.
"""
from __future__ import annotations

from .html import FigureStyle, check_report_dir, open_report_dir, write_report

__all__ = ["FigureStyle", "check_report_dir", "open_report_dir", "write_report"]
