"""The digital twin: specimens, pads, contact mechanics, optics, bench and participants -> a study folder.

Imports only ``roughsense.study``, ``errors`` and ``atomic`` from the rest of the package (the analysis must not
know whether a folder was simulated).
"""
from .simulate import SimulationConfig, SimulationRun, simulate_study

__all__ = ["SimulationConfig", "SimulationRun", "simulate_study"]
