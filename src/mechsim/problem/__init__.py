"""The constrained equations of motion in numbers (`NumericProblem`) and their parts: the mass
and the constraint forces' Schur complement (`mass`), and the loads (`loads`)."""

from .loads import FlexibleData, Loads, PointLoad, RotationalSpringData, SpringData
from .mass import MassFactor, MassModel, SchurSolver
from .numeric import Counters, NumericProblem

__all__ = ["Counters", "FlexibleData", "Loads", "MassFactor", "MassModel", "NumericProblem",
           "PointLoad", "RotationalSpringData", "SchurSolver", "SpringData"]
