"""Periodic steady states by shooting (seed 002): g(u) = x(0) − x(T) = 0.

    sol = mechsim.shooting.solve(problem, guess, method="warner" | "newton", tol=1e-6)

"warner" is Warner's algorithm of the paper's appendix (a multidimensional secant method);
"newton" is quasi-Newton: the Jacobian ∂g/∂u by forward differences of the flow, then
Broyden's rank-one updates while they converge, or the exact Jacobian where the problem
knows its monodromy; steps are halved until ‖g‖ decreases. Both return a ShootingResult
with the one-period trajectory and the Floquet multipliers.
"""

from .regime import RegimeMap, regime_map
from .solve import SHOOTING_METHODS, ShootingResult, monodromy, solve

__all__ = ["SHOOTING_METHODS", "RegimeMap", "ShootingResult", "monodromy", "regime_map", "solve"]
