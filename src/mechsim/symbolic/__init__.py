"""sympy layer: the constraint equations Φ(q, t; p) of a mechanism and their derivatives.

Importing this package imports sympy; nothing else in mechsim does so at import time, and a
mechanism whose compiled model is in the cache never reaches it.
"""

from .constraints import (SymbolicContext, SymbolicSystem, build_system, jacobian_of,
                          second_derivative_along)

__all__ = ["SymbolicContext", "SymbolicSystem", "build_system", "jacobian_of",
           "second_derivative_along"]
