"""Figures and the self-contained HTML report of a study analysis."""
from __future__ import annotations

from .html import write_report

__all__ = ["write_report"]
