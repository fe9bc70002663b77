"""The digital twin: specimens, pads, contact mechanics, optics, bench and participants -> a study folder.

Imports only ``roughsense.study``, ``errors`` and ``atomic`` from the rest of the package (the analysis must not
know whether a folder was simulated). The public names load lazily, so the CLI can read the presets and defaults
from ``sim.specimens`` and ``sim.pads`` without importing the whole simulator.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["SimulationConfig", "SimulationRun", "simulate_study"]

if TYPE_CHECKING:
    from .simulate import SimulationConfig, SimulationRun, simulate_study


def __getattr__(name: str):
    if name in __all__:
        from . import simulate

        return getattr(simulate, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
