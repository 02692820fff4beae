"""Linear(ised) systems M ẍ + C ẋ + K x = f(t), their state-space Newmark integration and the
accuracy and stability analysis of seed 000."""

from .system import LINEAR_METHODS, LinearResult, LinearSystem

__all__ = ["LINEAR_METHODS", "LinearResult", "LinearSystem"]
