"""Newton's iteration on the constraints Φ(q, t) = 0: the one loop every projector uses.

Each caller brings its own correction (the mass metric's Schur complement, its truncated
pseudo-inverse near a singular configuration, the dependent coordinates' chord on Φ_q D, a
least-squares step); the loop owns the rules for when to stop, which are also handed to the
compiled evaluations (`mechsim.codegen.engine`) at call time, so that both paths decide alike:

- converged: ‖Φ‖∞ ≤ tol;
- stalled at round-off (with ``stall=True``): the residual no longer halves
  (`STALL_RATIO`) and is within `STALL_SPAN` tol. A tolerance below the round-off of
  large coordinates (a 20 m chain settles at ‖Φ‖ ≈ 7e-15) is then met as closely as the
  arithmetic allows instead of iterating to the limit;
- a chord that converges too slowly (with ``contraction``): the residual shrank by less than
  `CHORD_CONTRACTION` in one iteration, so the factor in use no longer describes Φ_q; the
  correction is told (``slow=True``) and may take a fresh Jacobian or give up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

# A chord iteration must shrink ‖Φ‖∞ at least this much, or its factor is stale.
CHORD_CONTRACTION = 0.25
# Round-off: the residual shrinks by less than half and lies within STALL_SPAN · tol.
STALL_RATIO = 0.5
STALL_SPAN = 1e3


def newton_stalled(err, prev, tol, round_off: float | None = None):
    """Has a Newton iteration on Φ reached round-off (see the module docstring)? Within
    `round_off` of zero if given, else within `STALL_SPAN` tol. Elementwise where the
    residuals are arrays (several iterations side by side)."""
    return (err > STALL_RATIO * prev) & (err <= (STALL_SPAN * tol if round_off is None
                                                 else round_off))


def max_abs(phi) -> float:
    """‖Φ‖∞ (0 for no constraints; NaN where Φ has a NaN)."""
    phi = np.asarray(phi)
    return float(np.abs(phi).max()) if phi.size else 0.0


@dataclass
class NewtonResult:
    """x: the last iterate; aux: what `residual` returned beside Φ there; iterations: the
    corrections applied; residual: ‖Φ‖∞ at x; converged: whether a stopping rule (tol, or
    round-off with ``stall``) was met, not the iteration limit, a non-finite residual or a
    correction that gave up."""
    x: Any
    aux: Any
    iterations: int
    residual: float
    converged: bool


def newton(x, residual: Callable, correct: Callable, tol: float, max_iter: int, *,
           stall: bool = False, round_off: float | None = None,
           contraction: float | None = None, extra: int = 0) -> NewtonResult:
    """Iterate x ← correct(x, Φ, aux, slow) until Φ(x) = 0 within `tol`.

    Parameters
    ----------
    x : the starting iterate (any type `correct` understands; returned objects are new)
    residual : x -> (Φ, aux); aux is whatever the correction needs from the same
        evaluation (Φ_q from shared subexpressions, the assembled q, …)
    correct : (x, Φ, aux, slow) -> the next iterate, or None to give up; `slow` is True
        where the residual shrank by less than `contraction` in the last iteration
    tol, max_iter : stop at ‖Φ‖∞ ≤ tol; at most max_iter corrections
    stall : also stop (converged) at round-off, `newton_stalled`
    round_off : the residual under which a stall counts as round-off (default
        `STALL_SPAN` tol)
    contraction : the factor by which each iteration must shrink ‖Φ‖∞ (`CHORD_CONTRACTION`
        for a chord), or None for no such test
    extra : corrections applied after convergence (a projection that should land below
        its tolerance by a margin)
    """
    prev = math.inf
    k = 0
    while True:
        try:
            phi, aux = residual(x)
        except (ValueError, OverflowError, ZeroDivisionError):
            # The iterate left the functions' domain (cos of an infinite angle): diverged.
            return NewtonResult(x, None, k, math.nan, False)
        err = max_abs(phi)
        if err <= tol or (stall and newton_stalled(err, prev, tol, round_off)):
            break
        if k == max_iter or not math.isfinite(err):
            return NewtonResult(x, aux, k, err, False)
        slow = contraction is not None and not err <= contraction * prev
        nxt = correct(x, phi, aux, slow)
        if nxt is None:
            return NewtonResult(x, aux, k, err, False)
        x, prev, k = nxt, err, k + 1
    for _ in range(extra):
        nxt = correct(x, phi, aux, False)
        if nxt is None:
            return NewtonResult(x, aux, k, err, False)
        x = nxt
        phi, aux = residual(x)
        err, k = max_abs(phi), k + 1
    return NewtonResult(x, aux, k, err, True)
