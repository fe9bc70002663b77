"""Design sweeps of the twin on Dask: one in-memory study per cell, a Parquet store, the sweep's own report.

It composes ``sim/`` with ``analysis/`` per cell, above both; only ``cli/`` imports it. ``read_sweep`` checks a sweep
file, ``run_sweep`` computes its cells, ``write_explore_report`` summarises them (docs/explore.md).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["read_sweep", "run_sweep", "run_cell", "write_explore_report"]

if TYPE_CHECKING:
    from .cell import run_cell
    from .runner import run_sweep
    from .sweep import read_sweep
    from .write_report import write_explore_report

_HOME = {"read_sweep": "sweep", "run_sweep": "runner", "run_cell": "cell", "write_explore_report": "write_report"}


def __getattr__(name: str):
    if name in _HOME:
        import importlib

        return getattr(importlib.import_module(f".{_HOME[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
