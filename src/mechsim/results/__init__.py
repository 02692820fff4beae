"""Simulation results: data accessors, energy log, plots, save and export
(`mechsim.load_result` reads them back)."""

from ..records import SingularPassage, Status, Switch
from .result import EnergyLog, SimulationResult

__all__ = ["EnergyLog", "SimulationResult", "SingularPassage", "Status", "Switch"]
