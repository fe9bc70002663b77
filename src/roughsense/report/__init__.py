"""Figures and the self-contained HTML report of a study analysis."""
from __future__ import annotations

from .html import check_report_dir, open_report_dir, write_report

__all__ = ["check_report_dir", "open_report_dir", "write_report"]
