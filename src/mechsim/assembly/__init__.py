"""Constraint systems assembled from per-type kernels (`model.AssembledModel`): what makes
a new mechanism of any size ready without a sympy run or a compiler, once its joint types
have been seen on the machine."""

from .model import AssembledModel, type_key

__all__ = ["AssembledModel", "type_key"]
