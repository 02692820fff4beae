"""Simulation results: data accessors, energy log, plots, save/load and export."""

from .result import EnergyLog, SimulationResult, SingularPassage, Switch
from .saved import load_result

__all__ = ["EnergyLog", "SimulationResult", "SingularPassage", "Switch", "load_result"]
