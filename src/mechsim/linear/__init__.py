"""Linear(ised) systems M ẍ + C ẋ + K x = f(t), their state-space Newmark integration and the
accuracy and stability analysis of seed 000."""

from .rotor import Bearing, Disk, Rotor, ShaftElement, Unbalance, turbo_compressor
from .system import LINEAR_METHODS, LinearResult, LinearSystem

__all__ = ["LINEAR_METHODS", "Bearing", "Disk", "LinearResult", "LinearSystem", "Rotor",
           "ShaftElement", "Unbalance", "turbo_compressor"]
