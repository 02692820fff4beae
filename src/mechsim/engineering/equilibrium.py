"""Static equilibrium: where a mechanism rests under gravity, springs and constant loads.

In the independent coordinates z of `ReducedCoordinates` the mechanism is at rest in
equilibrium where the generalized force g(z) = Rᵀ Q(t, q(z), 0) vanishes: the applied
forces then lie in the range of Φ_qᵀ, balanced by the joints. g is solved by Powell's hybrid
method (MINPACK's hybrd through `scipy.optimize.root`) from the assembled state; where that
fails, or finds an unstable equilibrium from an assembled state that was not at rest (a
pendulum drawn tilted upwards), by continuation on the fixed-point homotopy

    H(z, s) = s g(z) + (1 − s) K₀ (z₀ − z),   s: 0 → 1,

from z₀ (the assembled state, H's root at s = 0), each step solved from the last: the
loads applied slowly from the assembled state. Its root is taken where it is stable (or
Newton found none).

Stability is read from the reduced stiffness K = −∂g/∂z at the solution (central
differences with Richardson extrapolation): the equilibrium is stable where K's symmetric
part is positive definite (a minimum of the potential), unstable where it has a negative
eigenvalue, neutral where its smallest is zero to working precision. Drivers hold their
joints where their laws put them at t.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .reduced import ReducedCoordinates
from ..records import Status
from ..threads import in_run_threads

# Equilibrium: ‖g‖∞ below this share of the generalized forces' size (‖R_j‖ ‖Q‖).
RESIDUAL = 1e-9
# An eigenvalue of K's symmetric part within this share of the largest counts as zero.
NEUTRAL = 1e-9
# A continuation step may land this far from its prediction (radians, or mechanism sizes).
MAX_TURN = 0.1


def jacobian(fun, x0, steps) -> np.ndarray:
    """∂fun/∂x at x0 by central differences with steps h and h/2 per coordinate, combined
    by Richardson extrapolation (error O(h⁴)); `steps` (len(x0),)."""
    x0 = np.asarray(x0, float)
    columns = []
    for i, h in enumerate(steps):
        def central(h):
            e = np.zeros_like(x0)
            e[i] = h
            return (np.asarray(fun(x0 + e)) - np.asarray(fun(x0 - e))) / (2.0 * h)
        coarse, fine = central(h), central(0.5 * h)
        columns.append((4.0 * fine - coarse) / 3.0)
    return np.column_stack(columns) if columns else np.zeros((0, 0))


# Finite-difference steps, in each independent coordinate's unit (`ReducedCoordinates.units`).
STEP = 1e-4


@dataclass
class Equilibrium:
    """A static equilibrium (`Mechanism.equilibrium`).

    Attributes
    ----------
    q, v : ndarray (n,)
        The configuration; zero velocities.
    t : float
        The time the drivers are held at.
    converged : bool
        g = 0 was met (`residual` ≤ RESIDUAL of the forces' size).
    stable : bool
        The reduced stiffness K is positive definite.
    stability : str
        "stable", "unstable" or "neutral".
    stiffness : ndarray (f, f)
        K in the independent `coordinates` (their names).
    method : str
        "newton" (Powell's hybrid from the assembled state) or "continuation".
    message : str
        What was found, or why not.
    result : SimulationResult
        One sample at the equilibrium: reactions, efforts and points are read from it
        (`eq.joint_force(j)` is `eq.result.joint_force(j)[0]`).
    """
    q: np.ndarray
    v: np.ndarray
    t: float
    converged: bool
    stable: bool
    stability: str
    stiffness: np.ndarray
    coordinates: list
    residual: float
    method: str
    message: str
    result: object = field(repr=False, default=None)

    def joint_force(self, joint, frame: str = "global") -> np.ndarray:
        """The force (2,) the joint applies to its body_b at the equilibrium."""
        return self.result.joint_force(joint, frame)[0]

    def joint_moment(self, joint) -> float:
        return float(self.result.joint_moment(joint)[0])

    def driver_effort(self, driver) -> float:
        """The torque or force a driver must hold at the equilibrium."""
        return float(self.result.driver_effort(driver)[0])


@in_run_threads
def equilibrium(mech, t: float = 0.0, tol: float = RESIDUAL, max_iter: int = 200) -> Equilibrium:
    """The static equilibrium of `mech` nearest its assembled state (module docstring)."""
    from scipy.optimize import root
    problem = mech.problem()
    q0 = mech.assemble(t=t).q
    reduced = ReducedCoordinates(problem, q0, t)
    if reduced.f == 0:
        return _finish(mech, reduced, np.zeros(0), "newton", "no degree of freedom: "
                       "the drivers hold the mechanism in its assembled configuration", tol)
    z0 = np.zeros(reduced.f)

    def g(z):
        try:
            return reduced.force(z)
        except ValueError:
            return np.full(reduced.f, np.nan)   # beyond assembly: hybrd backs off

    # hybrd's steps measured in radians and in the mechanism's size, the first at most half
    # of one: from a point where g's Jacobian is singular it would otherwise leap to an
    # equilibrium turns away.
    units = reduced.units
    sol = root(g, z0, method="hybr", options={"xtol": 1e-14, "factor": 0.5, "diag": 1.0 / units,
                                               "maxfev": max_iter * (reduced.f + 1)})
    newton = _finish(mech, reduced, sol.x, "newton", "", tol) \
        if _balanced(reduced, sol.x, tol) else None
    if newton is not None and (newton.stable or _balanced(reduced, z0, tol)):
        return newton
    # No root, or an unstable one reached from a state that was not at rest: follow the
    # loads from the assembled state instead (where a slow release would take it).
    z, note = _continuation(reduced, g, z0, tol, max_iter)
    found = _finish(mech, reduced, z, "continuation", note, tol)
    return found if newton is None or (found.converged and found.stable) else newton


def _force_size(reduced, z) -> float:
    """max_j ‖R_j‖ ‖Q‖: the bound on each generalized force |R_jᵀ Q| (Cauchy–Schwarz), the
    size g is small against, even where the forces stand across the motion (a hanging
    pendulum's weight)."""
    q = reduced.positions(z)
    Q = reduced.problem.forces(reduced.t, q, np.zeros_like(q))
    R = reduced.tangent(q)
    return float(np.max(np.linalg.norm(R, axis=0), initial=0.0) * np.linalg.norm(Q))


def _balanced(reduced, z, tol) -> bool:
    try:
        residual = np.max(np.abs(reduced.force(z)), initial=0.0)
        return bool(residual <= tol * max(_force_size(reduced, z), 1e-300))
    except ValueError:
        return False


def _continuation(reduced, g, z0, tol, max_iter):
    """(z, note) by the fixed-point homotopy from z0 (module docstring)."""
    from scipy.optimize import root
    steps = reduced.units             # 1 rad, or the mechanism's size
    k0 = max(_force_size(reduced, z0), 1e-12) / steps     # K₀: that force per such a unit
    z, s, ds, taken = z0.copy(), 0.0, 0.1, 0
    slope = np.zeros_like(z0)                 # dz/ds of the path so far (the predictor)
    while s < 1.0 and taken < max_iter:
        target = min(1.0, s + ds)

        def H(x, a=target):
            return a * g(x) + (1.0 - a) * k0 * (z0 - x)
        guess = z + slope * (target - s)
        sol = root(H, guess, method="hybr", options={"xtol": 1e-12, "factor": 0.5,
                                                      "diag": 1.0 / steps})
        taken += 1
        # A step stays on the path where it lands near the prediction (within MAX_TURN of a
        # radian or of the mechanism's size); further, the solver jumped to another branch.
        if sol.success and np.all(np.isfinite(sol.x)) and \
                np.max(np.abs(sol.x - guess) / steps, initial=0.0) <= MAX_TURN:
            slope = (sol.x - z) / (target - s)
            z, s, ds = sol.x, target, min(2.0 * ds, 0.25)
        elif ds > 1e-4:
            ds *= 0.25
        else:
            return z, f"continuation stopped at load factor {s:.3g}"
    if s < 1.0:
        return z, f"continuation stopped at load factor {s:.3g} after {taken} steps"
    sol = root(g, z, method="hybr", options={"xtol": 1e-14, "factor": 0.5, "diag": 1.0 / steps})
    near = np.max(np.abs(sol.x - z) / steps, initial=0.0) <= MAX_TURN
    return (sol.x if near and _balanced(reduced, sol.x, tol) else z), ""


def _finish(mech, reduced, z, method, note, tol=RESIDUAL) -> Equilibrium:
    """The Equilibrium at z: its stiffness, stability, message and one-sample result."""
    from ..results import SimulationResult
    problem = reduced.problem
    q = reduced.positions(z)
    size = max(_force_size(reduced, z), 1e-300)
    residual = float(np.max(np.abs(reduced.force(z)), initial=0.0))
    converged = residual <= tol * size
    if reduced.f:
        K = -jacobian(reduced.force, z, STEP * reduced.units)
        reduced.positions(z)              # leave Newton's guess at the solution
        eig = np.linalg.eigvalsh(0.5 * (K + K.T))
        tiny = NEUTRAL * max(np.max(np.abs(eig)), 1e-300)
        stability = "unstable" if eig[0] < -tiny else "neutral" if eig[0] <= tiny else "stable"
    else:
        K, stability = np.zeros((0, 0)), "stable"
    message = note or (f"{stability} equilibrium: generalized forces balanced to "
                       f"{residual:.3g} ({residual / size:.2g} of their size)")
    if not converged:
        message = (f"no equilibrium found from the assembled state: {note or 'the solver'} "
                   f"left a residual generalized force of {residual:.3g}; the mechanism "
                   "may have none within reach (a load that no joint can balance)")
    result = SimulationResult([reduced.t], q[None], np.zeros((1, problem.n)),
                              problem.coordinate_names, problem=problem,
                              status=Status.SUCCESS if converged else Status.FAILED, message=message,
                              stats={"method": "equilibrium"})
    from ..results.reactions import ReactionTable, static_multipliers
    result.__dict__["reactions"] = ReactionTable(
        result.t, result.q, result.v, problem,
        multipliers=static_multipliers(problem, reduced.t, q))
    return Equilibrium(q, np.zeros(problem.n), reduced.t, bool(converged),
                       stability == "stable" and bool(converged), stability, K,
                       list(reduced.names), residual, method, message, result)
