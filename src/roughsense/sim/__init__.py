"""The digital twin: specimens, pads, contact mechanics, optics, bench, simulated finger and panel -> a study folder.

A source of study folders like the rig: it writes through ``io/`` and never imports the analysis or the models, so
the analysis cannot tell a simulated folder from a captured one except by its ``[simulation]`` table. The public
names load lazily, so the CLI can read the pads' defaults from ``sim.pads`` cheaply.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["SimulationConfig", "SimulationRun", "simulate_study"]

if TYPE_CHECKING:
    from .config import SimulationConfig
    from .simulate import SimulationRun, simulate_study


def __getattr__(name: str):
    """Each name from the module that defines it, imported by name (code fingerprints follow these imports)."""
    if name == "SimulationConfig":
        from .config import SimulationConfig

        return SimulationConfig
    if name in __all__:
        from . import simulate

        return getattr(simulate, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
