"""Simulation results: data accessors, energy log, plots, save and export
(`mechsim.load_result` reads them back)."""

from .result import EnergyLog, SimulationResult, SingularPassage, Switch

__all__ = ["EnergyLog", "SimulationResult", "SingularPassage", "Switch"]
